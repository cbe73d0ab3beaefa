//! Structural similarity (SSIM; Wang, Bovik, Sheikh and Simoncelli 2004) as
//! the NeRF papers report it: an 11 x 11 Gaussian window of standard
//! deviation 1.5, constants `K1 = 0.01` and `K2 = 0.03` over a data range of
//! 1 (colours in `[0, 1]`), population (not sample) variances, computed per
//! channel at every pixel whose window lies inside the image, and averaged.
//! This is scikit-image's `structural_similarity(..., gaussian_weights=True,
//! sigma=1.5, use_sample_covariance=False, data_range=1, channel_axis=-1)`
//! and Mip-NeRF's `compute_ssim`.

/// Pixels on each side of a window's centre (the window is `2 * R + 1` wide).
pub const SSIM_RADIUS: usize = 5;
/// Standard deviation of the Gaussian window, pixels.
pub const SSIM_SIGMA: f64 = 1.5;
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// The SSIM of every window centre of an image pair, averaged over the three
/// channels: centres `(x, y)` with `R <= x < width - R` and
/// `R <= y < height - R` (`R` = [`SSIM_RADIUS`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SsimMap {
    /// Width of the images compared.
    pub image_width: u32,
    /// Height of the images compared.
    pub image_height: u32,
    /// `(height - 2R) * (width - 2R)` values, row-major, in `[-1, 1]`.
    pub values: Vec<f64>,
}

impl SsimMap {
    /// The mean over every centre: the image pair's SSIM.
    pub fn mean(&self) -> f64 {
        self.values.iter().sum::<f64>() / self.values.len() as f64
    }

    /// The mean over the centres `(x, y)` (image coordinates) for which
    /// `keep` holds; `None` when it holds for none.
    pub fn mean_where(&self, keep: impl Fn(u32, u32) -> bool) -> Option<f64> {
        let r = SSIM_RADIUS as u32;
        let w = self.image_width - 2 * r;
        let (mut sum, mut n) = (0.0, 0usize);
        for (i, &v) in self.values.iter().enumerate() {
            let (x, y) = (i as u32 % w + r, i as u32 / w + r);
            if keep(x, y) {
                sum += v;
                n += 1;
            }
        }
        (n > 0).then(|| sum / n as f64)
    }
}

/// The normalised 1D Gaussian window (`2R + 1` weights summing to 1).
pub fn gaussian_window() -> Vec<f64> {
    let r = SSIM_RADIUS as f64;
    let w: Vec<f64> = (0..=2 * SSIM_RADIUS)
        .map(|i| (-0.5 * ((i as f64 - r) / SSIM_SIGMA).powi(2)).exp())
        .collect();
    let sum: f64 = w.iter().sum();
    w.into_iter().map(|v| v / sum).collect()
}

/// The SSIM map of two RGB images (`height * width * 3` values each,
/// row-major, in `[0, 1]`); `None` when their lengths differ from
/// `3 * width * height` or either side is smaller than the window.
pub fn ssim_map(a: &[f32], b: &[f32], width: u32, height: u32) -> Option<SsimMap> {
    let (w, h) = (width as usize, height as usize);
    let win = 2 * SSIM_RADIUS + 1;
    if a.len() != 3 * w * h || b.len() != 3 * w * h || w < win || h < win {
        return None;
    }
    let (ow, oh) = (w - 2 * SSIM_RADIUS, h - 2 * SSIM_RADIUS);
    let g = gaussian_window();
    let mut values = vec![0.0f64; ow * oh];
    for c in 0..3 {
        let x: Vec<f64> = (0..w * h).map(|p| a[3 * p + c] as f64).collect();
        let y: Vec<f64> = (0..w * h).map(|p| b[3 * p + c] as f64).collect();
        let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
        let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
        let xy: Vec<f64> = x.iter().zip(&y).map(|(p, q)| p * q).collect();
        let [ux, uy, uxx, uyy, uxy] =
            [&x, &y, &xx, &yy, &xy].map(|img| filter_valid(img, w, h, &g));
        for (i, v) in values.iter_mut().enumerate() {
            let (mx, my) = (ux[i], uy[i]);
            let vx = uxx[i] - mx * mx;
            let vy = uyy[i] - my * my;
            let vxy = uxy[i] - mx * my;
            let s = ((2.0 * mx * my + C1) * (2.0 * vxy + C2))
                / ((mx * mx + my * my + C1) * (vx + vy + C2));
            *v += s / 3.0;
        }
    }
    Some(SsimMap {
        image_width: width,
        image_height: height,
        values,
    })
}

/// The SSIM of two RGB images (see [`ssim_map`]).
pub fn ssim(a: &[f32], b: &[f32], width: u32, height: u32) -> Option<f64> {
    ssim_map(a, b, width, height).map(|m| m.mean())
}

/// `img` (`h x w`) filtered by the separable window `g` at every centre whose
/// window lies inside the image: `(h - 2R) x (w - 2R)` values.
fn filter_valid(img: &[f64], w: usize, h: usize, g: &[f64]) -> Vec<f64> {
    let k = g.len();
    let ow = w + 1 - k;
    let mut rows = vec![0.0f64; ow * h];
    for y in 0..h {
        let line = &img[y * w..(y + 1) * w];
        for x in 0..ow {
            rows[y * ow + x] = g.iter().zip(&line[x..x + k]).map(|(a, b)| a * b).sum();
        }
    }
    let oh = h + 1 - k;
    let mut out = vec![0.0f64; ow * oh];
    for y in 0..oh {
        for (t, &gt) in g.iter().enumerate() {
            let src = &rows[(y + t) * ow..(y + t + 1) * ow];
            for (o, &s) in out[y * ow..(y + 1) * ow].iter_mut().zip(src) {
                *o += gt * s;
            }
        }
    }
    out
}
