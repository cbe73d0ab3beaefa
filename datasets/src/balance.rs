//! Feature-balanced ray sampling: pixels are drawn with a probability that
//! grows with the rarity of their feature target, so that small objects (a
//! few dozen pixels in a few views) receive more than a handful of rays in a
//! whole training run.
//!
//! Rarity needs no labels: the training frames' feature targets are
//! clustered (k-means in the maps' own space, PCA coefficients when
//! compressed) and a pixel of a cluster holding the fraction `f` of all
//! pixels is drawn with weight `f^-power`. `power = 0` is uniform sampling,
//! `power = 1` gives every cluster the same share of rays. Because the
//! weight follows the target, a surface point seen close up (where the
//! extractor recognises it: a rare feature) gets more rays from those views
//! than from far views where it smears into its surroundings (a common
//! feature).
//!
//! Masked-out pixels ([`Frame::mask`]) are never drawn and count in no
//! cluster's share.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::DatasetError;
use crate::sampler::{RayBatch, SamplerConfig, batch_at, check_frames, interior};
use crate::scene::{Frame, Scene};

/// Map pixels sampled to fit the cluster centres.
const FIT_SAMPLES: usize = 16_384;
/// Lloyd iterations of the k-means fit.
const ITERATIONS: usize = 10;

/// How rays are balanced over features.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BalanceConfig {
    /// Feature clusters.
    pub clusters: usize,
    /// Exponent of the rarity weight `f^-power` (0 = uniform).
    pub power: f64,
}

impl BalanceConfig {
    /// The balance `config` asks for (its `balance_clusters` and
    /// `feature_balance`), `None` when it samples uniformly.
    pub fn of(config: &SamplerConfig) -> Option<Self> {
        (config.feature_balance > 0.0).then_some(Self {
            clusters: config.balance_clusters,
            power: config.feature_balance,
        })
    }
}

/// A block of image pixels that share one map pixel (so one target).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Cell {
    frame: usize,
    x: (u32, u32),
    y: (u32, u32),
    /// Unmasked pixels in the cell (all of them without a mask).
    pixels: u32,
}

/// Draws inside a cell before [`Cell::draw`] turns to listing its unmasked
/// pixels.
const CELL_REJECTIONS: usize = 64;

impl Cell {
    /// A cell of `frame` with its unmasked pixel count.
    fn new(frame: &Frame, fi: usize, x: (u32, u32), y: (u32, u32)) -> Self {
        let pixels = match frame.mask {
            None => (x.1 - x.0) * (y.1 - y.0),
            Some(_) => (y.0..y.1)
                .map(|yy| {
                    (x.0..x.1)
                        .filter(|&xx| frame.is_target_pixel(xx, yy))
                        .count() as u32
                })
                .sum(),
        };
        Self {
            frame: fi,
            x,
            y,
            pixels,
        }
    }

    /// A pixel of the cell uniformly among its unmasked ones (drawn again
    /// while masked; an unmasked cell keeps its first draw, the stream of
    /// a sampler without masks). The cell must have an unmasked pixel.
    fn draw(&self, rng: &mut ChaCha8Rng, scene: &Scene) -> (usize, u32, u32) {
        let frame = &scene.frames[self.frame];
        for _ in 0..CELL_REJECTIONS {
            let (x, y) = (
                rng.random_range(self.x.0..self.x.1),
                rng.random_range(self.y.0..self.y.1),
            );
            if frame.is_target_pixel(x, y) {
                return (self.frame, x, y);
            }
        }
        let listed: Vec<(u32, u32)> = (self.y.0..self.y.1)
            .flat_map(|y| (self.x.0..self.x.1).map(move |x| (x, y)))
            .filter(|&(x, y)| frame.is_target_pixel(x, y))
            .collect();
        if listed.is_empty() {
            // Not reached: cells without an unmasked pixel are never built.
            return (self.frame, self.x.0, self.y.0);
        }
        let (x, y) = listed[rng.random_range(0..listed.len())];
        (self.frame, x, y)
    }
}

/// Draws seeded batches of pixels with feature-balanced probabilities.
#[derive(Debug, Clone)]
pub struct BalancedSampler {
    frames: Vec<usize>,
    cells: Vec<Cell>,
    /// Cumulative cell weights (weight x pixel count).
    cdf: Vec<f64>,
    /// Fraction of the unmasked interior pixels in each cluster (the last
    /// entry: pixels without a target).
    pub cluster_fractions: Vec<f64>,
}

/// For each map column (or row) `m` of a map `map_len` wide, the image
/// pixels `[a, b)` inside `[lo, hi)` whose nearest map pixel is `m`.
fn spans(image_len: u32, map_len: u32, lo: u32, hi: u32) -> Vec<(u32, u32, u32)> {
    let mut out: Vec<(u32, u32, u32)> = Vec::new();
    for p in lo..hi {
        let m = (((p as f64 + 0.5) * map_len as f64 / image_len as f64).floor() as u32)
            .min(map_len - 1);
        match out.last_mut() {
            Some(last) if last.0 == m => last.2 = p + 1,
            _ => out.push((m, p, p + 1)),
        }
    }
    out
}

fn dist2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

fn nearest(v: &[f32], centres: &[f32], dim: usize) -> usize {
    let mut best = (0, f32::INFINITY);
    for (c, centre) in centres.chunks_exact(dim).enumerate() {
        let d = dist2(v, centre);
        if d < best.1 {
            best = (c, d);
        }
    }
    best.0
}

