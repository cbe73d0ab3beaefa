//! Occupancy grid for empty-space skipping: a coarse grid of cells over the
//! normalised scene cube `[-pi, pi]^3`, each with a decayed running maximum
//! of the field's density; a cell is occupied when a ray crossing it would
//! lose at least `min_opacity` of its light there.
//!
//! The grid is conservative, since a cell freed by mistake only comes back
//! when a later sample happens to hit its density: the first
//! `early_updates` updates draw `early_samples` jittered points per cell and
//! keep the maximum over all of them while every cell stays occupied, and
//! the cells within `dilation` cells (26 neighbours for 1) of a cell that
//! passes the threshold count as occupied too.
//!
//! Rays are clipped to the span from the first to the last occupied cell
//! they cross (samples are placed there only), and rays that cross no
//! occupied cell are not rendered at all: they see the background. A grid
//! with every cell occupied (as it starts) changes nothing, and a grid that
//! would have no occupied cell falls back to every cell occupied.
//!
//! The grid is host code; its update queries the field's density at
//! jittered points ([`OccupancyGrid::update_from_field`], or
//! [`OccupancyGrid::update`] with densities from elsewhere), and
//! [`OpenNerf::render`](crate::OpenNerf::render) clips its rays with the
//! grid the model carries. It travels as bytes ([`OccupancyGrid::to_bytes`])
//! or as hex text in a checkpoint's JSON state ([`OccupancyGrid::to_hex`]).

use std::f64::consts::PI;

use rand::{Rng, SeedableRng};

use crate::geometry::NormalizedRay;

mod bytes;
mod config;
mod mask;
mod update;

pub use bytes::GridDecodeError;
pub use config::OccupancyConfig;

/// Rays clipped to the occupied cells: the rays that cross at least one,
/// with tightened bounds, and their indices in the input.
#[derive(Debug, Clone, PartialEq)]
pub struct ClippedRays {
    /// The kept rays with `near`/`far` moved to the occupied span.
    pub rays: Vec<NormalizedRay>,
    /// Index in the input of each kept ray.
    pub kept: Vec<usize>,
    /// Sum over input rays of the kept span length over the original one
    /// (rays with an empty interval, or kept whole although they cross no
    /// occupied cell, count as 1).
    pub span_fraction_sum: f64,
    /// Input rays that cross no occupied cell (kept whole by
    /// [`OccupancyGrid::clip_keeping`], dropped by [`OccupancyGrid::clip`]).
    pub empty: usize,
}

/// The grid: densities per cell (x fastest, then y, then z) and the bitfield
/// derived from them (after dilation).
#[derive(Clone, PartialEq)]
pub struct OccupancyGrid {
    resolution: usize,
    density: Vec<f32>,
    bits: Vec<u64>,
    updates: u64,
    decay: f32,
    min_opacity: f32,
    early_samples: u32,
    early_updates: u32,
    dilation: u32,
}

impl std::fmt::Debug for OccupancyGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "OccupancyGrid({0}^3, {1} updates, {2:.1} % occupied)",
            self.resolution,
            self.updates,
            100.0 * self.occupied_fraction()
        )
    }
}

/// Half the side of the normalised scene cube.
const HALF: f64 = PI;

/// Most jittered points per cell in an early update.
pub const MAX_EARLY_SAMPLES: usize = 32;

/// Widest dilation, in cells.
pub const MAX_DILATION: usize = 4;

impl OccupancyGrid {
    /// A complete grid (every cell occupied) of `config.resolution^3` cells.
    pub fn new(config: &OccupancyConfig) -> Self {
        let r = config.resolution.clamp(1, 512);
        let cells = r * r * r;
        let mut grid = Self {
            resolution: r,
            density: vec![f32::INFINITY; cells],
            bits: vec![0; cells.div_ceil(64)],
            updates: 0,
            decay: config.decay,
            min_opacity: config.min_opacity,
            early_samples: config.early_samples.clamp(1, MAX_EARLY_SAMPLES) as u32,
            early_updates: config.early_updates.min(u32::MAX as usize) as u32,
            dilation: config.dilation.min(MAX_DILATION) as u32,
        };
        grid.fill_all();
        grid
    }

    /// Points per cell that [`OccupancyGrid::sample_points`] draws for the
    /// next update: `early_samples` during the early updates, then 1.
    pub fn samples_per_cell(&self) -> usize {
        if self.in_early_phase() {
            self.early_samples as usize
        } else {
            1
        }
    }

    /// Whether the next update is one of the early ones.
    fn in_early_phase(&self) -> bool {
        self.updates < self.early_updates as u64
    }

    /// Cells of dilation around each occupied cell.
    pub fn dilation(&self) -> usize {
        self.dilation as usize
    }

    /// Cells per axis.
    pub fn resolution(&self) -> usize {
        self.resolution
    }

