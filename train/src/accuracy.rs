//! How close renders come to their targets, in plain numbers: colour PSNR,
//! depth error and feature cosine, summed pixel by pixel, and SSIM, view by
//! view.

use serde::{Deserialize, Serialize};

pub use field_ops::metrics::{cosine, psnr};

/// Running sums of the held-out metrics.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EvalAccumulator {
    /// Sum of squared colour errors over channels.
    pub sq_err: f64,
    /// Number of colour channel values summed.
    pub rgb_values: u64,
    /// Sum of absolute depth errors (metres) over pixels with valid depth.
    pub depth_abs_err: f64,
    /// Pixels with valid depth.
    pub depth_pixels: u64,
    /// Sum of feature cosine similarities.
    pub cosine: f64,
    /// Pixels with a non-zero feature target.
    pub feature_pixels: u64,
    /// Sum of the SSIM of whole views.
    pub ssim: f64,
    /// Views whose SSIM was added.
    pub ssim_views: u64,
}

impl EvalAccumulator {
    /// Adds one pixel: rendered vs target colour, depth (`target <= 0` or
    /// non-finite = no depth) and feature (`None` = no features).
    pub fn add(
        &mut self,
        rgb: [f32; 3],
        target_rgb: [f32; 3],
        depth: Option<(f32, f32)>,
        feature: Option<(&[f32], &[f32])>,
    ) {
        for k in 0..3 {
            let d = (rgb[k] - target_rgb[k]) as f64;
            self.sq_err += d * d;
        }
        self.rgb_values += 3;
        if let Some((d, t)) = depth
            && t > 0.0
            && t.is_finite()
        {
            self.depth_abs_err += (d as f64 - t as f64).abs();
            self.depth_pixels += 1;
        }
        if let Some((f, t)) = feature
            && t.iter().any(|v| v.abs() > 1e-6)
        {
            self.cosine += cosine(f, t);
            self.feature_pixels += 1;
        }
    }

    /// Adds the SSIM of one view (`None`: a view too small for the window,
    /// or without a pixel to average over).
    pub fn add_ssim(&mut self, ssim: Option<f64>) {
        if let Some(s) = ssim {
            self.ssim += s;
            self.ssim_views += 1;
        }
    }

    /// The finished metrics.
    pub fn finish(&self) -> EvalMetrics {
        EvalMetrics {
            psnr: psnr(self.sq_err / self.rgb_values.max(1) as f64),
            depth_mae: (self.depth_pixels > 0)
                .then(|| self.depth_abs_err / self.depth_pixels as f64),
            feature_cosine: (self.feature_pixels > 0)
                .then(|| self.cosine / self.feature_pixels as f64),
            ssim: (self.ssim_views > 0).then(|| self.ssim / self.ssim_views as f64),
            pixels: self.rgb_values / 3,
        }
    }
}

/// Held-out metrics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvalMetrics {
    /// Colour PSNR in dB.
    pub psnr: f64,
    /// Mean absolute error of the rendered median depth in metres (`None`
    /// without depth; see `model::RenderedRays::median_depth`).
    pub depth_mae: Option<f64>,
    /// Mean cosine similarity of rendered vs target features (`None` without features).
    pub feature_cosine: Option<f64>,
    /// Mean SSIM of whole views (11 x 11 Gaussian window, sigma 1.5, see
    /// [`field_ops::ssim`]); absent where views were not rendered in full
    /// (a pixel sample) and in runs written before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ssim: Option<f64>,
    /// Pixels evaluated.
    pub pixels: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_and_cosine_closed_forms() {
        assert!((psnr(0.01) - 20.0).abs() < 1e-12);
        assert!((psnr(1.0)).abs() < 1e-12);
        assert!((cosine(&[1.0, 0.0], &[1.0, 1.0]) - 0.5f64.sqrt()).abs() < 1e-7);
        assert_eq!(cosine(&[0.0, 0.0], &[1.0, 1.0]), 0.0);
        assert!((cosine(&[2.0, -1.0], &[-4.0, 2.0]) + 1.0).abs() < 1e-12);
    }

    #[test]
    fn accumulator_skips_invalid_depth_and_zero_features() {
        let mut acc = EvalAccumulator::default();
        acc.add(
            [0.5; 3],
            [0.6; 3],
            Some((2.0, 2.5)),
            Some((&[1.0, 0.0], &[1.0, 0.0])),
        );
        acc.add(
            [0.5; 3],
            [0.4; 3],
            Some((2.0, 0.0)),
            Some((&[1.0, 0.0], &[0.0, 0.0])),
        );
        acc.add([0.5; 3], [0.5; 3], None, Some((&[1.0, 0.0], &[0.0, 1.0])));
        let m = acc.finish();
        // Squared errors: 3 * 0.01 twice, 0 once, over 9 values.
        assert!((m.psnr - psnr(0.06 / 9.0)).abs() < 1e-5, "{}", m.psnr);
        assert!((m.depth_mae.unwrap() - 0.5).abs() < 1e-12);
        assert!((m.feature_cosine.unwrap() - 0.5).abs() < 1e-12);
        assert_eq!(m.pixels, 3);
        let empty = EvalAccumulator::default().finish();
        assert!(empty.depth_mae.is_none() && empty.feature_cosine.is_none());
        assert!(m.ssim.is_none() && empty.ssim.is_none());
        let mut views = EvalAccumulator::default();
        views.add_ssim(Some(0.5));
        views.add_ssim(None);
        views.add_ssim(Some(0.75));
        assert_eq!(views.finish().ssim, Some(0.625));
    }
}
