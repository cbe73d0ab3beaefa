//! Pictures of rendered views: the colour, depth (Turbo) and feature (top
//! three principal components) images.

use std::path::{Path, PathBuf};

use datasets::features::symmetric_eigen;
use datasets::imageio::save_rgb8;

use crate::colormap::{to_u8, turbo};
use crate::error::OpsError;
use crate::render::RenderedView;

/// Writes `{name}_rgb.png`, `{name}_depth.png` (Turbo over the depth range of
/// the covered pixels; uncovered pixels black) and, with a feature head,
/// `{name}_feature.png` (the feature image's top three principal components)
/// into `dir`, creating it. Returns the written paths.
pub fn save_view_pngs(
    view: &RenderedView,
    dir: &Path,
    name: &str,
) -> Result<Vec<PathBuf>, OpsError> {
    std::fs::create_dir_all(dir).map_err(|e| OpsError::io(dir, e))?;
    let (w, h) = (view.width, view.height);
    let mut written = Vec::new();

    let path = dir.join(format!("{name}_rgb.png"));
    let rgb: Vec<u8> = view.rgb.iter().map(|&v| to_u8(v)).collect();
    save_rgb8(&path, w, h, &rgb)?;
    written.push(path);

    let path = dir.join(format!("{name}_depth.png"));
    save_rgb8(&path, w, h, &depth_colors(&view.depth, &view.acc))?;
    written.push(path);

    if view.feature_dim > 0 {
        let path = dir.join(format!("{name}_feature.png"));
        let colors = pca_colors(&view.feature, view.feature_dim);
        let bytes: Vec<u8> = colors.into_iter().flatten().collect();
        save_rgb8(&path, w, h, &bytes)?;
        written.push(path);
    }
    Ok(written)
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
