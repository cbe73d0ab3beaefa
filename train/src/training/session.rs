//! What a session is asked to do besides the configuration, what it starts
//! from, and what it returns.

use std::borrow::Cow;
use std::path::PathBuf;

use burn::optim::ModuleOptimizer;
use burn::tensor::Device;
use datasets::Scene;
use field_ops::novel::record::RecordedViews;
use field_ops::run_dir::{RunDir, Split};
use field_ops::stages::StageLog;
use model::OpenNerf;

use crate::backend::BackendKind;
use crate::checkpoint::CheckpointState;
use crate::config::TrainConfig;
use crate::interrupt::StopFlag;
use crate::summary::Summary;

/// How a session runs (as opposed to what is trained, which is the config).
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Backend.
    pub backend: BackendKind,
    /// wgpu adapter index.
    pub device_index: Option<usize>,
    /// Stop after this many seconds of this session (then evaluate and save).
    pub time_budget: Option<f64>,
    /// Stop after this iteration even if the schedule is longer.
    pub stop_at: Option<usize>,
    /// Show a progress bar (otherwise plain log lines).
    pub progress: bool,
    /// Render the held-out views to PNG and measure them in full at the end.
    pub final_render: bool,
    /// With a time budget: time the first steps and set the schedule's
    /// length to the iterations that fit the budget (written back to
    /// `config.json`), so that the learning rate decays over the whole
    /// budget instead of the run ending early or being cut mid-schedule.
    pub fit_schedule_to_budget: bool,
    /// Serve the run's web viewer while training.
    pub viewer: Option<super::ViewerSettings>,
    /// Raised (by a signal handler) to stop before the next step with a
    /// checkpoint: the session then returns `TrainError::Interrupted`.
    pub stop: StopFlag,
}

impl Default for SessionOptions {
    fn default() -> Self {
        Self {
            backend: BackendKind::Flex,
            device_index: None,
            time_budget: None,
            stop_at: None,
            progress: false,
            final_render: true,
            fit_schedule_to_budget: false,
            viewer: None,
            stop: StopFlag::new(),
        }
    }
}

impl SessionOptions {
    /// The last iteration of this session for a schedule of `iterations`.
    pub fn end(&self, iterations: usize) -> usize {
        self.stop_at.map_or(iterations, |s| s.min(iterations))
    }
}

/// What a finished session returns.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// The run directory.
    pub dir: PathBuf,
    /// The summary written to `summary.json`.
    pub summary: Summary,
}

/// Everything a session starts from.
pub(super) struct SessionStart<'a> {
    /// Owned when the caller hands the scene over (adding novel views then
    /// extends it in place instead of copying it first).
    pub scene: Cow<'a, Scene>,
    /// Novel views already made (read back on resume).
    pub added: Option<RecordedViews>,
    pub config: &'a TrainConfig,
    pub split: &'a Split,
    pub run: &'a RunDir,
    pub model: OpenNerf,
    pub optim: ModuleOptimizer,
    pub state: CheckpointState,
    pub device: &'a Device,
    pub session: &'a SessionOptions,
    /// Where the stages' time and peak memory are recorded.
    pub stages: StageLog,
}
