//! Training ray batches drawn from the training frames of a scene.
//!
//! The generator of iteration `i` is seeded from `(seed, i)` alone, so the
//! whole sampler position is the iteration number: a resumed run draws
//! exactly the batches the uninterrupted run would have drawn.

use burn::tensor::{Device, Tensor, TensorData};
use datasets::Scene;
use model::Rays;
use model::geometry::NormalizedRay;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::config::SamplerSettings;

/// One batch of rays with their targets, on the host.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainBatch {
    /// Normalised rays.
    pub rays: Vec<NormalizedRay>,
    /// Target colours, `rays.len() * 3`.
    pub rgb: Vec<f32>,
    /// Target z-depths (0 = invalid), when the scene has depth.
    pub depth: Option<Vec<f32>>,
    /// Per-ray depth weights (the frame's `depth_weight`).
    pub depth_weight: Vec<f32>,
    /// Target features, `rays.len() * feature_dim`, when the scene has features.
    pub feature: Option<Vec<f32>>,
    /// Channels per feature target.
    pub feature_dim: usize,
}

/// The batch as device tensors.
#[derive(Debug, Clone)]
pub struct BatchTensors {
    /// Rays.
    pub rays: Rays,
    /// `[n, 3]`.
    pub rgb: Tensor<2>,
    /// `[n, 1]` depths and weights.
    pub depth: Option<(Tensor<2>, Tensor<2>)>,
    /// `[n, k]`.
    pub feature: Option<Tensor<2>>,
}

/// A seed for iteration `iteration` of a run seeded with `seed`
/// (SplitMix64 of the pair, so neighbouring iterations are unrelated).
pub fn iteration_seed(seed: u64, iteration: usize) -> u64 {
    let mut z = seed
        .wrapping_mul(0x9e37_79b9_7f4a_7c15)
        .wrapping_add(iteration as u64)
        .wrapping_add(0x632b_e59b_d9b4_e019);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Draws the batch of `iteration`: a frame uniformly from `frames`, then a
/// pixel uniformly among those at least `border_margin` from the border
/// (the margin shrinks for images too small to have an interior).
pub fn sample_batch(
    scene: &Scene,
    frames: &[usize],
    settings: &SamplerSettings,
    seed: u64,
    iteration: usize,
) -> TrainBatch {
    let mut rng = ChaCha8Rng::seed_from_u64(iteration_seed(seed, iteration));
    let n = if frames.is_empty() {
        0
    } else {
        settings.rays_per_batch
    };
    let has_depth = frames.iter().any(|&f| scene.frames[f].depth.is_some());
    let feature_dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let mut batch = TrainBatch {
        rays: Vec::with_capacity(n),
        rgb: Vec::with_capacity(3 * n),
        depth: has_depth.then(|| Vec::with_capacity(n)),
        depth_weight: Vec::with_capacity(n),
        feature: scene
            .features
            .as_ref()
            .map(|_| Vec::with_capacity(n * feature_dim)),
        feature_dim,
    };
    for _ in 0..n {
        let f = frames[rng.random_range(0..frames.len())];
        let frame = &scene.frames[f];
        let (w, h) = (frame.rgb.width, frame.rgb.height);
        let m = settings
            .border_margin
            .min(w.saturating_sub(1) / 2)
            .min(h.saturating_sub(1) / 2);
        let x = rng.random_range(m..w - m);
        let y = rng.random_range(m..h - m);
        let ray = frame.camera.ray(x as f64, y as f64);
        batch
            .rays
            .push(scene.scene_box.normalize_ray(&ray, settings.min_near));
        batch.rgb.extend(frame.rgb.get(x, y));
        if let Some(d) = batch.depth.as_mut() {
            d.push(frame.depth.as_ref().map_or(0.0, |img| img.get(x, y)));
        }
        batch.depth_weight.push(frame.depth_weight);
        if let (Some(fs), Some(dst)) = (scene.features.as_ref(), batch.feature.as_mut()) {
            dst.extend(
                fs.maps[f]
                    .lookup(x as f64, y as f64, w, h)
                    .iter()
                    .map(|v| v.to_f32()),
            );
        }
    }
    batch
}

impl TrainBatch {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.rays.len()
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.rays.is_empty()
    }

    /// Uploads the batch to `device`.
    pub fn to_tensors(&self, device: &Device) -> BatchTensors {
        let n = self.len();
        let t2 = |v: Vec<f32>, c: usize| Tensor::<2>::from_data(TensorData::new(v, [n, c]), device);
        BatchTensors {
            rays: Rays::from_normalized(&self.rays, device),
            rgb: t2(self.rgb.clone(), 3),
            depth: self
                .depth
                .as_ref()
                .map(|d| (t2(d.clone(), 1), t2(self.depth_weight.clone(), 1))),
            feature: self
                .feature
                .as_ref()
                .map(|f| t2(f.clone(), self.feature_dim)),
        }
    }
}
