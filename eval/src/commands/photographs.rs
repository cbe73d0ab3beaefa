//! Renders of scene frames against their photographs: PSNR and SSIM per
//! view, the strip `photograph | render | error | depth` per view, one
//! contact sheet, and `render_metrics.json` with the figures. A render at
//! another size than the photograph is measured against the photograph
//! resized to it ([`PHOTOGRAPH_FILTER`]).

use std::path::{Path, PathBuf};

use datasets::RgbImage;
use field_ops::OpsError;
use field_ops::metrics::psnr;
use field_ops::render::RenderedView;
use field_ops::ssim::ssim;
use field_ops::strips::{PHOTOGRAPH_FILTER, Strips, resized_photograph};
use serde::Serialize;

/// One view's figures against its photograph.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewScore {
    /// The camera's (frame's) name.
    pub name: String,
    /// Mean squared colour error over every pixel and channel.
    pub mse: f64,
    /// PSNR of `mse`, dB.
    pub psnr: f64,
    /// SSIM over every window centre (`None`: smaller than the window).
    pub ssim: Option<f64>,
    /// The photograph's size before it was resized to the render's, when
    /// it was.
    pub photograph_resized_from: Option<[u32; 2]>,
}

/// The scores and strips of the views rendered so far.
#[derive(Debug, Default)]
pub struct Photographs {
    /// Every scored view, in the order rendered.
    pub scores: Vec<ViewScore>,
    strips: Strips,
}

impl Photographs {
    /// Scores `view` (named `name`) against `photo` (resized to the view's
    /// size where it differs), writes its strip `{name}_strip.png` into
    /// `out` (`depth`: the view's coloured depth) and returns the score.
    pub fn add(
        &mut self,
        name: &str,
        photo: &RgbImage,
        view: &RenderedView,
        depth: &[u8],
        out: &Path,
        written: &mut Vec<PathBuf>,
    ) -> Result<&ViewScore, OpsError> {
        let original = [photo.width, photo.height];
        let resized = original != [view.width, view.height];
        let photo = resized_photograph(photo, view.width, view.height);
        let values = photo.to_f32();
        let n = values.len().max(1) as f64;
        let mse = values
            .iter()
            .zip(&view.rgb)
            .map(|(&a, &b)| (a as f64 - b as f64).powi(2))
            .sum::<f64>()
            / n;
        written.extend(self.strips.add(&photo, view, depth, out, name)?);
        self.scores.push(ViewScore {
            name: name.to_string(),
            mse,
            psnr: psnr(mse),
            ssim: ssim(&values, &view.rgb, view.width, view.height),
            photograph_resized_from: resized.then_some(original),
        });
        Ok(self.scores.last().expect("just pushed"))
    }

    /// PSNR of the mean squared error over the views, and their mean SSIM.
    pub fn means(&self) -> Option<(f64, Option<f64>)> {
        if self.scores.is_empty() {
            return None;
        }
        let n = self.scores.len() as f64;
        let mse = self.scores.iter().map(|s| s.mse).sum::<f64>() / n;
        let ssims: Vec<f64> = self.scores.iter().filter_map(|s| s.ssim).collect();
        let ssim = (!ssims.is_empty()).then(|| ssims.iter().sum::<f64>() / ssims.len() as f64);
        Some((psnr(mse), ssim))
    }

    /// Writes the contact sheet of the strips as `sheet` and
    /// `render_metrics.json` into `out` (nothing without a scored view).
    pub fn finish(&self, out: &Path, sheet: &str) -> Result<Vec<PathBuf>, OpsError> {
        let Some((psnr, ssim)) = self.means() else {
            return Ok(Vec::new());
        };
        let mut written: Vec<PathBuf> = self
            .strips
            .write_sheet(&out.join(sheet))?
            .into_iter()
            .collect();
        let path = out.join("render_metrics.json");
        field_ops::json::write_json(
            &path,
            &serde_json::json!({
                "psnr": psnr,
                "psnr_of": "the mean squared error over every pixel of every view",
                "ssim": ssim,
                "ssim_of": "the mean over views of each view's SSIM (11 x 11 Gaussian window, sigma 1.5)",
                "photograph_filter": PHOTOGRAPH_FILTER,
                "views": self.scores,
            }),
        )?;
        written.push(path);
        Ok(written)
    }
}