    /// Number of updates applied.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// Side of a cell in normalised units.
    pub fn cell_size(&self) -> f64 {
        2.0 * HALF / self.resolution as f64
    }

    /// Stored densities, one per cell (infinite before the first update).
    pub fn densities(&self) -> &[f32] {
        &self.density
    }

    /// Whether cell `(i, j, k)` is occupied.
    pub fn is_occupied(&self, i: usize, j: usize, k: usize) -> bool {
        let c = self.index(i, j, k);
        self.bits[c / 64] >> (c % 64) & 1 == 1
    }

    /// Fraction of the cells that are occupied.
    pub fn occupied_fraction(&self) -> f64 {
        let n: u32 = self.bits.iter().map(|b| b.count_ones()).sum();
        n as f64 / self.density.len() as f64
    }

    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.resolution + j) * self.resolution + i
    }

    fn fill_all(&mut self) {
        let cells = self.density.len();
        for (w, b) in self.bits.iter_mut().enumerate() {
            let left = cells - 64 * w;
            *b = if left >= 64 {
                u64::MAX
            } else {
                (1 << left) - 1
            };
        }
    }

    /// [`OccupancyGrid::samples_per_cell`] points per cell, cell after cell
    /// in the order of [`OccupancyGrid::update`]'s input, drawn from `seed`
    /// only (a resumed run draws the same ones). With `k^3 <= n` samples
    /// the first `k^3` are jittered in the `k^3` sub-cubes of the cell
    /// (stratified, so that no part of the cell goes unseen), the others
    /// uniform in it; one sample is uniform in the cell.
    ///
    /// # Shapes
    /// - output: `samples_per_cell * resolution^3` points `[x, y, z]` in
    ///   normalised units.
    pub fn sample_points(&self, seed: u64) -> Vec<[f32; 3]> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let (r, h) = (self.resolution, self.cell_size());
        let n = self.samples_per_cell();
        let k = (1..=n).take_while(|k| k * k * k <= n).last().unwrap_or(1);
        let mut points = Vec::with_capacity(n * r * r * r);
        for kz in 0..r {
            for j in 0..r {
                for i in 0..r {
                    for s in 0..n {
                        // Sub-cube of sample s (the whole cell past k^3).
                        let (sub, div) = if s < k * k * k {
                            ([s % k, s / k % k, s / (k * k)], k as f64)
                        } else {
                            ([0; 3], 1.0)
                        };
                        let at = |c: usize, a: usize, u: f64| {
                            (-HALF + (c as f64 + (sub[a] as f64 + u) / div) * h) as f32
                        };
                        points.push([
                            at(i, 0, rng.random()),
                            at(j, 1, rng.random()),
                            at(kz, 2, rng.random()),
                        ]);
                    }
                }
            }
        }
        points
    }

    /// Folds in new densities (per normalised unit, `m >= 1` per cell, cell
    /// after cell, e.g. at [`OccupancyGrid::sample_points`]): a cell's new
    /// value is the maximum over its `m`. During the early updates the
    /// stored value is the maximum over all of them and every cell stays
    /// occupied; after, it becomes `max(decay * old, new)` (just `new` at
    /// the first update when there are no early updates). A cell passes the
    /// threshold when `1 - exp(-density * cell_size) >= min_opacity`, with
    /// the threshold lowered to the mean density when that is smaller (so a
    /// field that is still faint everywhere keeps its brightest cells), and
    /// it and the cells within `dilation` of it are occupied. Non-finite or
    /// negative densities count as occupied. With no cell passing, the grid
    /// falls back to every cell occupied.
    ///
    /// # Panics
    /// When `new.len()` is not a positive multiple of the number of cells
    /// (a caller bug).
    pub fn update(&mut self, new: &[f32]) {
        let cells = self.density.len();
        assert!(
            !new.is_empty() && new.len().is_multiple_of(cells),
            "{} densities for {cells} cells: give the same number per cell",
            new.len()
        );
        let per_cell = new.len() / cells;
        let (first, early) = (self.updates == 0, self.in_early_phase());
        for (d, group) in self.density.iter_mut().zip(new.chunks_exact(per_cell)) {
            let n = group
                .iter()
                .map(|&n| {
                    if n.is_finite() && n >= 0.0 {
                        n
                    } else {
                        f32::INFINITY
                    }
                })
                .fold(0.0f32, f32::max);
            *d = if first {
                n
            } else if early {
                d.max(n)
            } else {
                (*d * self.decay).max(n)
            };
        }
        self.updates += 1;
        self.refresh_bits();
    }

    /// The bitfield from the densities: complete before the first update
    /// and during the early ones, the dilated threshold rule after.
    fn refresh_bits(&mut self) {
        if self.updates == 0 || self.in_early_phase() {
            self.fill_all();
        } else {
            self.rebuild_bits();
        }
    }

    /// The density above which a cell is occupied.
    pub fn threshold(&self) -> f64 {
        let opacity = (self.min_opacity as f64).clamp(1e-9, 1.0 - 1e-9);
        let from_opacity = -(1.0 - opacity).ln() / self.cell_size();
        let (sum, count) = self
            .density
            .iter()
            .filter(|d| d.is_finite())
            .fold((0.0f64, 0usize), |(s, n), &d| (s + d as f64, n + 1));
        if count == 0 {
            return from_opacity;
        }
        let mean = sum / count as f64;
        from_opacity.min(mean)
    }

    fn rebuild_bits(&mut self) {
        let threshold = self.threshold();
        let passes: Vec<bool> = self
            .density
            .iter()
            .map(|&d| !(d.is_finite() && (d as f64) < threshold))
            .collect();
        if !passes.contains(&true) {
            self.fill_all();
            return;
        }
        let occupied = mask::dilate(passes, self.resolution, self.dilation as usize);
        self.bits.iter_mut().for_each(|b| *b = 0);
        for (c, _) in occupied.iter().enumerate().filter(|(_, o)| **o) {
            self.bits[c / 64] |= 1 << (c % 64);
        }
    }

    /// The cells `ray` crosses inside `[near, far]`, in order, as
    /// `(t_enter, t_exit, occupied)`. Points outside the cube belong to the
    /// nearest cell.
    pub fn crossings(&self, ray: &NormalizedRay) -> Vec<(f64, f64, bool)> {
        let (near, far) = (ray.near as f64, ray.far as f64);
        if far <= near {
            return Vec::new();
        }
        let o = ray.origin.map(|v| v as f64);
        let d = ray.direction.map(|v| v as f64);
        let h = self.cell_size();
        let mut ts = vec![near, far];
        for a in 0..3 {
            if d[a] == 0.0 {
                continue;
            }
            for p in 0..=self.resolution {
                let t = (-HALF + p as f64 * h - o[a]) / d[a];
                if t > near && t < far {
                    ts.push(t);
                }
            }
        }
        ts.sort_unstable_by(f64::total_cmp);
        ts.dedup();
        let r = self.resolution as i64;
        let cell = |x: f64| (((x + HALF) / h).floor() as i64).clamp(0, r - 1) as usize;
        ts.windows(2)
            .filter(|w| w[1] > w[0])
            .map(|w| {
                let t = 0.5 * (w[0] + w[1]);
                let p = [0, 1, 2].map(|a| cell(o[a] + t * d[a]));
                (w[0], w[1], self.is_occupied(p[0], p[1], p[2]))
            })
            .collect()
    }

    /// `[near, far]` of `ray` shrunk to its first and last occupied cell;
    /// `None` when it crosses none. The bounds are the ray's own where the
    /// first (last) cell crossed is occupied, so a complete grid returns
    /// them unchanged. A ray with an empty interval is returned as it is.
    pub fn ray_span(&self, ray: &NormalizedRay) -> Option<(f32, f32)> {
        let cells = self.crossings(ray);
        if cells.is_empty() {
            return Some((ray.near, ray.far));
        }
        let first = cells.iter().position(|c| c.2)?;
        let last = cells.iter().rposition(|c| c.2)?;
        let near = if first == 0 {
            ray.near
        } else {
            cells[first].0 as f32
        };
        let far = if last + 1 == cells.len() {
            ray.far
        } else {
            cells[last].1 as f32
        };
        Some((near, far))
    }

    /// Clips every ray to its occupied span and drops those that cross no
    /// occupied cell.
    pub fn clip(&self, rays: &[NormalizedRay]) -> ClippedRays {
        self.clip_rays(rays, false)
    }

    /// [`OccupancyGrid::clip`], but the rays that cross no occupied cell are
    /// kept whole (for training while the grid may still be wrong).
    pub fn clip_keeping(&self, rays: &[NormalizedRay]) -> ClippedRays {
        self.clip_rays(rays, true)
    }

    fn clip_rays(&self, rays: &[NormalizedRay], keep_empty: bool) -> ClippedRays {
        let mut out = ClippedRays {
            rays: Vec::with_capacity(rays.len()),
            kept: Vec::with_capacity(rays.len()),
            span_fraction_sum: 0.0,
            empty: 0,
        };
        for (i, ray) in rays.iter().enumerate() {
            let (near, far) = match self.ray_span(ray) {
                Some(span) => span,
                None if keep_empty => {
                    out.empty += 1;
                    (ray.near, ray.far)
                }
                None => {
                    out.empty += 1;
                    continue;
                }
            };
            let full = (ray.far - ray.near) as f64;
            out.span_fraction_sum += if full > 0.0 {
                ((far - near) as f64 / full).clamp(0.0, 1.0)
            } else {
                1.0
            };
            out.rays.push(NormalizedRay { near, far, ..*ray });
            out.kept.push(i);
        }
        out
    }
}
