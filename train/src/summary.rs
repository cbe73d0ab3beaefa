//! `summary.json`: the final figures of a run.

use serde::{Deserialize, Serialize};

use crate::accuracy::EvalMetrics;

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