impl BalancedSampler {
    /// Clusters the targets of `frames` and builds the sampling weights.
    /// `None` when the scene has no feature maps (nothing to balance).
    pub fn new(
        scene: &Scene,
        frames: &[usize],
        border_margin: u32,
        balance: &BalanceConfig,
        seed: u64,
    ) -> Result<Option<Self>, DatasetError> {
        check_frames(scene, frames)?;
        let Some(fs) = scene.features.as_ref() else {
            return Ok(None);
        };
        if !(balance.power.is_finite() && balance.power >= 0.0) || balance.clusters == 0 {
            return Err(DatasetError::invalid(
                &scene.name,
                format!(
                    "feature balance needs clusters >= 1 and a finite power >= 0, got {} and {}",
                    balance.clusters, balance.power
                ),
            ));
        }
        let dim = fs.dim();
        let no_cells = || {
            DatasetError::invalid(
                &scene.name,
                "every interior pixel of the frames sampled from is masked out",
            )
        };
        // Cells of every frame, with the map pixel they read.
        let mut cells = Vec::new();
        let mut cell_pixel: Vec<Option<(usize, usize)>> = Vec::new();
        for &fi in frames {
            let frame = &scene.frames[fi];
            let (w, h) = (frame.rgb.width, frame.rgb.height);
            let ((x0, x1), (y0, y1)) = interior(border_margin, w, h);
            let map = fs.maps.get(fi);
            let (mw, mh) = map.map_or((w, h), |m| (m.width, m.height));
            for (my, ya, yb) in spans(h, mh, y0, y1) {
                for &(mx, xa, xb) in &spans(w, mw, x0, x1) {
                    let cell = Cell::new(frame, fi, (xa, xb), (ya, yb));
                    if cell.pixels == 0 {
                        continue; // wholly masked out: never drawn
                    }
                    cells.push(cell);
                    let valid = map.is_some_and(|m| fs.is_target(m.pixel(mx, my)));
                    cell_pixel.push(valid.then_some((fi, (my * mw + mx) as usize)));
                }
            }
        }
        if cells.is_empty() {
            return Err(no_cells());
        }
        let vector = |(fi, p): (usize, usize)| -> Vec<f32> {
            fs.maps[fi].data[p * dim..(p + 1) * dim]
                .iter()
                .map(|v| v.to_f32())
                .collect()
        };
        let valid: Vec<usize> = (0..cells.len())
            .filter(|&i| cell_pixel[i].is_some())
            .collect();
        let k = balance.clusters.min(valid.len()).max(1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xba1a_9ce5);
        let fit: Vec<Vec<f32>> = (0..FIT_SAMPLES.min(valid.len()))
            .filter_map(|_| cell_pixel[valid[rng.random_range(0..valid.len())]])
            .map(vector)
            .collect();
        let mut centres: Vec<f32> = Vec::with_capacity(k * dim);
        for i in 0..k.min(fit.len()) {
            centres.extend_from_slice(&fit[i * fit.len() / k.min(fit.len())]);
        }
        let k = centres.len() / dim.max(1);
        for _ in 0..ITERATIONS {
            let mut sums = vec![0f64; k * dim];
            let mut counts = vec![0usize; k];
            for v in &fit {
                let c = nearest(v, &centres, dim);
                counts[c] += 1;
                for (s, &x) in sums[c * dim..(c + 1) * dim].iter_mut().zip(v) {
                    *s += x as f64;
                }
            }
            for c in 0..k {
                if counts[c] > 0 {
                    for j in 0..dim {
                        centres[c * dim + j] = (sums[c * dim + j] / counts[c] as f64) as f32;
                    }
                }
            }
        }
        // Cluster of every cell (k = no target) and the pixel share of each.
        let cluster: Vec<usize> = cell_pixel
            .iter()
            .map(|p| p.map_or(k, |p| nearest(&vector(p), &centres, dim)))
            .collect();
        let area = |c: &Cell| c.pixels as f64;
        let mut share = vec![0f64; k + 1];
        for (c, &g) in cells.iter().zip(&cluster) {
            share[g] += area(c);
        }
        let total: f64 = share.iter().sum::<f64>().max(1.0);
        share.iter_mut().for_each(|s| *s /= total);
        let mut cdf = Vec::with_capacity(cells.len());
        let mut acc = 0.0;
        for (c, &g) in cells.iter().zip(&cluster) {
            acc += area(c) * share[g].max(1e-12).powf(-balance.power);
            cdf.push(acc);
        }
        Ok(Some(Self {
            frames: frames.to_vec(),
            cells,
            cdf,
            cluster_fractions: share,
        }))
    }

    /// Batch number `index` (a pure function of `seed` and `index`, so
    /// training resumes exactly).
    pub fn batch(&self, config: &SamplerConfig, seed: u64, scene: &Scene, index: u64) -> RayBatch {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0b5e_55ed);
        rng.set_stream(index);
        let total = self.cdf.last().copied().unwrap_or(0.0);
        let picks: Vec<(usize, u32, u32)> = (0..config.rays_per_batch)
            .map(|_| {
                let u = rng.random_range(0.0..total.max(f64::MIN_POSITIVE));
                let i = self
                    .cdf
                    .partition_point(|&c| c <= u)
                    .min(self.cells.len() - 1);
                self.cells[i].draw(&mut rng, scene)
            })
            .collect();
        batch_at(config, scene, &self.frames, &picks)
    }
}
