//! Random ray batches over a scene's frames, with their training targets.
//!
//! Batch `b` of a sampler depends only on `(seed, b)`, so training resumes
//! exactly after [`RaySampler::set_batches_drawn`].

use model::geometry::{Camera, NormalizedRay, SceneBox};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod depth;

pub use depth::{depth_pixels, sample_listed};

use crate::error::DatasetError;
use crate::scene::{Frame, Scene};

/// How training rays are drawn: the `sampler` section of a run's
/// `config.json`. The seed of the draws is given apart (a run derives it
/// from its own seed).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct SamplerConfig {
    /// Rays per batch.
    pub rays_per_batch: usize,
    /// Pixels within this distance of the image border are never drawn
    /// (feature maps and resized images are least reliable there). Given in
    /// pixels of an image whose shorter side is [`MARGIN_REFERENCE_SIDE`]
    /// (the paper's 640x360 Replica frames) and scaled with each image (see
    /// [`scaled_margin`]): 10 means 5 px at 320x180 and 2 px at 96x54.
    pub border_margin: u32,
    /// Lower bound on every ray's near distance (metres), keeping samples
    /// off the lens.
    pub min_near: f64,
    /// Feature-balanced sampling: pixels are drawn with weight `f^-power`,
    /// `f` the share of pixels whose feature target falls in the same
    /// cluster (0 = uniform; see [`crate::balance`]). Rare features (small
    /// objects) get more rays; scenes without feature maps sample
    /// uniformly, and so do [`RaySampler`] and [`sample_batch`].
    pub feature_balance: f64,
    /// Feature clusters the balance is computed over.
    pub balance_clusters: usize,
    /// Rays of each batch drawn uniformly from the pixels that have a depth
    /// target (see [`depth_pixels`]) rather than from all pixels: sparse
    /// depth (a few hundred pixels an image, e.g. COLMAP's points) is
    /// otherwise almost never drawn. 0: none.
    pub depth_rays: usize,
}

impl Default for SamplerConfig {
    fn default() -> Self {
        Self {
            rays_per_batch: 256,
            border_margin: 10,
            min_near: 0.05,
            // 1 = every feature cluster receives the same share of rays. On
            // three bench rooms it beat 0.5 on the tail (book 14.3 vs 0.4 IoU
            // on seed 22) and overall (hybrid mIoU 21.5 vs 20.4 there).
            feature_balance: 1.0,
            balance_clusters: 32,
            depth_rays: 0,
        }
    }
}

/// Rays and their targets.
#[derive(Debug, Clone, PartialEq)]
pub struct RayBatch {
    /// Rays in the field's normalised frame.
    pub rays: Vec<NormalizedRay>,
    /// Target colours.
    pub rgb: Vec<[f32; 3]>,
    /// Per-ray colour loss weight (the frame's `color_weight`), `None` when
    /// every frame of the scene weighs 1 (the plain mean squared error).
    pub rgb_weight: Option<Vec<f32>>,
    /// Target z-depths (0 = invalid), when any frame has depth.
    pub depth: Option<Vec<f32>>,
    /// Per-ray depth loss weight (the frame's `depth_weight`, 0 without depth).
    pub depth_weight: Option<Vec<f32>>,
    /// `n x feature_dim` feature targets, zeros where there is no target.
    pub features: Option<Vec<f32>>,
    /// Per ray, 1 where the feature target is valid and 0 where there is none
    /// (a frame without a map, a zero or masked map pixel); see
    /// [`crate::features::FeatureSet::target`].
    pub feature_mask: Option<Vec<f32>>,
    /// Channels per feature target (0 without features).
    pub feature_dim: usize,
    /// `[frame, x, y]` of every ray.
    pub pixels: Vec<[u32; 3]>,
}

