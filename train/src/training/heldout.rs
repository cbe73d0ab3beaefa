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
    /// as many as [`spread_within`] allows within [`FULL_RENDER_PIXELS`]), on interior pixels, on
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
            let pixels: Vec<usize> = self
                .frames
                .iter()
                .map(|&f| {
                    let k = &scene.frames[f].camera.intrinsics;
                    k.width as usize * k.height as usize
                })
                .collect();
            let chosen = spread_within(&pixels, FULL_RENDER_PIXELS);
            if chosen.len() < self.frames.len() {
                eprintln!(
                    "held-out views rendered in full: {} of {}, evenly spaced (at most {} \
                     million pixels; the periodic figures cover all of them)",
                    chosen.len(),
                    self.frames.len(),
                    FULL_RENDER_PIXELS / 1_000_000
                );
            }
            let rendered: Vec<usize> = chosen.iter().map(|&i| self.frames[i]).collect();
            let m = evaluate_views(
                &valid,
                scene,
                &rendered,
                self.border_margin,
                self.render_chunk,
                renders,
            )?;
            let rays: usize = chosen.iter().map(|&i| pixels[i]).sum();
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
pub const FULL_RENDER_PIXELS: usize = 6_000_000;

/// The views (indices into `pixels`, each view's pixels) rendered in full:
/// all of them when their pixels add up to at most `budget`, else as many
/// views of the mean size as fit (at least one), evenly spaced.
pub fn spread_within(pixels: &[usize], budget: usize) -> Vec<usize> {
    let (n, total) = (pixels.len(), pixels.iter().sum::<usize>());
    if total <= budget {
        return (0..n).collect();
    }
    let count = (budget / total.div_ceil(n)).clamp(1, n);
    (0..count).map(|i| i * n / count).collect()
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

#[cfg(test)]
mod tests {
    use super::spread_within;

    #[test]
    fn views_within_the_budget_are_all_rendered_and_the_rest_spread_evenly() {
        assert_eq!(spread_within(&[10; 3], 30), vec![0, 1, 2]);
        assert_eq!(spread_within(&[], 30), Vec::<usize>::new());
        // Ten views of 10 pixels in 45: four, a quarter of the way apart.
        assert_eq!(spread_within(&[10; 10], 45), vec![0, 2, 5, 7]);
        // A single view over the budget is still rendered.
        assert_eq!(spread_within(&[100, 100], 30), vec![0]);
        // The chosen views fit (views of one size).
        for n in 1..40 {
            let chosen = spread_within(&vec![7; n], 50);
            assert!(
                chosen.len() * 7 <= 50 || chosen.len() == 1,
                "{n}: {chosen:?}"
            );
            assert!(chosen.windows(2).all(|w| w[0] < w[1]), "{n}: {chosen:?}");
        }
    }
}
