//! The grid's settings and the rules of its schedule.

use burn::config::Config;

use super::OccupancyGrid;

/// Settings of the occupancy grid (switched off by default).
#[derive(Config, Debug, PartialEq)]
pub struct OccupancyConfig {
    /// Use the grid.
    #[config(default = false)]
    pub enabled: bool,
    /// Cells per axis.
    #[config(default = 32)]
    pub resolution: usize,
    /// Iterations between updates.
    #[config(default = 16)]
    pub update_every: usize,
    /// Iterations before the first update (the grid is complete until then).
    #[config(default = 256)]
    pub warmup: usize,
    /// Factor applied to the stored density at each update before the new
    /// value is maxed in (forgets density that the field has given up).
    #[config(default = 0.95)]
    pub decay: f32,
    /// Opacity across one cell above which the cell is occupied.
    #[config(default = 0.01)]
    pub min_opacity: f32,
    /// Jittered points per cell at each of the first `early_updates`
    /// updates (one after); a cell's new density is the maximum over them.
    #[config(default = 8)]
    pub early_samples: usize,
    /// Updates that sample `early_samples` points per cell and keep the
    /// maximum over all of them without decay; every cell stays occupied
    /// until they are done (0 or 1: the first update decides alone).
    #[config(default = 4)]
    pub early_updates: usize,
    /// Cells around an occupied cell that count as occupied too (Chebyshev
    /// distance: 1 adds the 26 neighbours; 0, the default, turns dilation
    /// off: the README measures what it costs on lego, and the early
    /// samples alone keep a thin pole).
    #[config(default = 0)]
    pub dilation: usize,
    /// Updates during which training still renders the rays that cross no
    /// occupied cell (over their whole span), so a region freed by mistake
    /// keeps a loss; 0 drops them from the first update on.
    #[config(default = 8)]
    pub keep_dropped_updates: usize,
}

impl Default for OccupancyConfig {
    fn default() -> Self {
        Self::new()
    }
}

impl OccupancyConfig {
    /// Whether an update is due at `iteration`.
    pub fn update_due(&self, iteration: usize) -> bool {
        self.enabled
            && iteration >= self.warmup.max(1)
            && (iteration - self.warmup.max(1)).is_multiple_of(self.update_every.max(1))
    }

    /// The grid a run starts with: a complete one when skipping is on.
    pub fn initial_grid(&self) -> Option<OccupancyGrid> {
        self.enabled.then(|| OccupancyGrid::new(self))
    }

    /// Whether training still renders the rays that cross no occupied cell
    /// of `grid` (over their whole span): during its first
    /// `keep_dropped_updates` updates, while a region freed by mistake
    /// should still get a loss that brings it back.
    pub fn keeps_empty_rays(&self, grid: &OccupancyGrid) -> bool {
        grid.updates() < self.keep_dropped_updates as u64
    }
}
