//! Occupancy grid for empty-space skipping: a coarse grid of cells over the
//! normalised scene cube `[-pi, pi]^3`, each with a decayed running maximum
//! of the field's density; a cell is occupied when a ray crossing it would
//! lose at least `min_opacity` of its light there.
//!
//! Rays are clipped to the span from the first to the last occupied cell
//! they cross (samples are placed there only), and rays that cross no
//! occupied cell are not rendered at all: they see the background. A grid
//! with every cell occupied (as it starts) changes nothing, and a grid that
//! would have no occupied cell falls back to every cell occupied.
//!
//! Pure host code: the densities come from the caller (see
//! [`OpenNerf::query_density`](crate::OpenNerf::query_density)).

use std::f64::consts::PI;

use burn::config::Config;
use rand::{Rng, SeedableRng};

use crate::geometry::NormalizedRay;

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
}

/// Rays clipped to the occupied cells: the rays that cross at least one,
/// with tightened bounds, and their indices in the input.
#[derive(Debug, Clone, PartialEq)]
pub struct ClippedRays {
    /// The kept rays with `near`/`far` moved to the occupied span.
    pub rays: Vec<NormalizedRay>,
    /// Index in the input of each kept ray.
    pub kept: Vec<usize>,
    /// Sum over input rays of the kept span length over the original one
    /// (rays with an empty interval count as 1).
    pub span_fraction_sum: f64,
}

/// The grid: densities per cell (x fastest, then y, then z) and the bitfield
/// derived from them.
#[derive(Clone, PartialEq)]
pub struct OccupancyGrid {
    resolution: usize,
    density: Vec<f32>,
    bits: Vec<u64>,
    updates: u64,
    decay: f32,
    min_opacity: f32,
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
        };
        grid.fill_all();
        grid
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

    /// One point per cell, uniformly at random inside it (seeded), in the
    /// order of [`OccupancyGrid::update`]'s input.
    ///
    /// # Shapes
    /// - output: `resolution^3` points `[x, y, z]` in normalised units.
    pub fn sample_points(&self, seed: u64) -> Vec<[f32; 3]> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let (r, h) = (self.resolution, self.cell_size());
        let mut points = Vec::with_capacity(r * r * r);
        for k in 0..r {
            for j in 0..r {
                for i in 0..r {
                    let at = |c: usize, u: f64| (-HALF + (c as f64 + u) * h) as f32;
                    points.push([
                        at(i, rng.random()),
                        at(j, rng.random()),
                        at(k, rng.random()),
                    ]);
                }
            }
        }
        points
    }

    /// Folds in new densities (per normalised unit, one per cell, e.g. at
    /// [`OccupancyGrid::sample_points`]): the stored value becomes
    /// `max(decay * old, new)` (just `new` at the first update), and a cell is
    /// occupied when `1 - exp(-density * cell_size) >= min_opacity`, with the
    /// threshold lowered to the mean density when that is smaller (so a field
    /// that is still faint everywhere keeps its brightest cells). Non-finite
    /// or negative densities count as occupied. With no occupied cell the
    /// grid falls back to every cell occupied.
    ///
    /// # Panics
    /// When `new.len()` is not the number of cells (a caller bug).
    pub fn update(&mut self, new: &[f32]) {
        assert_eq!(new.len(), self.density.len(), "one density per cell");
        let first = self.updates == 0;
        for (d, &n) in self.density.iter_mut().zip(new) {
            let n = if n.is_finite() && n >= 0.0 {
                n
            } else {
                f32::INFINITY
            };
            *d = if first { n } else { (*d * self.decay).max(n) };
        }
        self.updates += 1;
        self.rebuild_bits();
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
        self.bits.iter_mut().for_each(|b| *b = 0);
        let mut any = false;
        for (c, &d) in self.density.iter().enumerate() {
            if !(d.is_finite() && (d as f64) < threshold) {
                self.bits[c / 64] |= 1 << (c % 64);
                any = true;
            }
        }
        if !any {
            self.fill_all();
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
        let mut out = ClippedRays {
            rays: Vec::with_capacity(rays.len()),
            kept: Vec::with_capacity(rays.len()),
            span_fraction_sum: 0.0,
        };
        for (i, ray) in rays.iter().enumerate() {
            let Some((near, far)) = self.ray_span(ray) else {
                continue;
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

    /// Serialises the grid (resolution, update count, decay, opacity and the
    /// densities, little-endian); the bitfield is rebuilt on reading.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(32 + 4 * self.density.len());
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&(self.resolution as u64).to_le_bytes());
        b.extend_from_slice(&self.updates.to_le_bytes());
        b.extend_from_slice(&self.decay.to_le_bytes());
        b.extend_from_slice(&self.min_opacity.to_le_bytes());
        for d in &self.density {
            b.extend_from_slice(&d.to_le_bytes());
        }
        b
    }

    /// Reads [`OccupancyGrid::to_bytes`]; `Err` names what is wrong.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        let head = MAGIC.len() + 24;
        if bytes.len() < head || &bytes[..MAGIC.len()] != MAGIC {
            return Err("not an occupancy grid (bad header)".into());
        }
        let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap_or([0; 8]));
        let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap_or([0; 4]));
        let m = MAGIC.len();
        let resolution = u64_at(m) as usize;
        if resolution == 0 || resolution > 512 {
            return Err(format!("resolution {resolution} outside 1..=512"));
        }
        let cells = resolution * resolution * resolution;
        if bytes.len() != head + 4 * cells {
            return Err(format!(
                "{} bytes where a {resolution}^3 grid has {}",
                bytes.len(),
                head + 4 * cells
            ));
        }
        let density: Vec<f32> = (0..cells).map(|c| f32_at(head + 4 * c)).collect();
        let mut grid = Self {
            resolution,
            density,
            bits: vec![0; cells.div_ceil(64)],
            updates: u64_at(m + 8),
            decay: f32_at(m + 16),
            min_opacity: f32_at(m + 20),
        };
        if grid.updates == 0 {
            grid.fill_all();
        } else {
            grid.rebuild_bits();
        }
        Ok(grid)
    }
}

const MAGIC: &[u8; 8] = b"OCCGRID1";
