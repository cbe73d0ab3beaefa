//! Training ray batches drawn from the training frames of a scene, and
//! their upload to the device.
//!
//! Batch `i` is batch number `i` of the dataset sampler seeded with the run's
//! seed, so the whole sampler position is the iteration number: a resumed run
//! draws exactly the batches the uninterrupted run would have drawn.

use burn::tensor::{Device, Int, Tensor, TensorData};
use datasets::Scene;
use datasets::balance::{BalanceConfig, BalancedSampler};
use datasets::sampler::{RayBatch, SamplerConfig, depth_pixels, sample_batch_from, sample_listed};
use model::FeatureSpace;
use model::geometry::NormalizedRay;

use crate::error::TrainError;

/// A training batch: its rays on the host (rendering uploads them) and
/// its targets as device tensors, row `i` the target of ray `i`.
#[derive(Debug, Clone)]
pub struct BatchTensors {
    /// Rays in the normalised frame.
    pub rays: Vec<NormalizedRay>,
    /// The frame each ray was drawn from (the scene's frame index).
    pub frames: Vec<usize>,
    /// `[n, 3]`.
    pub rgb: Tensor<2>,
    /// `[n, 1]` colour-loss weights (`None`: all 1).
    pub rgb_weight: Option<Tensor<2>>,
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

impl BatchTensors {
    /// The rays `rows` (indices into the batch, e.g. those a render kept,
    /// see `model::RenderOutputs::kept`) with their targets, in that order.
    pub fn select(&self, rows: &[usize]) -> BatchTensors {
        let device = self.rgb.device();
        let ids: Vec<i64> = rows.iter().map(|&r| r as i64).collect();
        let idx = Tensor::<1, Int>::from_data(TensorData::new(ids, [rows.len()]), &device);
        let pick = |t: &Tensor<2>| t.clone().select(0, idx.clone());
        BatchTensors {
            rays: rows.iter().map(|&r| self.rays[r]).collect(),
            frames: rows.iter().map(|&r| self.frames[r]).collect(),
            rgb: pick(&self.rgb),
            rgb_weight: self.rgb_weight.as_ref().map(pick),
            depth: self.depth.as_ref().map(|(d, w)| (pick(d), pick(w))),
            feature: self.feature.as_ref().map(|f| FeatureTargets {
                values: pick(&f.values),
                mask: pick(&f.mask),
                space: f.space.clone(),
            }),
        }
    }
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
///
/// Novel views are drawn apart from the captured frames: each batch gives
/// them their share of the pixels (uniformly over their pixels), and the
/// rest of the batch comes from the captured frames exactly as without
/// views (the same clusters and weights). Clustering the novel views' maps
/// together with the captured ones would re-cluster the capture itself: on
/// the seed-21 bench room, 24 views holding 3% of the pixels moved the
/// captured rays of whole classes by factors of 0.3 to 3 (window -63%,
/// chair -71%, tv-screen +195%), a change of the training stream that has
/// nothing to do with what the views show.
#[derive(Debug, Clone)]
pub struct TrainSampler {
    config: SamplerConfig,
    seed: u64,
    frames: Vec<usize>,
    novel: Vec<usize>,
    novel_rays: usize,
    balanced: Option<BalancedSampler>,
    /// The training pixels with a depth target, when `config.depth_rays`
    /// draws from them.
    depth_pixels: Vec<(usize, u32, u32)>,
    depth_rays: usize,
}

/// Salt of the novel views' draws (a stream apart from the captured one).
const NOVEL_STREAM: u64 = 0x6e6f_7665_6c21;

/// Salt of the draws among the pixels with a depth target.
const DEPTH_STREAM: u64 = 0x6465_7074_6821;

impl TrainSampler {
    /// Builds the sampler of `frames` of `scene` (clustering the feature
    /// targets when balancing).
    pub fn new(
        scene: &Scene,
        frames: &[usize],
        config: &SamplerConfig,
        seed: u64,
    ) -> Result<Self, TrainError> {
        Self::with_novel(scene, frames, &[], config, seed)
    }

