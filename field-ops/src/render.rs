//! Rendering a trained field at a camera: colour, depth, opacity and feature
//! images (written as pictures by [`crate::images`]), with the inference
//! pass of [`OpenNerf::render`].

use burn::tensor::Tensor;
use model::geometry::{Camera, NormalizedRay, SceneBox};
use model::{Cancelled, FeatureMode, GridUse, OpenNerf, RenderRequest, Termination};

/// Lower bound on the ray parameter (metres) of rendered rays; the same as
/// the training ray sampler's default, so views render as they were trained.
pub const RENDER_MIN_NEAR: f64 = 0.05;

/// One rendered view, row-major images of `height x width` pixels.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderedView {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height * width * 3` colours in `[0, 1]`.
    pub rgb: Vec<f32>,
    /// `height * width` z-depths in metres of the median depth along each
    /// ray (the expected depth where its weight never reaches a half).
    pub depth: Vec<f32>,
    /// `height * width` accumulated opacities in `[0, 1]`.
    pub acc: Vec<f32>,
    /// `height * width * feature_dim` composited features (empty without a head).
    pub feature: Vec<f32>,
    /// Channels per pixel of `feature` (0 without a feature head).
    pub feature_dim: usize,
    /// Samples the field was evaluated at, over both levels.
    pub samples_evaluated: usize,
}

impl RenderedView {
    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Feature vector of pixel `(x, y)` (empty without a feature head).
    pub fn feature_at(&self, x: u32, y: u32) -> &[f32] {
        let i = (y as usize * self.width as usize + x as usize) * self.feature_dim;
        &self.feature[i..i + self.feature_dim]
    }

    /// Rendered depth of pixel `(x, y)`.
    pub fn depth_at(&self, x: u32, y: u32) -> f32 {
        self.depth[y as usize * self.width as usize + x as usize]
    }
}

/// The normalised rays of every pixel of `camera`, row-major.
pub fn camera_rays(camera: &Camera, scene_box: &SceneBox) -> Vec<NormalizedRay> {
    let k = &camera.intrinsics;
    let mut rays = Vec::with_capacity(k.width as usize * k.height as usize);
    for j in 0..k.height {
        for i in 0..k.width {
            let ray = camera.ray(i as f64, j as f64);
            rays.push(scene_box.normalize_ray(&ray, RENDER_MIN_NEAR));
        }
    }
    rays
}

/// Values of a float tensor as `f32`, whatever the backend's float type
/// (an inference read, counted by [`model::host_work::read_backs`]).
pub fn tensor_to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    model::host_work::read_back(model::host_work::ReadReason::Inference, t)
}

/// How a view is rendered.
#[derive(Clone, Copy)]
pub struct ViewSettings<'a> {
    /// Colour behind the unoccluded part of a ray (black without one).
    pub background: Option<[f32; 3]>,
    /// Rays per forward pass (the peak memory is that of one chunk).
    pub chunk: usize,
    /// Whether and how the feature head is evaluated (runs trained without
    /// feature targets have no meaningful head, and skipping it saves its
    /// cost).
    pub features: FeatureMode,
    /// When a ray stops being evaluated.
    pub termination: Termination,
    /// How the model's occupancy grid is used: with [`GridUse::Model`],
    /// pixels whose ray crosses no occupied cell get the background (black
    /// without one) with zero opacity, depth and feature.
    pub grid: GridUse,
    /// Called with `(rays rendered, rays to render)` after every chunk;
    /// returning `false` cancels the render.
    pub observer: Option<&'a dyn Fn(usize, usize) -> bool>,
}

impl<'a> ViewSettings<'a> {
    /// Over `background`, `chunk` rays at a time: no feature image, the
    /// default termination (1e-4, see [`Termination`]), the model's grid,
    /// no observer.
    pub fn new(background: Option<[f32; 3]>, chunk: usize) -> Self {
        ViewSettings {
            background,
            chunk,
            features: FeatureMode::None,
            termination: Termination::default(),
            grid: GridUse::Model,
            observer: None,
        }
    }

    /// With the feature image composited when `features` is set, none
    /// otherwise.
    pub fn with_features(mut self, features: bool) -> Self {
        self.features = if features {
            FeatureMode::Composited
        } else {
            FeatureMode::None
        };
        self
    }

    /// With ray termination `termination` ([`Termination::off`] evaluates
    /// every sample).
    pub fn with_termination(mut self, termination: Termination) -> Self {
        self.termination = termination;
        self
    }

    /// With the model's grid used as `grid` says.
    pub fn with_grid(mut self, grid: GridUse) -> Self {
        self.grid = grid;
        self
    }

    /// With progress and cancellation through `observer`.
    pub fn with_observer(mut self, observer: &'a dyn Fn(usize, usize) -> bool) -> Self {
        self.observer = Some(observer);
        self
    }
}

impl std::fmt::Debug for ViewSettings<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewSettings")
            .field("background", &self.background)
            .field("chunk", &self.chunk)
            .field("features", &self.features)
            .field("termination", &self.termination)
            .field("grid", &self.grid)
            .field("observer", &self.observer.is_some())
            .finish()
    }
}

/// Renders every pixel of `camera` with the fine level of `model` as
/// `settings` say. `Err` only when the settings' observer cancels the
/// render (never without an observer).
pub fn render_view(
    model: &OpenNerf,
    camera: &Camera,
    scene_box: &SceneBox,
    settings: &ViewSettings<'_>,
) -> Result<RenderedView, Cancelled> {
    let rays = camera_rays(camera, scene_box);
    let request = RenderRequest::inference(&rays)
        .with_chunk(settings.chunk)
        .with_termination(settings.termination)
        .with_observer(settings.observer)
        .with_features(settings.features)
        .with_background(settings.background)
        .with_grid(settings.grid);
    let r = model.render(&request)?;
    Ok(RenderedView {
        width: camera.intrinsics.width,
        height: camera.intrinsics.height,
        rgb: r.rgb,
        depth: r.median_depth,
        acc: r.acc,
        feature: r.feature,
        feature_dim: r.feature_dim,
        samples_evaluated: r.samples_evaluated,
    })
}
