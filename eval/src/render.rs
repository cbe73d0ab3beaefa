//! Rendering a trained field at a camera: colour, depth, opacity and feature
//! images, and writing them as PNGs.

use std::path::{Path, PathBuf};

use burn::tensor::{Device, Tensor};
use model::geometry::{Camera, NormalizedRay, SceneBox};
use model::{FeatureMode, OpenNerf, Rays};

use crate::colormap::{to_u8, turbo};
use crate::error::EvalError;

/// Lower bound on the ray parameter (metres) of rendered rays; the same as
/// the training ray sampler's default, so views render as they were trained.
pub const RENDER_MIN_NEAR: f64 = 0.05;

/// One rendered view, row-major images of `height x width` pixels.
#[derive(Debug, Clone, PartialEq)]
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
    let mode = if features {
        FeatureMode::Composited
    } else {
        FeatureMode::None
    };
    let rays = camera_rays(camera, scene_box);
    let r = render_rays(model, &rays, background, chunk, mode, device);
    RenderedView {
        width: camera.intrinsics.width,
        height: camera.intrinsics.height,
        rgb: r.rgb,
        depth: r.depth,
        acc: r.acc,
        feature: r.feature,
        feature_dim: r.feature_dim,
    }
}

/// Fine-level outputs of a list of rays, on the host.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderedRays {
    /// `3 n` colours.
    pub rgb: Vec<f32>,
    /// `n` expected depths along the ray (metres of `t`).
    pub depth: Vec<f32>,
    /// `n` accumulated opacities.
    pub acc: Vec<f32>,
    /// `n * feature_dim` features (empty when not rendered).
    pub feature: Vec<f32>,
    /// Channels per ray of `feature`.
    pub feature_dim: usize,
}

/// Renders `rays` with the fine level of `model`, `chunk` rays at a time.
/// With an occupancy grid on the model, each ray is first clipped to its
/// occupied cells and rays that cross none are not evaluated: they get the
/// background (black without one), zero opacity, depth and feature — what
/// the field renders for a ray that meets no density.
pub fn render_rays(
    model: &OpenNerf,
    rays: &[NormalizedRay],
    background: Option<[f32; 3]>,
    chunk: usize,
    mode: FeatureMode,
    device: &Device,
) -> RenderedRays {
    let clipped = model.occupancy().map(|g| g.clip(rays));
    let to_render: &[NormalizedRay] = clipped.as_ref().map_or(rays, |c| &c.rays);
    let chunk = chunk.max(1);
    let mut out = RenderedRays::default();
    for part in to_render.chunks(chunk) {
        let batch = Rays::from_normalized(part, device);
        let fine = model.render_inference(&batch, chunk, background, mode).fine;
        out.rgb.extend(tensor_to_vec(fine.rgb));
        out.depth.extend(tensor_to_vec(fine.depth));
        out.acc.extend(tensor_to_vec(fine.acc));
        if let Some(f) = fine.feature {
            out.feature_dim = f.dims()[1];
            out.feature.extend(tensor_to_vec(f));
        }
    }
    let Some(clipped) = clipped else {
        return out;
    };
    if clipped.kept.len() == rays.len() {
        return out;
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
    full
}

/// Writes `{name}_rgb.png`, `{name}_depth.png` (Turbo over the depth range of
/// the covered pixels; uncovered pixels black) and, with a feature head,
/// `{name}_feature.png` (the feature image's top three principal components)
/// into `dir`, creating it. Returns the written paths.
pub fn save_view_pngs(
    view: &RenderedView,
    dir: &Path,
    name: &str,
) -> Result<Vec<PathBuf>, EvalError> {
    std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir, e))?;
    let (w, h) = (view.width, view.height);
    let mut written = Vec::new();

    let path = dir.join(format!("{name}_rgb.png"));
    let rgb: Vec<u8> = view.rgb.iter().map(|&v| to_u8(v)).collect();
    save_rgb8(&path, w, h, rgb)?;
    written.push(path);

    let path = dir.join(format!("{name}_depth.png"));
    save_rgb8(&path, w, h, depth_colors(&view.depth, &view.acc))?;
    written.push(path);

    if view.feature_dim > 0 {
        let path = dir.join(format!("{name}_feature.png"));
        let colors = pca_colors(&view.feature, view.feature_dim);
        save_rgb8(&path, w, h, colors.into_iter().flatten().collect())?;
        written.push(path);
    }
    Ok(written)
}

