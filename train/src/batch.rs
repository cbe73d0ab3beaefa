//! Training ray batches drawn from the training frames of a scene, and
//! their upload to the device.
//!
//! Batch `i` is batch number `i` of the dataset sampler seeded with the run's
//! seed, so the whole sampler position is the iteration number: a resumed run
//! draws exactly the batches the uninterrupted run would have drawn.

use burn::tensor::{Device, Tensor, TensorData};
use datasets::Scene;
use datasets::balance::{BalanceConfig, BalancedSampler};
use datasets::sampler::{RayBatch, SamplerConfig, sample_batch_from};
use model::{FeatureSpace, Rays};

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
    /// Feature targets.
    pub feature: Option<FeatureTargets>,
}

/// Feature targets of a batch and the space they are compared in.
#[derive(Debug, Clone)]
pub struct FeatureTargets {
    /// `[n, k]` targets (zero rows where there is none).
    pub values: Tensor<2>,
    /// `[n, 1]`: 1 where the ray has a target, 0 where not.
    pub mask: Tensor<2>,
    /// Identity, or the lift of PCA coefficients.
    pub space: FeatureSpace,
}

impl FeatureTargets {
    /// Targets that are all valid, compared as they are (tests, benchmarks).
    pub fn dense(values: Tensor<2>) -> Self {
        let [n, _] = values.dims();
        let mask = Tensor::ones([n, 1], &values.device());
        Self {
            values,
            mask,
            space: FeatureSpace::Identity,
        }
    }
}

/// The space the loss compares `scene`'s features in: the PCA lift when its
/// maps are compressed, else identity.
pub fn feature_space(scene: &Scene, device: &Device) -> FeatureSpace {
    let Some(pca) = scene.features.as_ref().and_then(|f| f.pca.as_ref()) else {
        return FeatureSpace::Identity;
    };
    let mean: Vec<f64> = pca.mean.iter().map(|&x| x as f64).collect();
    let mean_proj: Vec<f32> = pca
        .components
        .chunks_exact(pca.dim.max(1))
        .map(|row| {
            row.iter()
                .zip(&mean)
                .map(|(&u, m)| u as f64 * m)
                .sum::<f64>() as f32
        })
        .collect();
    FeatureSpace::Lifted {
        mean_proj: Box::new(Tensor::from_data(
            TensorData::new(mean_proj, [1, pca.k]),
            device,
        )),
        mean_sq: mean.iter().map(|m| m * m).sum::<f64>() as f32,
    }
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

/// Draws the training batches of a run: feature-balanced (see
/// `datasets::balance`) when the scene has feature maps and
/// `feature_balance > 0`, else a frame uniformly from the training frames
/// and a pixel uniformly inside the (scaled) border margin. Batch `i`
/// depends only on the seed and `i`, so a resumed run draws what an
/// uninterrupted one would.
#[derive(Debug, Clone)]
pub struct TrainSampler {
    config: SamplerConfig,
    seed: u64,
    frames: Vec<usize>,
    balanced: Option<BalancedSampler>,
}

impl TrainSampler {
    /// Builds the sampler of `frames` of `scene` (clustering the feature
    /// targets when balancing).
    pub fn new(
        scene: &Scene,
        frames: &[usize],
        config: &SamplerConfig,
        seed: u64,
    ) -> Result<Self, TrainError> {
        let balanced = match BalanceConfig::of(config) {
            Some(balance) => {
                BalancedSampler::new(scene, frames, config.border_margin, &balance, seed)?
            }
            None => None,
        };
        Ok(Self {
            config: *config,
            seed,
            frames: frames.to_vec(),
            balanced,
        })
    }

    /// The batch of `iteration`.
    pub fn batch(&self, scene: &Scene, iteration: usize) -> Result<RayBatch, TrainError> {
        Ok(match &self.balanced {
            Some(b) => b.batch(&self.config, self.seed, scene, iteration as u64),
            None => sample_batch_from(
                &self.config,
                self.seed,
                scene,
                &self.frames,
                iteration as u64,
            )?,
        })
    }
}

/// Uploads `batch` to `device`; its feature targets are compared in `space`
/// (see [`feature_space`]).
pub fn to_tensors(batch: &RayBatch, space: &FeatureSpace, device: &Device) -> BatchTensors {
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
            .zip(batch.feature_mask.as_ref())
            .map(|(f, m)| FeatureTargets {
                values: t2(f.clone(), batch.feature_dim),
                mask: t2(m.clone(), 1),
                space: space.clone(),
            }),
    }
}
