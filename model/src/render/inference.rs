//! The inference pass: the fine level of every input ray on the host,
//! rendered chunk by chunk with early ray termination, with progress and
//! cancellation.

use super::grid::clip_for_inference;
use super::march::Termination;
use super::rendered::RenderedRays;
use super::sealed::{Sealed, Token};
use super::{FeatureMode, RenderPass, RenderRequest};
use crate::geometry::NormalizedRay;
use crate::nerf::{OpenNerf, Rays};

/// The inference pass (no autodiff graph is kept between chunks).
#[derive(Clone, Copy)]
pub struct Inference<'a> {
    /// Rays per forward pass (the peak memory is that of one chunk; 0 is
    /// taken as 1).
    pub chunk: usize,
    /// When a ray stops being evaluated.
    pub termination: Termination,
    /// Called with `(rays rendered, rays to render)` after every chunk (the
    /// rays to render are those the grid leaves); returning `false` cancels
    /// the render.
    pub observer: Option<&'a dyn Fn(usize, usize) -> bool>,
}

impl Default for Inference<'_> {
    /// Chunks of 4096 rays, the default [`Termination`], no observer.
    fn default() -> Self {
        Inference {
            chunk: 4096,
            termination: Termination::default(),
            observer: None,
        }
    }
}

impl std::fmt::Debug for Inference<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Inference")
            .field("chunk", &self.chunk)
            .field("termination", &self.termination)
            .field("observer", &self.observer.is_some())
            .finish()
    }
}

/// A render stopped by its observer. Only a request with an observer is
/// ever cancelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cancelled;

impl std::fmt::Display for Cancelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("rendering was cancelled")
    }
}

impl std::error::Error for Cancelled {}

impl Sealed for Inference<'_> {}

impl RenderPass for Inference<'_> {
    type Output = Result<RenderedRays, Cancelled>;

    fn run(
        model: &OpenNerf,
        request: &RenderRequest<'_, Self>,
        _: Token,
    ) -> Result<RenderedRays, Cancelled> {
        let bounded = model.extent.bound_rays(request.rays);
        let clipped = clip_for_inference(model.sampler_grid(), request.grid, &bounded);
        let to_render: &[NormalizedRay] = clipped.rays.as_deref().unwrap_or(&bounded);
        let out = model.render_chunks(to_render, request)?;
        Ok(match clipped.kept {
            None => out,
            Some(kept) => scatter(out, &kept, request.rays.len(), request.background),
        })
    }
}

impl OpenNerf {
    /// Marches `rays` chunk by chunk, reporting to the request's observer.
    fn render_chunks(
        &self,
        rays: &[NormalizedRay],
        request: &RenderRequest<'_, Inference<'_>>,
    ) -> Result<RenderedRays, Cancelled> {
        let pass = &request.pass;
        let device = self.device();
        let mut out = RenderedRays::empty(self.feature_dim(request.features));
        let total = rays.len();
        for part in rays.chunks(pass.chunk.max(1)) {
            let batch = Rays::from_normalized(part, &device);
            let fine = self.march(
                &batch,
                request.background,
                request.features,
                pass.termination,
            );
            out.append(fine);
            if let Some(observe) = pass.observer
                && !observe(out.depth.len(), total)
            {
                return Err(Cancelled);
            }
        }
        Ok(out)
    }

    /// Channels of the feature `mode` renders (0 without one).
    pub(super) fn feature_dim(&self, mode: FeatureMode) -> usize {
        match mode {
            FeatureMode::None => 0,
            _ => self.head.output.weight.dims()[1],
        }
    }
}

/// The outputs of the rendered rays `out` (input rays `kept`) spread over
/// all `n` input rays: the others get the background (black without one)
/// and zero depths, opacity and feature.
fn scatter(
    out: RenderedRays,
    kept: &[usize],
    n: usize,
    background: Option<[f32; 3]>,
) -> RenderedRays {
    let dim = out.feature_dim;
    let bg = background.unwrap_or([0.0; 3]);
    let mut full = RenderedRays {
        rgb: bg.repeat(n),
        depth: vec![0.0; n],
        median_depth: vec![0.0; n],
        acc: vec![0.0; n],
        feature: vec![0.0; n * dim],
        feature_dim: dim,
        samples_evaluated: out.samples_evaluated,
    };
    for (j, &i) in kept.iter().enumerate() {
        full.rgb[3 * i..3 * i + 3].copy_from_slice(&out.rgb[3 * j..3 * j + 3]);
        full.depth[i] = out.depth[j];
        full.median_depth[i] = out.median_depth[j];
        full.acc[i] = out.acc[j];
        full.feature[i * dim..(i + 1) * dim].copy_from_slice(&out.feature[j * dim..(j + 1) * dim]);
    }
    full
}