    /// The sampler of the captured training `frames` and the `novel`
    /// views of `scene` (see [`TrainSampler`]).
    pub fn with_novel(
        scene: &Scene,
        frames: &[usize],
        novel: &[usize],
        config: &SamplerConfig,
        seed: u64,
    ) -> Result<Self, TrainError> {
        let balanced = match BalanceConfig::of(config) {
            Some(balance) => {
                BalancedSampler::new(scene, frames, config.border_margin, &balance, seed)?
            }
            None => None,
        };
        let novel_rays = novel_rays(scene, frames, novel, config.rays_per_batch);
        let (depth_pixels, depth_rays) = if config.depth_rays > 0 {
            let pixels = depth_pixels(scene, frames, config.border_margin);
            if pixels.is_empty() {
                return Err(TrainError::Config(format!(
                    "sampler.depth_rays is {} but no training pixel has a depth target \
                     (COLMAP: --sparse-depth or --colmap-depth)",
                    config.depth_rays
                )));
            }
            let room = config.rays_per_batch.saturating_sub(novel_rays + 1);
            (pixels, config.depth_rays.min(room))
        } else {
            (Vec::new(), 0)
        };
        Ok(Self {
            config: *config,
            seed,
            frames: frames.to_vec(),
            novel: novel.to_vec(),
            novel_rays,
            balanced,
            depth_pixels,
            depth_rays,
        })
    }

