//! `summary.json`: the final figures of a run.

use serde::{Deserialize, Serialize};

use crate::accuracy::EvalMetrics;
use crate::view_eval::ViewFigures;

/// `summary.json`: the final figures of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Iterations completed.
    pub iterations: usize,
    /// Held-out figures over the *interior* pixels of the held-out views:
    /// those at least the (scaled) border margin from the image border, the
    /// only ones training ever draws (or of the training views when nothing
    /// is held out).
    pub heldout_interior: EvalMetrics,
    /// Held-out figures over *every* pixel of the held-out views, the
    /// never-supervised border included (`null` when the views were not
    /// rendered in full).
    pub heldout_whole: Option<EvalMetrics>,
    /// The figures of each held-out view rendered in full (empty when the
    /// views were not rendered, and in runs written before it was recorded).
    #[serde(default)]
    pub heldout_views: Vec<ViewFigures>,
    /// Training wall-clock seconds (all sessions of a resumed run).
    pub wall_seconds: f64,
    /// Training rays per second (rays processed / training seconds).
    pub rays_per_second: f64,
    /// Rays per second of the final held-out evaluation (rendering without
    /// autodiff; `null` in runs written before it was recorded).
    #[serde(default)]
    pub render_rays_per_second: Option<f64>,
    /// Peak resident memory of the process (`VmHWM`), bytes.
    pub peak_memory_bytes: Option<u64>,
    /// The untrained field on the fixed sample of interior held-out pixels
    /// that every periodic evaluation measures, for comparison.
    pub initial_interior: Option<EvalMetrics>,
    /// Steps skipped because of a non-finite loss or gradient.
    pub skipped_steps: usize,
    /// Backend used.
    pub backend: String,
    /// Held-out frame indices the figures refer to.
    pub heldout_frames: Vec<usize>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_summary_written_before_ssim_reads_back_without_it() {
        let old = r#"{"iterations":50,"heldout_interior":{"psnr":15.2,"depth_mae":1.4,"feature_cosine":0.9,"pixels":13800},
            "heldout_whole":{"psnr":15.1,"depth_mae":1.3,"feature_cosine":0.9,"pixels":15552},
            "wall_seconds":18.5,"rays_per_second":1500.0,"peak_memory_bytes":1000,"initial_interior":null,
            "skipped_steps":0,"backend":"flex","heldout_frames":[3,7]}"#;
        let s: Summary = serde_json::from_str(old).unwrap();
        assert!(s.heldout_interior.ssim.is_none());
        assert!(s.heldout_whole.is_some_and(|w| w.ssim.is_none()));
        assert!(s.heldout_views.is_empty() && s.render_rays_per_second.is_none());
        // Written again, it gains no SSIM key it never had.
        let text = serde_json::to_string(&s).unwrap();
        assert!(!text.contains("ssim"), "{text}");
        let back: Summary = serde_json::from_str(&text).unwrap();
        assert_eq!(back, s);
    }
}