impl RayBatch {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.rays.len()
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.rays.is_empty()
    }

    /// Appends `other`'s rays and targets. A target one side lacks is
    /// filled as the loss reads a missing one: depth 0 with weight 0,
    /// colour weight 1, no feature target (mask 0).
    ///
    /// # Errors
    /// When the two batches' feature channels differ.
    pub fn append(&mut self, other: RayBatch) -> Result<(), DatasetError> {
        let (n, m) = (self.len(), other.len());
        let both = self.features.is_some() && other.features.is_some();
        if both && self.feature_dim != other.feature_dim && n > 0 && m > 0 {
            return Err(DatasetError::invalid(
                "<ray batch>",
                format!(
                    "cannot join batches of {} and {} feature channels",
                    self.feature_dim, other.feature_dim
                ),
            ));
        }
        let features = self.features.is_some() || other.features.is_some();
        let dim = if self.features.is_some() && n > 0 {
            self.feature_dim
        } else {
            other.feature_dim
        };
        fn join<T: Clone>(a: &mut Option<Vec<T>>, b: Option<Vec<T>>, n: usize, m: usize, fill: T) {
            match (a.as_mut(), b) {
                (Some(a), Some(b)) => a.extend(b),
                (Some(a), None) => a.extend(std::iter::repeat_n(fill, m)),
                (None, Some(b)) => {
                    let mut v = vec![fill; n];
                    v.extend(b);
                    *a = Some(v);
                }
                (None, None) => {}
            }
        }
        join(&mut self.rgb_weight, other.rgb_weight, n, m, 1.0);
        join(&mut self.depth, other.depth, n, m, 0.0);
        join(&mut self.depth_weight, other.depth_weight, n, m, 0.0);
        join(&mut self.feature_mask, other.feature_mask, n, m, 0.0);
        join(&mut self.features, other.features, n * dim, m * dim, 0.0);
        self.feature_dim = if features { dim } else { 0 };
        self.rays.extend(other.rays);
        self.rgb.extend(other.rgb);
        self.pixels.extend(other.pixels);
        Ok(())
    }
}

/// Draws seeded random pixel batches, uniformly.
#[derive(Debug, Clone)]
pub struct RaySampler {
    config: SamplerConfig,
    seed: u64,
    frames: Option<Vec<usize>>,
    drawn: u64,
}

impl RaySampler {
    /// A sampler that has drawn no batch yet, its draws seeded with `seed`.
    pub fn new(config: SamplerConfig, seed: u64) -> Self {
        Self {
            config,
            seed,
            frames: None,
            drawn: 0,
        }
    }

    /// Draws only from the scene frames listed in `frames` (checked when a
    /// batch is drawn).
    pub fn with_frames(mut self, frames: Vec<usize>) -> Self {
        self.frames = Some(frames);
        self
    }

    /// The frames drawn from, `None` for all of them.
    pub fn frames(&self) -> Option<&[usize]> {
        self.frames.as_deref()
    }

    /// The settings.
    pub fn config(&self) -> &SamplerConfig {
        &self.config
    }

    /// Number of batches drawn so far (the index of the next batch).
    pub fn batches_drawn(&self) -> u64 {
        self.drawn
    }

    /// Continues as if `n` batches had been drawn.
    pub fn set_batches_drawn(&mut self, n: u64) {
        self.drawn = n;
    }

    /// The next batch: pixels uniform over frames, then uniform inside the
    /// frame's border margin, masked-out pixels never (see
    /// [`sample_batch_from`]).
    pub fn next_batch(&mut self, scene: &Scene) -> Result<RayBatch, DatasetError> {
        let batch = match &self.frames {
            Some(frames) => sample_batch_from(&self.config, self.seed, scene, frames, self.drawn)?,
            None => sample_batch(&self.config, self.seed, scene, self.drawn)?,
        };
        self.drawn += 1;
        Ok(batch)
    }
}

/// The shorter image side a border margin is given for: a margin of `m`
/// pixels means `m` pixels on a 640x360 image (the paper's Replica
/// resolution) and proportionally more or fewer on larger or smaller images,
/// so that the same fraction of every image is left out.
pub const MARGIN_REFERENCE_SIDE: u32 = 360;

/// The border margin in pixels of a `width x height` image for a margin of
/// `margin` pixels at [`MARGIN_REFERENCE_SIDE`] (rounded; at most a
/// quarter of the shorter side, so that half of each axis stays usable).
pub fn scaled_margin(margin: u32, width: u32, height: u32) -> u32 {
    let side = width.min(height);
    let m = (margin as f64 * side as f64 / MARGIN_REFERENCE_SIDE as f64).round() as u32;
    m.min(side / 4)
}

/// Pixel range `[lo, hi)` along an axis of `size` pixels with `margin`, kept
/// non-empty by shrinking the margin.
fn axis_range(size: u32, margin: u32) -> (u32, u32) {
    let m = margin.min(size.saturating_sub(1) / 2);
    (m, size - m)
}

/// The pixels of a `width x height` image that `config` draws from:
/// `([x0, x1), [y0, y1))`.
pub fn interior(config_margin: u32, width: u32, height: u32) -> ((u32, u32), (u32, u32)) {
    let m = scaled_margin(config_margin, width, height);
    (axis_range(width, m), axis_range(height, m))
}

