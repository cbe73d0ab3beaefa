//! Training ray batches drawn from the training frames of a scene, and
//! their upload to the device.
//!
//! Batch `i` is batch number `i` of the dataset sampler seeded with the run's
//! seed, so the whole sampler position is the iteration number: a resumed run
//! draws exactly the batches the uninterrupted run would have drawn.

use burn::tensor::{Device, Tensor, TensorData};
use datasets::Scene;
use datasets::sampler::{RayBatch, SamplerConfig, sample_batch_from};
use model::Rays;

use crate::config::SamplerSettings;
use crate::error::TrainError;

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

/// The batch of `iteration`: a frame uniformly from `frames` (scene indices
/// of the training frames), then a pixel uniformly among those at least
/// `border_margin` from the border (the margin shrinks for images too small
/// to have an interior). Depth targets are 0 with weight 0 on frames without
/// depth, feature targets zero on frames without a map.
pub fn sample_batch(
    scene: &Scene,
    frames: &[usize],
    settings: &SamplerSettings,
    seed: u64,
    iteration: usize,
) -> Result<RayBatch, TrainError> {
    let config = SamplerConfig {
        rays_per_batch: settings.rays_per_batch,
        border_margin: settings.border_margin,
        seed,
        min_near: settings.min_near,
    };
    Ok(sample_batch_from(&config, scene, frames, iteration as u64)?)
}

/// Uploads `batch` to `device`.
pub fn to_tensors(batch: &RayBatch, device: &Device) -> BatchTensors {
    let n = batch.len();
    let t2 = |v: Vec<f32>, c: usize| Tensor::<2>::from_data(TensorData::new(v, [n, c]), device);
    BatchTensors {
        rays: Rays::from_normalized(&batch.rays, device),
        rgb: t2(batch.rgb.as_flattened().to_vec(), 3),
        depth: batch
            .depth
            .as_ref()
            .zip(batch.depth_weight.as_ref())
            .map(|(d, w)| (t2(d.clone(), 1), t2(w.clone(), 1))),
        feature: batch
            .features
            .as_ref()
            .map(|f| t2(f.clone(), batch.feature_dim)),
    }
}
