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
//! Masked-out pixels ([`Frame::mask`](crate::Frame::mask)) are never drawn
//! and count in no cluster's share.
//!
//! # Memory
//! A cell (the image pixels sharing one map pixel) is stored as one `u32`:
//! its index in the frame grids (kept once per frame geometry), listed in
//! groups of cells with the same cluster and the same unmasked pixel count.
//! Every cell of a group has the same probability, so a draw picks a group
//! by its total weight, then a cell of it uniformly, then an unmasked pixel
//! of the cell uniformly: the per-pixel distribution of a per-cell CDF in 4
//! bytes a cell (paper scale, 46M cells: 184 MB instead of about 1.8 GB
//! held and 3.7 GB while building).
//!
//! Batches are still a pure function of `(seed, index)`, but the random
//! stream changed with this layout: the same seed gives other batches (of
//! the same distribution) than the per-cell sampler before it. The clusters
//! are that sampler's (the same fit sample, starting centres and Lloyd
//! steps), but for cells at a floating-point tie between two centres:
//! distances are now summed in vectorised partial sums.

mod cluster;
mod layout;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::DatasetError;
use crate::sampler::{RayBatch, SamplerConfig, batch_at, check_frames};
use crate::scene::Scene;
use layout::{Layout, draw_in_cell};

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

/// The cells of one cluster with one unmasked pixel count, which all have
/// the same probability: `order[start..start + len]`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Group {
    /// Total weight of this group and the ones before it.
    cdf: f64,
    start: u32,
    len: u32,
}

/// Draws seeded batches of pixels with feature-balanced probabilities.
#[derive(Debug, Clone)]
pub struct BalancedSampler {
    frames: Vec<usize>,
    layout: Layout,
    /// Every cell with an unmasked pixel, grouped (see [`Group`]).
    order: Vec<u32>,
    groups: Vec<Group>,
    /// Fraction of the unmasked interior pixels in each cluster (the last
    /// entry: pixels without a target).
    pub cluster_fractions: Vec<f64>,
}

impl BalancedSampler {
    /// Clusters the targets of `frames` and builds the sampling weights.
    /// `None` when the scene has no feature maps (nothing to balance).
    ///
    /// The nearest-centre assignment of the cells runs on every available
    /// core; a cell takes 4 bytes once built (6 while building).
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
        let layout = Layout::new(scene, fs, frames, border_margin)?;
        let (bits, count) = cluster::targets(&layout, scene, fs);
        let centres = cluster::fit(&layout, fs, (&bits, count), balance.clusters, seed);
        let ids = cluster::assign(&layout, fs, &bits, &centres);
        drop(bits);
        let k = centres.len() / fs.dim().max(1);
        let (order, groups, share) = group(&layout, scene, &ids, k, balance.power);
        if order.is_empty() {
            return Err(DatasetError::invalid(
                &scene.name,
                "every interior pixel of the frames sampled from is masked out",
            ));
        }
        Ok(Some(Self {
            frames: frames.to_vec(),
            layout,
            order,
            groups,
            cluster_fractions: share,
        }))
    }

    /// Batch number `index` (a pure function of `seed` and `index`, so
    /// training resumes exactly; not the batch the per-cell sampler before
    /// this one drew for the same seed, see [`crate::balance`]).
    pub fn batch(&self, config: &SamplerConfig, seed: u64, scene: &Scene, index: u64) -> RayBatch {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0b5e_55ed);
        rng.set_stream(index);
        let total = self.groups.last().map_or(0.0, |g| g.cdf);
        let picks: Vec<(usize, u32, u32)> = (0..config.rays_per_batch)
            .map(|_| {
                let u = rng.random_range(0.0..total.max(f64::MIN_POSITIVE));
                let i = self
                    .groups
                    .partition_point(|g| g.cdf <= u)
                    .min(self.groups.len() - 1);
                let g = self.groups[i];
                let cell = self.order[g.start as usize + rng.random_range(0..g.len as usize)];
                let at = self.layout.locate(cell as usize);
                let fi = self.layout.frames[at.slot].frame;
                draw_in_cell(&mut rng, scene, fi, at.x, at.y)
            })
            .collect();
        batch_at(config, scene, &self.frames, &picks)
    }

    /// Heap bytes the sampler holds: 4 per cell with an unmasked pixel,
    /// plus the frame grids (one per frame geometry), the groups (a few
    /// per cluster: one per unmasked pixel count its cells have) and the
    /// cluster fractions. The scene is not counted.
    pub fn memory_bytes(&self) -> usize {
        self.frames.capacity() * size_of::<usize>()
            + self.layout.memory_bytes()
            + self.order.capacity() * size_of::<u32>()
            + self.groups.capacity() * size_of::<Group>()
            + self.cluster_fractions.capacity() * size_of::<f64>()
    }
}

/// The cells with an unmasked pixel grouped by cluster (`ids`, `k` = no
/// target) and unmasked pixel count, the groups with their cumulative
/// weights `pixels * share[cluster]^-power`, and the pixel share of each
/// cluster (`k + 1` entries).
fn group(
    layout: &Layout,
    scene: &Scene,
    ids: &[u16],
    k: usize,
    power: f64,
) -> (Vec<u32>, Vec<Group>, Vec<f64>) {
    // Counts per (pixel count, cluster): pixel counts get dense slots in
    // the order they appear (a few without masks: the span lengths).
    let mut slot_of_pixels: Vec<u32> = Vec::new();
    let mut slot_pixels: Vec<u32> = Vec::new();
    let mut counts: Vec<u32> = Vec::new();
    let mut cluster_pixels = vec![0u64; k + 1];
    layout.visit(scene, |cell, px| {
        let p = px as usize;
        if slot_of_pixels.len() <= p {
            slot_of_pixels.resize(p + 1, u32::MAX);
        }
        if slot_of_pixels[p] == u32::MAX {
            slot_of_pixels[p] = slot_pixels.len() as u32;
            slot_pixels.push(px);
            counts.resize(counts.len() + k + 1, 0);
        }
        let g = ids[cell] as usize;
        counts[slot_of_pixels[p] as usize * (k + 1) + g] += 1;
        cluster_pixels[g] += u64::from(px);
    });
    // Integer pixel sums are exact in f64, so the shares equal the
    // per-cell sums of the previous sampler bit for bit.
    let mut share: Vec<f64> = cluster_pixels.iter().map(|&p| p as f64).collect();
    let total: f64 = share.iter().sum::<f64>().max(1.0);
    share.iter_mut().for_each(|s| *s /= total);
    // Groups cluster by cluster; `next` is where a group's next cell goes.
    let mut groups = Vec::new();
    let mut next = vec![0u32; counts.len()];
    let (mut start, mut acc) = (0u32, 0.0);
    for (g, &f) in share.iter().enumerate() {
        let weight = f.max(1e-12).powf(-power);
        for (s, &px) in slot_pixels.iter().enumerate() {
            let len = counts[s * (k + 1) + g];
            if len > 0 {
                acc += len as f64 * px as f64 * weight;
                groups.push(Group {
                    cdf: acc,
                    start,
                    len,
                });
                next[s * (k + 1) + g] = start;
                start += len;
            }
        }
    }
    let mut order = vec![0u32; start as usize];
    layout.visit(scene, |cell, px| {
        let key = slot_of_pixels[px as usize] as usize * (k + 1) + ids[cell] as usize;
        order[next[key] as usize] = cell as u32;
        next[key] += 1;
    });
    (order, groups, share)
}