/// Batch number `index` for `config` over all frames of `scene`, drawn
/// uniformly (a pure function of `seed` and `index`).
pub fn sample_batch(
    config: &SamplerConfig,
    seed: u64,
    scene: &Scene,
    index: u64,
) -> Result<RayBatch, DatasetError> {
    let all: Vec<usize> = (0..scene.frames.len()).collect();
    sample_batch_from(config, seed, scene, &all, index)
}

/// Batch number `index` for `config`, drawn uniformly and only from the
/// frames of `scene` listed in `frames` (for instance the training frames,
/// held-out ones left out). A pure function of `seed`, `index` and
/// `frames`; `pixels` keeps the scene's frame indices. Listing every frame
/// in order gives [`sample_batch`]'s batch.
///
/// Masked-out pixels ([`Frame::mask`]) are never drawn: a draw (frame and
/// pixel) landing on one is drawn again, so the batch of a scene without
/// masks is the same as before masks existed, and an unmasked pixel keeps
/// its weight. Fails when every interior pixel is masked out.
pub fn sample_batch_from(
    config: &SamplerConfig,
    seed: u64,
    scene: &Scene,
    frames: &[usize],
    index: u64,
) -> Result<RayBatch, DatasetError> {
    check_frames(scene, frames)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    let picks: Vec<(usize, u32, u32)> = (0..config.rays_per_batch)
        .map(|_| draw_pixel(&mut rng, config.border_margin, scene, frames))
        .collect::<Result<_, _>>()?;
    Ok(batch_at(config, scene, frames, &picks))
}

/// Draws before [`draw_pixel`] turns to drawing from the unmasked pixels
/// listed (only when nearly every pixel is masked out).
const MAX_REJECTIONS: usize = 1000;

/// One pixel: a frame of `frames` uniformly, then a pixel of its interior
/// uniformly, drawn again (frame and pixel) while the pixel is masked out.
/// Every unmasked interior pixel thus keeps its unmasked weight (a frame's
/// share of rays shrinks with its masked area), and without masks the
/// first draw is kept: the same stream as an unmasked sampler.
fn draw_pixel(
    rng: &mut ChaCha8Rng,
    margin: u32,
    scene: &Scene,
    frames: &[usize],
) -> Result<(usize, u32, u32), DatasetError> {
    for _ in 0..MAX_REJECTIONS {
        let fi = frames[rng.random_range(0..frames.len())];
        let frame = &scene.frames[fi];
        let ((x0, x1), (y0, y1)) = interior(margin, frame.rgb.width, frame.rgb.height);
        let (x, y) = (rng.random_range(x0..x1), rng.random_range(y0..y1));
        if frame.is_target_pixel(x, y) {
            return Ok((fi, x, y));
        }
    }
    draw_listed(rng, margin, scene, frames)
}