    /// The batch of `iteration`.
    pub fn batch(&self, scene: &Scene, iteration: usize) -> Result<RayBatch, TrainError> {
        let captured = SamplerConfig {
            rays_per_batch: self.config.rays_per_batch - self.novel_rays - self.depth_rays,
            ..self.config
        };
        let mut batch = match &self.balanced {
            Some(b) => b.batch(&captured, self.seed, scene, iteration as u64),
            None => sample_batch_from(&captured, self.seed, scene, &self.frames, iteration as u64)?,
        };
        if self.novel_rays > 0 {
            let config = SamplerConfig {
                rays_per_batch: self.novel_rays,
                ..self.config
            };
            let seed = self.seed ^ NOVEL_STREAM;
            batch.append(sample_batch_from(
                &config,
                seed,
                scene,
                &self.novel,
                iteration as u64,
            )?)?;
        }
        if self.depth_rays > 0 {
            batch.append(sample_listed(
                &self.config,
                self.seed ^ DEPTH_STREAM,
                scene,
                &self.frames,
                &self.depth_pixels,
                self.depth_rays,
                iteration as u64,
            ))?;
        }
        Ok(batch)
    }
}

/// The novel views' rays in a batch of `rays`: their share of the pixels of
/// `frames` and `novel` together, rounded, at least 1 and leaving at least
/// one captured ray (0 without views).
pub fn novel_rays(scene: &Scene, frames: &[usize], novel: &[usize], rays: usize) -> usize {
    let pixels = |f: &[usize]| -> f64 {
        f.iter()
            .filter_map(|&i| scene.frames.get(i))
            .map(|f| f.rgb.width as f64 * f.rgb.height as f64)
            .sum()
    };
    let (captured, added) = (pixels(frames), pixels(novel));
    if novel.is_empty() || added <= 0.0 || rays < 2 {
        return 0;
    }
    ((rays as f64 * added / (captured + added)).round() as usize).clamp(1, rays - 1)
}

/// Uploads `batch` to `device`; its feature targets are compared in `space`
/// (see [`feature_space`]).
pub fn to_tensors(batch: &RayBatch, space: &FeatureSpace, device: &Device) -> BatchTensors {
    let n = batch.len();
    let t2 = |v: Vec<f32>, c: usize| Tensor::<2>::from_data(TensorData::new(v, [n, c]), device);
    BatchTensors {
        rays: batch.rays.clone(),
        frames: batch.pixels.iter().map(|p| p[0] as usize).collect(),
        rgb: t2(batch.rgb.as_flattened().to_vec(), 3),
        rgb_weight: batch.rgb_weight.as_ref().map(|w| t2(w.clone(), 1)),
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

#[cfg(test)]
mod tests {
    use super::*;
    use datasets::synthetic::{SceneSize, generate};
    use model::{
        FeatureHeadConfig, MipMlpConfig, OccupancyConfig, OccupancyGrid, OpenNerfConfig,
        RenderRequest,
    };

    fn ray_batch(n: usize) -> RayBatch {
        let rays = (0..n)
            .map(|i| {
                // Rays along +x at heights from -3 to 3: the low ones pass
                // through the lower half of the cube only.
                let y = -3.0 + 6.0 * i as f32 / (n - 1) as f32;
                NormalizedRay {
                    origin: [-4.0, y, 0.1],
                    direction: [1.0, 0.0, 0.0],
                    radius: 0.01,
                    near: 1.0,
                    far: 7.0,
                }
            })
            .collect();
        RayBatch {
            rays,
            rgb: (0..n).map(|i| [i as f32; 3]).collect(),
            rgb_weight: Some((0..n).map(|i| 0.5 * (i % 3) as f32).collect()),
            depth: Some((0..n).map(|i| i as f32).collect()),
            depth_weight: Some(vec![1.0; n]),
            features: Some((0..2 * n).map(|i| i as f32).collect()),
            feature_mask: Some(vec![1.0; n]),
            feature_dim: 2,
            pixels: (0..n as u32).map(|i| [0, i, 0]).collect(),
        }
    }

    fn host(t: &Tensor<2>) -> Vec<f32> {
        t.clone().into_data().try_into_vec_as::<f32>().expect("f32")
    }

    /// The rays a render keeps behind the grid and the targets selected for
    /// them stay paired.
    #[test]
    fn targets_follow_their_rays_through_the_clip() {
        // Only cells with y < 0 hold density; the first update decides
        // alone, no dilation, rays over free space skipped at once.
        let config = OccupancyConfig::new()
            .with_resolution(4)
            .with_early_samples(1)
            .with_early_updates(0)
            .with_dilation(0)
            .with_keep_dropped_updates(0);
        let mut grid = OccupancyGrid::new(&config);
        let d: Vec<f32> = (0..64)
            .map(|c| if (c / 4) % 4 < 2 { 10.0 } else { 0.0 })
            .collect();
        grid.update(&d);
        let device = Device::flex();
        let model = OpenNerfConfig::new(FeatureHeadConfig::new(2).with_width(8))
            .with_mlp(
                MipMlpConfig::new()
                    .with_width(16)
                    .with_depth(2)
                    .with_skip_layer(1),
            )
            .with_num_samples(4)
            .init(&device)
            .with_occupancy(Some(grid));
        let b = ray_batch(9);
        let tensors = to_tensors(&b, &FeatureSpace::Identity, &device);
        let out = model.render(&RenderRequest::train(&b.rays).with_randomized(false));
        let stats = out.clip.expect("the model's grid");
        assert_eq!(stats.drawn, 9);
        let kept = out.kept.expect("rays dropped");
        assert_eq!(kept.len(), stats.kept);
        assert_eq!(out.fine.rgb.dims()[0], stats.kept);
        assert!(stats.kept > 0 && stats.kept < 9, "kept {}", stats.kept);
        let t = tensors.select(&kept);
        let rgb = host(&t.rgb);
        for (j, (&i, r)) in kept.iter().zip(&t.rays).enumerate() {
            assert!(r.origin[1] < 0.0);
            assert_eq!(*r, b.rays[i]);
            assert_eq!(rgb[3 * j..3 * j + 3], [b.pixels[i][1] as f32; 3]);
        }
        let j = 1;
        let i = kept[j];
        let (depth, _) = t.depth.as_ref().expect("depth");
        assert_eq!(host(depth)[j], i as f32);
        let w = host(t.rgb_weight.as_ref().expect("weights"));
        assert_eq!(w[j], 0.5 * (i % 3) as f32);
        let f = host(&t.feature.as_ref().expect("features").values);
        assert_eq!(
            &f[2 * j..2 * j + 2],
            &[2.0 * i as f32, 2.0 * i as f32 + 1.0]
        );
    }

    #[test]
    fn novel_views_get_their_pixel_share_and_leave_the_capture_stream_alone() {
        let scene = generate(5, SceneSize::Ci).expect("scene");
        let train: Vec<usize> = (0..14).collect();
        let novel: Vec<usize> = (14..18).collect();
        let config = SamplerConfig::default();
        let rays = config.rays_per_batch;
        // Frames of one size: 4 of 18 hold 4/18 of the pixels.
        let n = novel_rays(&scene, &train, &novel, rays);
        assert_eq!(n, (rays as f64 * 4.0 / 18.0).round() as usize);
        assert_eq!(novel_rays(&scene, &train, &[], rays), 0);
        let mixed = TrainSampler::with_novel(&scene, &train, &novel, &config, 9).expect("sampler");
        let captured_only = SamplerConfig {
            rays_per_batch: rays - n,
            ..config
        };
        let capture = TrainSampler::new(&scene, &train, &captured_only, 9).expect("sampler");
        let balance = BalanceConfig::of(&config).expect("balanced");
        let old = BalancedSampler::new(&scene, &train, config.border_margin, &balance, 9)
            .expect("old")
            .expect("maps");
        let mut per_view = [0usize; 4];
        for it in 0..60 {
            let b = mixed.batch(&scene, it).expect("batch");
            assert_eq!(b.len(), rays);
            // The captured part is the capture's own batch, rays for rays.
            let c = capture.batch(&scene, it).expect("capture");
            assert_eq!(b.pixels[..rays - n], c.pixels[..]);
            assert_eq!(
                c.pixels,
                old.batch(&captured_only, 9, &scene, it as u64).pixels
            );
            for p in &b.pixels[rays - n..] {
                let f = p[0] as usize;
                assert!(novel.contains(&f), "novel ray from frame {f}");
                per_view[f - 14] += 1;
            }
        }
        // Uniform over the views: each gets about a quarter.
        let total = (60 * n) as f64;
        for c in per_view {
            assert!((c as f64 / total - 0.25).abs() < 0.05, "{per_view:?}");
        }
    }

    #[test]
    fn depth_rays_come_from_the_depth_pixels_and_leave_the_rest_alone() {
        let mut scene = generate(5, SceneSize::Ci).expect("scene");
        // Sparse depth: only every 97th pixel keeps its target.
        for f in &mut scene.frames {
            let d = f.depth.as_mut().expect("synthetic depth");
            for (i, v) in d.values_mut().iter_mut().enumerate() {
                if i % 97 != 0 {
                    *v = 0.0;
                }
            }
        }
        let train: Vec<usize> = (0..14).collect();
        let plain = SamplerConfig {
            feature_balance: 0.0,
            ..SamplerConfig::default()
        };
        let config = SamplerConfig {
            depth_rays: 40,
            ..plain
        };
        let rays = config.rays_per_batch;
        let sampler = TrainSampler::new(&scene, &train, &config, 9).expect("sampler");
        let rest = SamplerConfig {
            rays_per_batch: rays - 40,
            ..plain
        };
        let uniform = TrainSampler::new(&scene, &train, &rest, 9).expect("sampler");
        let mut with_target = 0;
        for it in 0..20 {
            let b = sampler.batch(&scene, it).expect("batch");
            assert_eq!(b.len(), rays);
            assert_eq!(b, sampler.batch(&scene, it).expect("again"));
            // The uniform part is the uniform sampler's batch, ray for ray.
            assert_eq!(
                b.pixels[..rays - 40],
                uniform.batch(&scene, it).expect("b").pixels[..]
            );
            let depth = b.depth.as_ref().expect("depth");
            for (p, d) in b.pixels[rays - 40..].iter().zip(&depth[rays - 40..]) {
                assert!(train.contains(&(p[0] as usize)), "{p:?}");
                assert!(*d > 0.0, "a depth ray without a target at {p:?}");
            }
            with_target += depth[..rays - 40].iter().filter(|&&d| d > 0.0).count();
        }
        // Uniform rays hit a target about once in 97 draws.
        assert!(with_target < 20 * (rays - 40) / 30, "{with_target}");
        for f in &mut scene.frames {
            f.depth = None;
        }
        let err = TrainSampler::new(&scene, &train, &config, 9)
            .expect_err("no depth")
            .to_string();
        assert!(
            err.contains("sampler.depth_rays") && err.contains("--sparse-depth"),
            "{err}"
        );
    }
}
