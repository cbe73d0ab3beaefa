//! Rendering a trained field at a camera: colour, depth, opacity and feature
//! images (written as pictures by [`crate::images`]).

use burn::tensor::{Device, Tensor};
use model::geometry::{Camera, NormalizedRay, SceneBox};
use model::{FeatureMode, OpenNerf, Rays, Termination};

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
    /// `height * width` expected z-depths in metres.
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

/// Values of a float tensor as `f32`, whatever the backend's float type.
pub fn tensor_to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .try_into_vec_as::<f32>()
        .expect("a float tensor converts to f32")
}

/// Renders every pixel of `camera` with the fine level of `model`, `chunk`
/// rays at a time (the peak memory is that of one chunk). The feature image
/// is rendered only when `features` is set (runs trained without feature
/// targets have no meaningful head, and skipping it saves its cost).
pub fn render_view(
    model: &OpenNerf,
    camera: &Camera,
    scene_box: &SceneBox,
    background: Option<[f32; 3]>,
    chunk: usize,
    features: bool,
    device: &Device,
) -> RenderedView {
    let settings = RenderSettings::view(background, chunk, features);
    render_view_with(model, camera, scene_box, settings, device)
}

/// Fine-level outputs of a list of rays, on the host: colours, depths,
/// opacities, features and the samples evaluated.
pub type RenderedRays = model::MarchedRays;

/// Renders `rays` with the fine level of `model`, `chunk` rays at a time,
/// each ray ending once its transmittance falls below 1e-4 (see
/// [`Termination`]). With an occupancy grid on the model, each ray is first
/// clipped to its occupied cells and rays that cross none are not
/// evaluated: they get the background (black without one), zero opacity,
/// depth and feature — what the field renders for a ray that meets no
/// density.
pub fn render_rays(
    model: &OpenNerf,
    rays: &[NormalizedRay],
    background: Option<[f32; 3]>,
    chunk: usize,
    mode: FeatureMode,
    device: &Device,
) -> RenderedRays {
    render_rays_with(
        model,
        rays,
        background,
        chunk,
        mode,
        Termination::default(),
        device,
    )
}

/// [`render_rays`] with an explicit ray termination
/// ([`Termination::off`] evaluates every sample).
pub fn render_rays_with(
    model: &OpenNerf,
    rays: &[NormalizedRay],
    background: Option<[f32; 3]>,
    chunk: usize,
    mode: FeatureMode,
    termination: Termination,
    device: &Device,
) -> RenderedRays {
    let settings = RenderSettings {
        background,
        chunk,
        mode,
        termination,
    };
    render_rays_observed(model, rays, settings, device, &mut |_, _| true).unwrap_or_default()
}

/// How rays are rendered.
#[derive(Debug, Clone, Copy)]
pub struct RenderSettings {
    /// Colour behind the unoccluded part of a ray (black without one).
    pub background: Option<[f32; 3]>,
    /// Rays per forward pass (the peak memory is that of one chunk).
    pub chunk: usize,
    /// Whether and how the feature head is evaluated.
    pub mode: FeatureMode,
    /// When a ray stops being evaluated.
    pub termination: Termination,
}

impl RenderSettings {
    /// The settings [`render_view`] uses: features composited when asked
    /// for, the default termination.
    pub fn view(background: Option<[f32; 3]>, chunk: usize, features: bool) -> Self {
        RenderSettings {
            background,
            chunk,
            mode: if features {
                FeatureMode::Composited
            } else {
                FeatureMode::None
            },
            termination: Termination::default(),
        }
    }
}

/// [`render_view`] with explicit settings.
pub fn render_view_with(
    model: &OpenNerf,
    camera: &Camera,
    scene_box: &SceneBox,
    settings: RenderSettings,
    device: &Device,
) -> RenderedView {
    view_observed(model, camera, scene_box, settings, device, &mut |_, _| true).unwrap_or_default()
}

/// [`render_view`] that reports its progress after every chunk to `go`
/// (`(rays done, rays to render)`) and stops, returning `None`, as soon as
/// `go` returns `false` (a cancelled request).
#[allow(clippy::too_many_arguments)]
pub fn render_view_observed(
    model: &OpenNerf,
    camera: &Camera,
    scene_box: &SceneBox,
    background: Option<[f32; 3]>,
    chunk: usize,
    features: bool,
    device: &Device,
    go: &mut dyn FnMut(usize, usize) -> bool,
) -> Option<RenderedView> {
    let settings = RenderSettings::view(background, chunk, features);
    view_observed(model, camera, scene_box, settings, device, go)
}

/// Every pixel of `camera`, with progress and cancellation.
fn view_observed(
    model: &OpenNerf,
    camera: &Camera,
    scene_box: &SceneBox,
    settings: RenderSettings,
    device: &Device,
    go: &mut dyn FnMut(usize, usize) -> bool,
) -> Option<RenderedView> {
    let rays = camera_rays(camera, scene_box);
    let r = render_rays_observed(model, &rays, settings, device, go)?;
    Some(RenderedView {
        width: camera.intrinsics.width,
        height: camera.intrinsics.height,
        rgb: r.rgb,
        depth: r.depth,
        acc: r.acc,
        feature: r.feature,
        feature_dim: r.feature_dim,
        samples_evaluated: r.samples_evaluated,
    })
}

/// [`render_rays`] with progress and cancellation (see
/// [`render_view_observed`]).
fn render_rays_observed(
    model: &OpenNerf,
    rays: &[NormalizedRay],
    settings: RenderSettings,
    device: &Device,
    go: &mut dyn FnMut(usize, usize) -> bool,
) -> Option<RenderedRays> {
    let RenderSettings {
        background,
        chunk,
        mode,
        termination,
    } = settings;
    let clipped = model.occupancy().map(|g| g.clip(rays));
    let to_render: &[NormalizedRay] = clipped.as_ref().map_or(rays, |c| &c.rays);
    let chunk = chunk.max(1);
    let mut out = RenderedRays::default();
    let total = to_render.len();
    for (i, part) in to_render.chunks(chunk).enumerate() {
        if !go((i * chunk).min(total), total) {
            return None;
        }
        let batch = Rays::from_normalized(part, device);
        let fine = model.render_marched(&batch, background, mode, termination);
        out.rgb.extend(fine.rgb);
        out.depth.extend(fine.depth);
        out.acc.extend(fine.acc);
        out.feature_dim = fine.feature_dim;
        out.feature.extend(fine.feature);
        out.samples_evaluated += fine.samples_evaluated;
    }
    if !go(total, total) {
        return None;
    }
    let Some(clipped) = clipped else {
        return Some(out);
    };
    if clipped.kept.len() == rays.len() {
        return Some(out);
    }
    let dim = match mode {
        FeatureMode::None => 0,
        _ => model.head.output.weight.dims()[1],
    };
    let n = rays.len();
    let bg = background.unwrap_or([0.0; 3]);
    let mut full = RenderedRays {
        rgb: bg.repeat(n),
        depth: vec![0.0; n],
        acc: vec![0.0; n],
        feature: vec![0.0; n * dim],
        feature_dim: dim,
        samples_evaluated: out.samples_evaluated,
    };
    for (j, &i) in clipped.kept.iter().enumerate() {
        full.rgb[3 * i..3 * i + 3].copy_from_slice(&out.rgb[3 * j..3 * j + 3]);
        full.depth[i] = out.depth[j];
        full.acc[i] = out.acc[j];
        if dim > 0 {
            full.feature[i * dim..(i + 1) * dim]
                .copy_from_slice(&out.feature[j * dim..(j + 1) * dim]);
        }
    }
    Some(full)
}