/// The unmasked interior pixels of `frame`, row-major.
fn unmasked_interior(frame: &Frame, margin: u32) -> Vec<(u32, u32)> {
    let ((x0, x1), (y0, y1)) = interior(margin, frame.rgb.width, frame.rgb.height);
    (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .filter(|&(x, y)| frame.is_target_pixel(x, y))
        .collect()
}

/// [`draw_pixel`]'s distribution drawn exactly from the listed unmasked
/// pixels: a frame with weight (unmasked / all interior pixels), then one
/// of its unmasked pixels. Fails when every pixel is masked out.
fn draw_listed(
    rng: &mut ChaCha8Rng,
    margin: u32,
    scene: &Scene,
    frames: &[usize],
) -> Result<(usize, u32, u32), DatasetError> {
    let mut cdf = Vec::with_capacity(frames.len());
    let mut total = 0.0;
    for &fi in frames {
        let frame = &scene.frames[fi];
        let ((x0, x1), (y0, y1)) = interior(margin, frame.rgb.width, frame.rgb.height);
        let all = ((x1 - x0) * (y1 - y0)) as f64;
        total += unmasked_interior(frame, margin).len() as f64 / all;
        cdf.push(total);
    }
    if total <= 0.0 {
        return Err(DatasetError::invalid(
            &scene.name,
            "every interior pixel of the frames sampled from is masked out",
        ));
    }
    let u = rng.random_range(0.0..total);
    let k = cdf.partition_point(|&c| c <= u).min(frames.len() - 1);
    let fi = frames[k];
    let pixels = unmasked_interior(&scene.frames[fi], margin);
    let (x, y) = pixels[rng.random_range(0..pixels.len())];
    Ok((fi, x, y))
}

/// Checks that `frames` can be sampled from: non-empty, in range, non-empty images.
pub(crate) fn check_frames(scene: &Scene, frames: &[usize]) -> Result<(), DatasetError> {
    let err = |m: &str| DatasetError::invalid(&scene.name, m.to_string());
    if frames.is_empty() {
        return Err(err("no frames to sample rays from"));
    }
    if let Some(&bad) = frames.iter().find(|&&f| f >= scene.frames.len()) {
        return Err(err(&format!(
            "frame index {bad} out of range: the scene has {} frames",
            scene.frames.len()
        )));
    }
    if let Some(f) = frames
        .iter()
        .map(|&f| &scene.frames[f])
        .find(|f| f.rgb.width == 0 || f.rgb.height == 0)
    {
        return Err(err(&format!("frame {} has an empty image", f.name)));
    }
    if let Some(f) = frames.iter().map(|&f| &scene.frames[f]).find(|f| {
        f.mask
            .as_ref()
            .is_some_and(|m| m.len() != f.rgb.width as usize * f.rgb.height as usize)
    }) {
        return Err(err(&format!(
            "frame {}'s mask does not match its {}x{} image",
            f.name, f.rgb.width, f.rgb.height
        )));
    }
    Ok(())
}

/// The rays and targets of the pixels `picks` (`(frame, x, y)`); `frames`
/// decides whether the batch carries depth (any of them has it).
pub(crate) fn batch_at(
    config: &SamplerConfig,
    scene: &Scene,
    frames: &[usize],
    picks: &[(usize, u32, u32)],
) -> RayBatch {
    let n = picks.len();
    let has_depth = frames.iter().any(|&f| scene.frames[f].depth.is_some());
    let weighs_rgb = frames.iter().any(|&f| scene.frames[f].color_weight != 1.0);
    let feature_dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let mut b = RayBatch {
        rays: Vec::with_capacity(n),
        rgb: Vec::with_capacity(n),
        rgb_weight: weighs_rgb.then(|| Vec::with_capacity(n)),
        depth: has_depth.then(|| Vec::with_capacity(n)),
        depth_weight: has_depth.then(|| Vec::with_capacity(n)),
        features: scene
            .features
            .as_ref()
            .map(|_| Vec::with_capacity(n * feature_dim)),
        feature_mask: scene.features.as_ref().map(|_| Vec::with_capacity(n)),
        feature_dim,
        pixels: Vec::with_capacity(n),
    };
    for &(fi, x, y) in picks {
        let frame = &scene.frames[fi];
        let (w, h) = (frame.rgb.width, frame.rgb.height);
        let ray = frame.camera.ray(x as f64, y as f64);
        b.rays
            .push(scene.scene_box.normalize_ray(&ray, config.min_near));
        b.rgb.push(frame.rgb.get(x, y));
        if let Some(w) = b.rgb_weight.as_mut() {
            w.push(frame.color_weight);
        }
        b.pixels.push([fi as u32, x, y]);
        if let (Some(d), Some(dw)) = (b.depth.as_mut(), b.depth_weight.as_mut()) {
            match &frame.depth {
                Some(img) => {
                    d.push(img.get(x, y));
                    dw.push(frame.depth_weight);
                }
                None => {
                    d.push(0.0);
                    dw.push(0.0);
                }
            }
        }
        if let (Some(out), Some(mask), Some(fs)) = (
            b.features.as_mut(),
            b.feature_mask.as_mut(),
            scene.features.as_ref(),
        ) {
            match fs.target(fi, x as f64, y as f64, w, h) {
                Some(t) => {
                    out.extend(t.iter().map(|v| v.to_f32()));
                    mask.push(1.0);
                }
                None => {
                    out.extend(std::iter::repeat_n(0.0, feature_dim));
                    mask.push(0.0);
                }
            }
        }
    }
    b
}

/// Rays through every pixel of `camera`'s image, row-major, for rendering.
pub fn frame_rays(scene_box: &SceneBox, camera: &Camera, min_near: f64) -> Vec<NormalizedRay> {
    let k = &camera.intrinsics;
    let mut rays = Vec::with_capacity(k.width as usize * k.height as usize);
    for y in 0..k.height {
        for x in 0..k.width {
            rays.push(scene_box.normalize_ray(&camera.ray(x as f64, y as f64), min_near));
        }
    }
    rays
}
