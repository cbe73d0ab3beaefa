//! The occupancy grid as a sampler: which rays a request renders, and over
//! which span, before any sample is placed.

use super::GridUse;
use crate::geometry::NormalizedRay;
use crate::occupancy::{ClippedRays, OccupancyGrid};

/// What clipping to the grid did to a batch of rays.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClipStats {
    /// Rays drawn.
    pub drawn: usize,
    /// Rays rendered: those that crossed an occupied cell, and with
    /// [`GridUse::KeepEmpty`] those that crossed none (all of them when
    /// none crossed one).
    pub kept: usize,
    /// Sum over drawn rays of the fraction of their length still sampled
    /// (0 for a skipped ray, 1 for one kept whole).
    pub span_sum: f64,
    /// Rays that crossed no occupied cell (rendered whole with
    /// [`GridUse::KeepEmpty`], skipped with [`GridUse::Model`]).
    pub empty: usize,
}

impl ClipStats {
    /// Adds the counts of `other` (another batch).
    pub fn add(&mut self, other: ClipStats) {
        self.drawn += other.drawn;
        self.kept += other.kept;
        self.span_sum += other.span_sum;
        self.empty += other.empty;
    }
}

/// The rays a request renders.
pub(super) struct Clipped {
    /// The rays with their clipped bounds (`None`: the input as it is).
    pub rays: Option<Vec<NormalizedRay>>,
    /// Index in the input of each ray rendered (`None`: every input ray).
    pub kept: Option<Vec<usize>>,
    /// What clipping did (`None`: no grid used).
    pub stats: Option<ClipStats>,
}

impl Clipped {
    /// Every input ray as it is.
    fn whole(stats: Option<ClipStats>) -> Self {
        Clipped {
            rays: None,
            kept: None,
            stats,
        }
    }
}

/// `rays` clipped to `grid` as `grid_use` asks, with what clipping did.
fn clip(
    grid: Option<&OccupancyGrid>,
    grid_use: GridUse,
    rays: &[NormalizedRay],
) -> Option<(ClippedRays, ClipStats)> {
    let clipped = match (grid, grid_use) {
        (None, _) | (_, GridUse::Off) => return None,
        (Some(g), GridUse::Model) => g.clip(rays),
        (Some(g), GridUse::KeepEmpty) => g.clip_keeping(rays),
    };
    let stats = ClipStats {
        drawn: rays.len(),
        kept: clipped.kept.len(),
        span_sum: clipped.span_fraction_sum,
        empty: clipped.empty,
    };
    Some((clipped, stats))
}

/// The rays of a training batch: clipped as `grid_use` asks, except that a
/// batch in which no ray would be rendered is rendered whole (an empty step
/// teaches nothing, and its rays may show the grid is wrong).
pub(super) fn clip_for_training(
    grid: Option<&OccupancyGrid>,
    grid_use: GridUse,
    rays: &[NormalizedRay],
) -> Clipped {
    let Some((clipped, mut stats)) = clip(grid, grid_use, rays) else {
        return Clipped::whole(None);
    };
    if clipped.kept.is_empty() {
        stats.kept = stats.drawn;
        stats.span_sum = stats.drawn as f64;
        return Clipped::whole(Some(stats));
    }
    let all = clipped.kept.len() == rays.len();
    Clipped {
        rays: Some(clipped.rays),
        kept: (!all).then_some(clipped.kept),
        stats: Some(stats),
    }
}

/// The rays of an inference request: clipped as `grid_use` asks (possibly
/// none left).
pub(super) fn clip_for_inference(
    grid: Option<&OccupancyGrid>,
    grid_use: GridUse,
    rays: &[NormalizedRay],
) -> Clipped {
    let Some((clipped, stats)) = clip(grid, grid_use, rays) else {
        return Clipped::whole(None);
    };
    let all = clipped.kept.len() == rays.len();
    Clipped {
        rays: Some(clipped.rays),
        kept: (!all).then_some(clipped.kept),
        stats: Some(stats),
    }
}