/// Writes an 8-bit RGB PNG from `height * width * 3` bytes.
pub fn save_rgb8(path: &Path, width: u32, height: u32, data: Vec<u8>) -> Result<(), EvalError> {
    let img = image::RgbImage::from_raw(width, height, data).ok_or_else(|| EvalError::Image {
        path: path.to_path_buf(),
        message: format!("buffer does not hold {width}x{height} RGB pixels"),
    })?;
    img.save(path).map_err(|e| EvalError::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Depth colour-mapped with Turbo over `[min, max]` of pixels with opacity
/// above one half; the rest black. Returns `3 * n` bytes.
pub fn depth_colors(depth: &[f32], acc: &[f32]) -> Vec<u8> {
    let covered = |i: usize| acc.get(i).is_none_or(|&a| a > 0.5) && depth[i].is_finite();
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for (i, &d) in depth.iter().enumerate() {
        if covered(i) {
            lo = lo.min(d);
            hi = hi.max(d);
        }
    }
    let span = (hi - lo).max(1e-6);
    let mut out = Vec::with_capacity(3 * depth.len());
    for (i, &d) in depth.iter().enumerate() {
        let c = if covered(i) {
            turbo((d - lo) / span)
        } else {
            [0.0; 3]
        };
        out.extend(c.map(to_u8));
    }
    out
}

/// Colours of an `n x dim` feature image from its top three principal
/// components, each scaled to `[0, 1]` between its 1st and 99th percentile.
pub fn pca_colors(feature: &[f32], dim: usize) -> Vec<[u8; 3]> {
    if dim == 0 {
        return Vec::new();
    }
    let n = feature.len() / dim;
    // A strided sample of at most 4096 pixels fixes the basis; the cost of the
    // covariance is then independent of the image size.
    let stride = n.div_ceil(4096).max(1);
    let sample: Vec<&[f32]> = (0..n)
        .step_by(stride)
        .map(|i| &feature[i * dim..(i + 1) * dim])
        .collect();
    let mean = mean_vector(&sample, dim);
    let axes = top_components(&sample, &mean, dim, 3);
    let project = |f: &[f32], a: &[f64]| -> f64 {
        f.iter()
            .zip(&mean)
            .zip(a)
            .map(|((&x, &m), &v)| (x as f64 - m) * v)
            .sum()
    };
    let ranges: Vec<(f64, f64)> = axes
        .iter()
        .map(|a| {
            let mut v: Vec<f64> = sample.iter().map(|f| project(f, a)).collect();
            v.sort_by(f64::total_cmp);
            let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
            (q(0.01), q(0.99))
        })
        .collect();
    (0..n)
        .map(|i| {
            let f = &feature[i * dim..(i + 1) * dim];
            let mut c = [0u8; 3];
            for (ch, (a, &(lo, hi))) in axes.iter().zip(&ranges).enumerate() {
                let x = (project(f, a) - lo) / (hi - lo).max(1e-12);
                c[ch] = to_u8(x as f32);
            }
            c
        })
        .collect()
}

fn mean_vector(sample: &[&[f32]], dim: usize) -> Vec<f64> {
    let mut mean = vec![0.0f64; dim];
    for f in sample {
        for (m, &x) in mean.iter_mut().zip(f.iter()) {
            *m += x as f64;
        }
    }
    let n = sample.len().max(1) as f64;
    mean.iter_mut().for_each(|m| *m /= n);
    mean
}

/// The `count` leading eigenvectors of the sample covariance, by power
/// iteration with deflation (fewer when `dim < count`: missing axes are zero).
///
/// # Shapes
/// `sample`: `n` slices of `dim`; returns `count` vectors of `dim`.
pub fn top_components(sample: &[&[f32]], mean: &[f64], dim: usize, count: usize) -> Vec<Vec<f64>> {
    let mut cov = vec![0.0f64; dim * dim];
    for f in sample {
        let c: Vec<f64> = f.iter().zip(mean).map(|(&x, &m)| x as f64 - m).collect();
        for a in 0..dim {
            let ca = c[a];
            if ca == 0.0 {
                continue;
            }
            let row = &mut cov[a * dim..(a + 1) * dim];
            for (r, &cb) in row.iter_mut().zip(&c) {
                *r += ca * cb;
            }
        }
    }
    let mut axes = Vec::with_capacity(count);
    for axis in 0..count {
        if axis >= dim {
            axes.push(vec![0.0; dim]);
            continue;
        }
        // Deterministic start that is unlikely to be orthogonal to the answer.
        let mut v: Vec<f64> = (0..dim)
            .map(|i| 1.0 + ((i * 7 + axis * 3) % 5) as f64)
            .collect();
        let mut lambda = 0.0;
        for _ in 0..200 {
            let mut w = vec![0.0; dim];
            for (a, wa) in w.iter_mut().enumerate() {
                *wa = cov[a * dim..(a + 1) * dim]
                    .iter()
                    .zip(&v)
                    .map(|(c, x)| c * x)
                    .sum();
            }
            lambda = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            if lambda < 1e-30 {
                break;
            }
            v = w.into_iter().map(|x| x / lambda).collect();
        }
        if lambda < 1e-30 {
            axes.push(vec![0.0; dim]);
            continue;
        }
        for a in 0..dim {
            for b in 0..dim {
                cov[a * dim + b] -= lambda * v[a] * v[b];
            }
        }
        axes.push(v);
    }
    axes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_components_recovers_planted_axes() {
        // Points spread 10x along (1,1,0)/sqrt2, 3x along z, 0.1x along (1,-1,0).
        let mut data = Vec::new();
        for i in 0..200 {
            let t = ((i * 37) % 101) as f32 / 50.0 - 1.0;
            let s = ((i * 53) % 97) as f32 / 48.0 - 1.0;
            let r = ((i * 29) % 89) as f32 / 44.0 - 1.0;
            let a = 10.0 * t / 2f32.sqrt();
            let b = 0.1 * r / 2f32.sqrt();
            data.push(vec![a + b, a - b, 3.0 * s]);
        }
        let sample: Vec<&[f32]> = data.iter().map(|v| v.as_slice()).collect();
        let mean = mean_vector(&sample, 3);
        let axes = top_components(&sample, &mean, 3, 3);
        let h = 1.0 / 2f64.sqrt();
        let expect = [[h, h, 0.0], [0.0, 0.0, 1.0], [h, -h, 0.0]];
        for (a, e) in axes.iter().zip(expect) {
            let d: f64 = a.iter().zip(e).map(|(x, y)| x * y).sum();
            assert!(d.abs() > 0.999, "axis {a:?} vs {e:?}");
        }
    }

    #[test]
    fn depth_colors_span_the_map_and_blank_empty_pixels() {
        let depth = [1.0, 2.0, 3.0, 5.0];
        let acc = [1.0, 1.0, 1.0, 0.0];
        let c = depth_colors(&depth, &acc);
        assert_eq!(&c[0..3], &turbo(0.0).map(to_u8));
        assert_eq!(&c[3..6], &turbo(0.5).map(to_u8));
        assert_eq!(&c[6..9], &turbo(1.0).map(to_u8));
        assert_eq!(&c[9..12], &[0, 0, 0]);
    }

    #[test]
    fn pca_colors_separate_two_clusters() {
        let mut f = Vec::new();
        for i in 0..100 {
            let v = if i < 50 { 1.0 } else { -1.0 };
            f.extend([v, 0.5 * v, 0.0, 0.01 * (i % 3) as f32]);
        }
        let c = pca_colors(&f, 4);
        assert_eq!(c.len(), 100);
        // The first channel is the cluster axis: the two halves land at the two ends.
        let (a, b) = (c[0][0] as i32, c[99][0] as i32);
        assert!((a - b).abs() > 200, "{a} vs {b}");
    }
}
