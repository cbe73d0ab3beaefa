//! Typed errors of `batch`; each names the file or command at fault.

use std::path::{Path, PathBuf};

/// Everything that can stop a batch.
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// The scene list cannot be read or is inconsistent.
    #[error("{path}: {message}")]
    Scenes {
        /// The scene list.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The batch directory does not hold what it should.
    #[error("{path}: {message}")]
    Dir {
        /// The directory or file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing a run's files failed.
    #[error(transparent)]
    Ops(#[from] field_ops::OpsError),
    /// Slurm's commands are missing or refused the job.
    #[error("{0}")]
    Slurm(String),
}

impl BatchError {
    /// A problem of the scene list `path`.
    pub fn scenes(path: &Path, message: impl std::fmt::Display) -> Self {
        Self::Scenes {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }

    /// A problem of the batch directory (or one of its files) `path`.
    pub fn dir(path: &Path, message: impl std::fmt::Display) -> Self {
        Self::Dir {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}
