//! Rendering rays with the field: one entry point, [`OpenNerf::render`],
//! for training and for inference.
//!
//! A [`RenderRequest`] holds host rays in the normalised frame, the pass
//! that renders them, the feature path, the background and how the model's
//! occupancy grid is used:
//!
//! - [`Train`]: the coarse and the fine level as tensors (autodiff ones on
//!   an autodiff model), or with the proposal sampler its rounds'
//!   histograms and the one NeRF level, every sample of a level evaluated
//!   at once, for the losses. With [`Train::randomized`] off it is the
//!   deterministic dense render that checks compare against.
//! - [`Inference`]: the fine level on the host for every input ray, in
//!   chunks, each ray marched front to back and ended once its
//!   transmittance is below [`Termination::transmittance`]; progress and
//!   cancellation through an observer.
//!
//! Both passes run one loop over the model's levels ([`OpenNerf::levels`]:
//! the coarse and the fine level of the shared MLP, or the proposal rounds
//! and the NeRF level), each level placing its posts from the previous
//! level's weights, the last one the NeRF MLP's.
//!
//! Where the samples go is the model's (see [`ProposalLevel`] and
//! [`Extent::spacing`](crate::extent::Extent::spacing)): stratified and
//! resampled posts in the box, in normalised disparity in an unbounded
//! field, whose rays run over its own bounds
//! ([`Extent::bound_rays`](crate::extent::Extent::bound_rays)); or the
//! proposal rounds.
//!
//! The grid is a sampler (see [`GridUse`]): before the stratified coarse
//! samples are placed, each ray's `near`/`far` is narrowed to the span from
//! its first to its last occupied cell, and rays that cross no occupied cell
//! are dropped (the training pass renders a batch in which every ray would
//! be dropped whole instead). Inference gives a dropped ray the background
//! (black without one) with zero depth, opacity and feature: what the field
//! renders for a ray that meets no density.
//!
//! Both passes composite with the same compositor: the weights of a run of
//! samples from the optical depth before it
//! ([`segment_weights`](crate::composite::segment_weights); the dense level
//! is one segment from zero optical depth), their weighted sums
//! ([`composite_values`](crate::composite::composite_values)) and the
//! closing steps ([`over_background`](crate::composite::over_background),
//! [`expected_depth`](crate::composite::expected_depth)). Without
//! termination the marched fine level is the dense one, bit for bit on the
//! CPU backends (checked by the model's tests).

mod dense;
mod grid;
mod inference;
mod levels;
mod march;
mod posts;
mod rendered;

use crate::geometry::NormalizedRay;
use crate::nerf::OpenNerf;
use crate::occupancy::{OccupancyConfig, OccupancyGrid};

pub use dense::{LevelOutputs, PerPhotograph, RenderOutputs, Train};
pub use grid::ClipStats;
pub use inference::{Cancelled, Inference};
pub use levels::{Level, LevelField};
pub use march::Termination;
pub use posts::ProposalLevel;
pub use rendered::RenderedRays;

/// How the open-set feature is computed at a level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeatureMode {
    /// Not at all.
    None,
    /// Head applied per sample, then composited (reference path).
    PerSample,
    /// Hidden activations composited, output layer once per ray (default).
    Composited,
}

/// How a request uses the occupancy grid the model carries
/// ([`OpenNerf::occupancy`]); without one, every choice renders the rays as
/// they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GridUse {
    /// Each ray clipped to its occupied span; rays that cross no occupied
    /// cell are dropped.
    #[default]
    Model,
    /// Each ray clipped to its occupied span, but rays that cross no
    /// occupied cell are rendered over their whole span (training while the
    /// grid may still be wrong, see
    /// [`OccupancyConfig::keep_dropped_updates`]).
    KeepEmpty,
    /// The grid is ignored: every ray over its whole span.
    Off,
}

impl GridUse {
    /// How training uses `grid` under `config`: [`GridUse::KeepEmpty`]
    /// during its first `keep_dropped_updates` updates (a region freed by
    /// mistake still gets a loss that brings it back), [`GridUse::Model`]
    /// after (and without a grid).
    pub fn for_training(config: &OccupancyConfig, grid: Option<&OccupancyGrid>) -> GridUse {
        match grid {
            Some(g) if config.keeps_empty_rays(g) => GridUse::KeepEmpty,
            _ => GridUse::Model,
        }
    }
}

