//! What a session measures its field on: the held-out frames (the training
//! frames when none are held out), a fixed sample of their interior pixels
//! for the periodic evaluations, and the views in full at the end.

use std::path::Path;

use burn::module::Module;
use datasets::Scene;
use field_ops::run_dir::Split;
use model::OpenNerf;

use crate::accuracy::EvalMetrics;
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::evaluate::{EvalPixels, eval_pixels, evaluate_pixels};
use crate::view_eval::{ViewFigures, evaluate_views};

/// The held-out frames and pixels of a session.
#[derive(Debug, Clone)]
pub(super) struct HeldOut {
    /// Frame indices measured.
    pub frames: Vec<usize>,
    pixels: EvalPixels,
    render_chunk: usize,
    border_margin: u32,
}

impl HeldOut {
    /// Draws the pixel sample (fixed by the run's seed). Rendering runs on
    /// the device of the model it is given (an inference model).
    pub(super) fn new(
        scene: &Scene,
        split: &Split,
        config: &TrainConfig,
    ) -> Result<Self, TrainError> {
        let frames: Vec<usize> = if split.heldout.is_empty() {
            split.train.clone()
        } else {
            split.heldout.clone()
        };
        let pixels = eval_pixels(
            scene,
            &frames,
            config.logging.eval_pixels,
            config.sampler.border_margin,
            config.sampler.min_near,
            config.seed,
        )?;
        Ok(Self {
            frames,
            pixels,
            render_chunk: config.logging.render_chunk,
            border_margin: config.sampler.border_margin,
        })
    }

    /// Figures of `model` on the pixel sample.
    pub(super) fn sample(&self, model: &OpenNerf, scene: &Scene) -> EvalMetrics {
        evaluate_pixels(&model.valid(), scene, &self.pixels, self.render_chunk)
    }

    /// The final figures of `model`: with `render`, the views in full
    /// (their pictures, strips and contact sheet written into `renders`;
    /// as many as [`full_render_views`] allows), on interior pixels, on
    /// every pixel and per view; else on the pixel sample only.
    pub(super) fn last(
        &self,
        model: &OpenNerf,
        scene: &Scene,
        render: bool,
        renders: &Path,
    ) -> Result<FinalEval, TrainError> {
        let valid = model.valid();
        let start = std::time::Instant::now();
        let (interior, whole, views, rays) = if render {
            let rendered = full_render_views(scene, &self.frames);
            if rendered.len() < self.frames.len() {
                eprintln!(
                    "held-out views rendered in full: {} of {}, evenly spaced (at most {} \
                     million pixels; the periodic figures cover all of them)",
                    rendered.len(),
                    self.frames.len(),
                    FULL_RENDER_PIXELS / 1_000_000
                );
            }
            let m = evaluate_views(
                &valid,
                scene,
                &rendered,
                self.border_margin,
                self.render_chunk,
                renders,
            )?;
            let rays: usize = rendered
                .iter()
                .map(|&f| {
                    let k = &scene.frames[f].camera.intrinsics;
                    k.width as usize * k.height as usize
                })
                .sum();
            (m.interior, Some(m.whole), m.views, rays)
        } else {
            let m = evaluate_pixels(&valid, scene, &self.pixels, self.render_chunk);
            (m, None, Vec::new(), self.pixels.rays.len())
        };
        Ok(FinalEval {
            interior,
            whole,
            views,
            rays_per_second: rays as f64 / start.elapsed().as_secs_f64().max(1e-9),
        })
    }
}

/// The most pixels the final render of the held-out views covers: a
/// capture of hundreds of held-out frames would otherwise take longer to
/// render than to train.
pub const FULL_RENDER_PIXELS: usize = 4_000_000;

/// The held-out `frames` rendered in full at the end: all of them when
/// their pixels are at most [`FULL_RENDER_PIXELS`], else as many as fit
/// (at least one), evenly spaced.
pub fn full_render_views(scene: &Scene, frames: &[usize]) -> Vec<usize> {
    let pixels = |f: usize| {
        let k = &scene.frames[f].camera.intrinsics;
        k.width as usize * k.height as usize
    };
    let total: usize = frames.iter().map(|&f| pixels(f)).sum();
    if total <= FULL_RENDER_PIXELS || frames.is_empty() {
        return frames.to_vec();
    }
    let per_view = total.div_ceil(frames.len()).max(1);
    let count = (FULL_RENDER_PIXELS / per_view).clamp(1, frames.len());
    (0..count)
        .map(|i| frames[i * frames.len() / count])
        .collect()
}

/// The final figures of a session.
#[derive(Debug, Clone)]
pub(super) struct FinalEval {
    /// On interior pixels.
    pub interior: EvalMetrics,
    /// On every pixel (when the views were rendered in full).
    pub whole: Option<EvalMetrics>,
    /// Per view (when the views were rendered in full).
    pub views: Vec<ViewFigures>,
    /// Rays rendered per second (the rendering, the metrics and, for the
    /// full views, writing their PNGs).
    pub rays_per_second: f64,
}
