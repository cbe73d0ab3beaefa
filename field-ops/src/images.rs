//! Pictures of rendered views: the colour, depth (see [`crate::depth_image`]),
//! opacity and feature (top three principal components) images.

use std::path::{Path, PathBuf};

use datasets::features::symmetric_eigen;
use datasets::imageio::save_rgb8;

use crate::colormap::to_u8;
use crate::depth_image::{DepthQuantity, DepthScale, opacity_grey};
use crate::error::OpsError;
use crate::render::RenderedView;

/// The pictures of one rendered view, as RGB8 bytes of its size.
#[derive(Debug, Clone)]
pub struct ViewImages {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The colour render.
    pub rgb: Vec<u8>,
    /// Depth coloured over [`ViewImages::depth_scale`].
    pub depth: Vec<u8>,
    /// The depth image's scale (range, units, colours).
    pub depth_scale: DepthScale,
    /// Accumulated opacity as grey.
    pub opacity: Vec<u8>,
    /// The feature image's top three principal components (with a head).
    pub feature: Option<Vec<u8>>,
}

impl ViewImages {
    /// The pictures of `view`, its depth shown as `quantity` (see
    /// [`DepthQuantity::of`]).
    pub fn of(view: &RenderedView, quantity: DepthQuantity) -> Self {
        let depth_scale = DepthScale::of(&view.depth, &view.acc, quantity);
        ViewImages {
            width: view.width,
            height: view.height,
            rgb: view.rgb.iter().map(|&v| to_u8(v)).collect(),
            depth: depth_scale.colours(&view.depth, &view.acc),
            depth_scale,
            opacity: opacity_grey(&view.acc),
            feature: (view.feature_dim > 0).then(|| {
                pca_colors(&view.feature, view.feature_dim)
                    .into_iter()
                    .flatten()
                    .collect()
            }),
        }
    }

    /// Writes `{name}_rgb.png`, `{name}_depth.png` with its scale in
    /// `{name}_depth.json`, `{name}_opacity.png` and, with a feature head,
    /// `{name}_feature.png` into `dir`, creating it. Returns the written paths.
    pub fn save(&self, dir: &Path, name: &str) -> Result<Vec<PathBuf>, OpsError> {
        std::fs::create_dir_all(dir).map_err(|e| OpsError::io(dir, e))?;
        let (w, h) = (self.width, self.height);
        let mut written = Vec::new();
        let pictures = [
            ("rgb", Some(&self.rgb)),
            ("depth", Some(&self.depth)),
            ("opacity", Some(&self.opacity)),
            ("feature", self.feature.as_ref()),
        ];
        for (kind, bytes) in pictures {
            if let Some(bytes) = bytes {
                let path = dir.join(format!("{name}_{kind}.png"));
                save_rgb8(&path, w, h, bytes)?;
                written.push(path);
            }
        }
        let path = dir.join(format!("{name}_depth.json"));
        crate::json::write_json(&path, &self.depth_scale)?;
        written.push(path);
        Ok(written)
    }
}

/// Writes the pictures of `view` (see [`ViewImages::save`]) into `dir`,
/// its depth shown as `quantity`. Returns the written paths.
pub fn save_view_pngs(
    view: &RenderedView,
    dir: &Path,
    name: &str,
    quantity: DepthQuantity,
) -> Result<Vec<PathBuf>, OpsError> {
    ViewImages::of(view, quantity).save(dir, name)
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

/// The `count` leading eigenvectors of the sample covariance, by order of
/// eigenvalue, each with its largest-magnitude entry positive (fewer when
/// `dim < count`: missing axes are zero).
///
/// # Shapes
/// `sample`: `n` slices of `dim`; returns `count` vectors of `dim`.
pub fn top_components(sample: &[&[f32]], mean: &[f64], dim: usize, count: usize) -> Vec<Vec<f64>> {
    let mut cov = vec![0.0f64; dim * dim];
    for f in sample {
        let c: Vec<f64> = f.iter().zip(mean).map(|(&x, &m)| x as f64 - m).collect();
        for (a, &ca) in c.iter().enumerate() {
            for (r, &cb) in cov[a * dim..(a + 1) * dim].iter_mut().zip(&c) {
                *r += ca * cb;
            }
        }
    }
    let (values, vectors) = symmetric_eigen(cov, dim).unwrap_or_default();
    (0..count)
        .map(|axis| match values.get(axis) {
            Some(&v) if v > 1e-30 => vectors[axis * dim..(axis + 1) * dim].to_vec(),
            _ => vec![0.0; dim],
        })
        .collect()
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