/// What to render: rays, a pass and its settings. Built with
/// [`RenderRequest::train`] or [`RenderRequest::inference`] and the
/// `with_*` methods.
///
/// # Shapes
/// - `rays`: `n` host rays in the normalised frame (`t` in metres of the
///   unnormalised direction, see [`NormalizedRay`]).
/// - outputs: per ray, in input order (see the pass).
#[derive(Debug, Clone, Copy)]
pub struct RenderRequest<'a, P> {
    /// The rays, in the normalised frame.
    pub rays: &'a [NormalizedRay],
    /// The pass and its own settings.
    pub pass: P,
    /// How the feature is computed at the fine level (and at the coarse
    /// one when the model composites coarse features).
    pub features: FeatureMode,
    /// Colour behind the unoccluded part of each ray, RGB in `[0, 1]`
    /// (black without one).
    pub background: Option<[f32; 3]>,
    /// How the model's occupancy grid is used.
    pub grid: GridUse,
}

impl<'a> RenderRequest<'a, Train> {
    /// Training: stratified jitter on, composited features, no background,
    /// the model's grid ([`GridUse::Model`]).
    pub fn train(rays: &'a [NormalizedRay]) -> Self {
        Self::new(
            rays,
            Train {
                randomized: true,
                progress: 1.0,
            },
        )
    }

    /// Whether the sample positions are jittered (off: the deterministic
    /// dense render).
    pub fn with_randomized(mut self, randomized: bool) -> Self {
        self.pass.randomized = randomized;
        self
    }

    /// The fraction of training done, in `[0, 1]`, for the proposal
    /// sampler's annealing (1, the default: none).
    pub fn with_progress(mut self, progress: f32) -> Self {
        self.pass.progress = progress;
        self
    }
}

impl<'a> RenderRequest<'a, Inference<'a>> {
    /// Inference: the default [`Inference`] pass (chunks of 4096 rays,
    /// the default termination, no observer), composited features, no
    /// background, the model's grid ([`GridUse::Model`]).
    pub fn inference(rays: &'a [NormalizedRay]) -> Self {
        Self::new(rays, Inference::default())
    }

    /// Rays per forward pass (the peak memory is that of one chunk; 0 is
    /// taken as 1).
    pub fn with_chunk(mut self, chunk: usize) -> Self {
        self.pass.chunk = chunk;
        self
    }

    /// When a ray stops being evaluated ([`Termination::off`]: never).
    pub fn with_termination(mut self, termination: Termination) -> Self {
        self.pass.termination = termination;
        self
    }

    /// Called with `(rays rendered, rays to render)` after every chunk;
    /// returning `false` cancels the render.
    pub fn with_observer(mut self, observer: Option<&'a dyn Fn(usize, usize) -> bool>) -> Self {
        self.pass.observer = observer;
        self
    }
}

impl<'a, P: RenderPass> RenderRequest<'a, P> {
    /// `rays` rendered by `pass` with composited features, no background
    /// and the model's grid.
    pub fn new(rays: &'a [NormalizedRay], pass: P) -> Self {
        RenderRequest {
            rays,
            pass,
            features: FeatureMode::Composited,
            background: None,
            grid: GridUse::Model,
        }
    }

    /// The feature path ([`FeatureMode::None`] skips the head).
    pub fn with_features(mut self, features: FeatureMode) -> Self {
        self.features = features;
        self
    }

    /// The background colour (`None`: black).
    pub fn with_background(mut self, background: Option<[f32; 3]>) -> Self {
        self.background = background;
        self
    }

    /// How the model's occupancy grid is used.
    pub fn with_grid(mut self, grid: GridUse) -> Self {
        self.grid = grid;
        self
    }
}

/// A way of rendering: [`Train`] or [`Inference`] (the trait is sealed).
pub trait RenderPass: sealed::Sealed + Sized {
    /// What the pass returns.
    type Output;

    /// Renders `request` with `model`; reached through
    /// [`OpenNerf::render`] only.
    #[doc(hidden)]
    fn run(
        model: &OpenNerf,
        request: &RenderRequest<'_, Self>,
        token: sealed::Token,
    ) -> Self::Output;
}

mod sealed {
    /// Only this crate's passes implement [`super::RenderPass`].
    pub trait Sealed {}

    /// Proof that a pass is run by [`crate::OpenNerf::render`].
    pub struct Token(pub(super) ());
}

impl OpenNerf {
    /// Renders `request` (see [`crate::render`]): with [`Train`] both levels
    /// as tensors for the losses, with [`Inference`] the fine level of every
    /// ray on the host. The rays are uploaded to the model's device
    /// ([`OpenNerf::device`]).
    pub fn render<P: RenderPass>(&self, request: &RenderRequest<'_, P>) -> P::Output {
        P::run(self, request, sealed::Token(()))
    }
}
