//! Typed errors of the training crate; every variant names the file or the
//! input at fault.

use std::path::{Path, PathBuf};

use field_ops::OpsError;

/// Everything that can stop a training run.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A checkpoint file is truncated, overwritten with garbage or does not
    /// match the model it is loaded into.
    #[error("{path}: corrupt or incompatible checkpoint: {message}")]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// The run directory given to `--resume` has no checkpoint.
    #[error("{path}: no checkpoint to resume from (expected checkpoints/ckpt-*.onck)")]
    NoCheckpoint {
        /// The run directory.
        path: PathBuf,
    },
    /// Too many consecutive steps had a non-finite loss or gradient.
    #[error(
        "training diverged: {count} consecutive steps with a non-finite loss or gradient \
         (last at iteration {iteration}); the last good checkpoint is intact{}",
        last_checkpoint.as_ref().map(|p| format!(" at {}", p.display())).unwrap_or_default()
    )]
    Diverged {
        /// Consecutive non-finite steps.
        count: usize,
        /// Iteration of the last one.
        iteration: usize,
        /// The last checkpoint written, if any.
        last_checkpoint: Option<PathBuf>,
    },
    /// A signal asked the run to stop; its checkpoint at `iteration` is
    /// written and `--resume` continues it.
    #[error(
        "interrupted by a signal at iteration {iteration}: checkpoint {} written; \
         continue with `train --resume {}`",
        checkpoint.display(),
        dir.display()
    )]
    Interrupted {
        /// Iterations completed.
        iteration: usize,
        /// The checkpoint written.
        checkpoint: PathBuf,
        /// The run directory.
        dir: PathBuf,
    },
    /// A dataset could not be loaded.
    #[error(transparent)]
    Dataset(#[from] datasets::DatasetError),
    /// Reading or writing a file of the run, rendering or novel views
    /// failed (the errors shared with `eval`).
    #[error(transparent)]
    Ops(#[from] OpsError),
    /// An option or configuration value is out of range or inconsistent.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// The compute device could not be used.
    #[error("device error: {0}")]
    Device(String),
}

impl TrainError {
    /// A failed read or write of `path` ([`OpsError::Io`]).
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Self::Ops(OpsError::io(path.as_ref(), source))
    }

    /// A JSON file at `path` that does not parse or has the wrong shape
    /// ([`OpsError::Json`]).
    pub fn json(path: impl AsRef<Path>, message: impl ToString) -> Self {
        Self::Ops(OpsError::json(path.as_ref(), message))
    }

    /// A [`TrainError::Checkpoint`] for `path`.
    pub fn checkpoint(path: impl AsRef<Path>, message: impl ToString) -> Self {
        Self::Checkpoint {
            path: path.as_ref().to_path_buf(),
            message: message.to_string(),
        }
    }
}
