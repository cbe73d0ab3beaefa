//! The files of a batch directory, as `batch` writes them and `eval gather`
//! reads them: `batch.json` (the list of runs, fixed when the batch is
//! written, so that array task `i` means the same run however the scene
//! list is edited afterwards) and, in each run directory, `batch_task.json`
//! (how far that run got).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::OpsError;
use crate::json::{read_json, write_json};

/// File name of the batch's list of runs.
pub const MANIFEST_FILE: &str = "batch.json";
/// File name of a run's batch record.
pub const TASK_FILE: &str = "batch_task.json";

/// One run of a batch: a scene trained with one seed, then evaluated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatchTask {
    /// Position in the batch (the Slurm array index).
    pub index: usize,
    /// The run directory's name, under the batch directory.
    pub run: String,
    /// The scene it belongs to (runs of one scene are averaged by
    /// `eval gather`).
    pub scene: String,
    /// `--seed` of the run, when the scene lists seeds.
    pub seed: Option<u64>,
    /// Arguments of `train` (without the program name and `--out`).
    pub train: Vec<String>,
    /// `eval` commands run after training, each without the program name
    /// and `--run`.
    pub eval: Vec<Vec<String>>,
}

/// `batch.json`: where the list came from and its runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatchManifest {
    /// The scene list the batch was written from.
    pub scenes_file: PathBuf,
    /// The runs, in array order.
    pub tasks: Vec<BatchTask>,
}

impl BatchManifest {
    /// Reads `DIR/batch.json`.
    pub fn read(dir: &Path) -> Result<Self, OpsError> {
        read_json(&dir.join(MANIFEST_FILE))
    }

    /// Writes `DIR/batch.json` (atomically).
    pub fn write(&self, dir: &Path) -> Result<(), OpsError> {
        write_json(&dir.join(MANIFEST_FILE), self)
    }
}

/// How far a run of a batch got.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskState {
    /// Training or evaluation is under way, or was stopped (by a signal or
    /// a killed job) and resumes when the task runs again.
    Running,
    /// Trained and every `eval` command done.
    Done,
    /// Stopped by an error (in `error`); running the task again retries it.
    Failed,
}

/// `batch_task.json` of a run directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskRecord {
    /// The state.
    pub state: TaskState,
    /// How many times the task has started (1 for an uninterrupted run).
    pub attempts: u32,
    /// The `eval` commands finished, in order (indices into the task's
    /// list).
    pub eval_done: Vec<usize>,
    /// The error that stopped it, when `state` is `failed`.
    pub error: Option<String>,
}

impl TaskRecord {
    /// Path of the record in run directory `run`.
    pub fn path(run: &Path) -> PathBuf {
        run.join(TASK_FILE)
    }

    /// The record of `run`, `None` when it has none.
    pub fn read(run: &Path) -> Result<Option<Self>, OpsError> {
        let path = Self::path(run);
        if !path.exists() {
            return Ok(None);
        }
        read_json(&path).map(Some)
    }

    /// Writes the record of `run` (atomically).
    pub fn write(&self, run: &Path) -> Result<(), OpsError> {
        write_json(&Self::path(run), self)
    }
}
