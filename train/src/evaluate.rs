//! Held-out evaluation on a fixed pixel subset, for the periodic checks
//! during training (the views in full at the end: [`crate::view_eval`]).

use datasets::Scene;
use datasets::sampler::{SamplerConfig, sample_batch_from};
use model::geometry::NormalizedRay;
use model::{FeatureMode, OpenNerf, RenderRequest};

use crate::accuracy::{EvalAccumulator, EvalMetrics};
use crate::error::TrainError;

/// A fixed set of held-out pixels with their targets, drawn once per run so
/// that every periodic evaluation (and the one at initialisation) measures
/// the same pixels.
#[derive(Debug, Clone)]
pub struct EvalPixels {
    /// Normalised rays.
    pub rays: Vec<NormalizedRay>,
    /// Target colours.
    pub rgb: Vec<[f32; 3]>,
    /// Target z-depths (0 = invalid), when the scene has depth.
    pub depth: Option<Vec<f32>>,
    /// Target features, `rays.len() * dim` values, when the scene has features.
    pub feature: Option<Vec<f32>>,
    /// Per ray, 1 where the feature target is valid.
    pub feature_mask: Option<Vec<f32>>,
}

/// Draws `count` pixels (at least `margin` pixels from the border)
/// uniformly from `frames` of `scene`, with a fixed `seed`, through the
/// same sampler as training (so targets are looked up the same way).
pub fn eval_pixels(
    scene: &Scene,
    frames: &[usize],
    count: usize,
    margin: u32,
    min_near: f64,
    seed: u64,
) -> Result<EvalPixels, TrainError> {
    if frames.is_empty() || count == 0 {
        return Ok(EvalPixels {
            rays: Vec::new(),
            rgb: Vec::new(),
            depth: None,
            feature: None,
            feature_mask: None,
        });
    }
    let config = SamplerConfig {
        rays_per_batch: count,
        border_margin: margin,
        min_near,
        ..SamplerConfig::default()
    };
    let batch = sample_batch_from(&config, seed ^ 0xe7a1_0000, scene, frames, 0)?;
    Ok(EvalPixels {
        rays: batch.rays,
        rgb: batch.rgb,
        depth: batch.depth,
        feature: batch.features,
        feature_mask: batch.feature_mask,
    })
}

/// Lifts PCA coefficients to the full feature space when the scene's
/// features were compressed (cosines are reported in the space the text
/// embeddings live in); otherwise returns the input.
pub fn lift_features(scene: &Scene, values: Vec<f32>) -> Vec<f32> {
    match scene.features.as_ref().and_then(|f| f.pca.as_ref()) {
        Some(pca) => pca.lift(&values),
        None => values,
    }
}

/// Renders the fixed pixels with `model` (an inference model, see
/// `Module::valid`) and measures them.
pub fn evaluate_pixels(
    model: &OpenNerf,
    scene: &Scene,
    pixels: &EvalPixels,
    chunk: usize,
) -> EvalMetrics {
    let mut acc = EvalAccumulator::default();
    let dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let mut start = 0;
    for part in pixels.rays.chunks(chunk.max(1)) {
        let mode = if dim > 0 {
            FeatureMode::Composited
        } else {
            FeatureMode::None
        };
        let request = RenderRequest::inference(part)
            .with_chunk(chunk)
            .with_features(mode)
            .with_background(scene.background);
        let out = model
            .render(&request)
            .expect("never cancelled without an observer");
        // The median depth, as the depth images show it (see
        // `model::RenderedRays::median_depth`).
        let (rgb, depth) = (out.rgb, out.median_depth);
        let feat = match (out.feature_dim > 0, pixels.feature.as_ref()) {
            (true, Some(_)) => Some(lift_features(scene, out.feature)),
            _ => None,
        };
        let target_feat = pixels
            .feature
            .as_ref()
            .map(|t| lift_features(scene, t[start * dim..(start + part.len()) * dim].to_vec()));
        let full = scene.features.as_ref().map_or(0, |f| f.full_dim);
        for i in 0..part.len() {
            let g = start + i;
            let d = pixels.depth.as_ref().map(|d| (depth[i], d[g]));
            let has_target = pixels.feature_mask.as_ref().is_some_and(|m| m[g] > 0.5);
            let f = match (&feat, &target_feat) {
                (Some(f), Some(t)) if has_target => {
                    Some((&f[i * full..(i + 1) * full], &t[i * full..(i + 1) * full]))
                }
                _ => None,
            };
            acc.add(
                [rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]],
                pixels.rgb[g],
                d,
                f,
            );
        }
        start += part.len();
    }
    acc.finish()
}
