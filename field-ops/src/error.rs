//! The typed errors of operations on runs, shared by training and
//! evaluation; every variant names the file or input at fault.

use std::path::PathBuf;

/// Everything that can go wrong while loading runs, cameras, point clouds or
/// embeddings, rendering, or writing results.
#[derive(Debug, thiserror::Error)]
pub enum OpsError {
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A JSON file could not be parsed or does not have the expected shape.
    #[error("{path}: invalid JSON: {message}")]
    Json {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A required file of a run directory or dataset is missing.
    #[error("{path}: missing ({what})")]
    Missing {
        /// The expected path.
        path: PathBuf,
        /// What the file should contain.
        what: String,
    },
    /// The model weights could not be loaded.
    #[error("{path}: cannot load model weights: {message}")]
    Weights {
        /// The weights file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Encoding or decoding an image failed.
    #[error("{path}: image error: {message}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A dataset-level error (loaders, point clouds, embeddings).
    #[error(transparent)]
    Dataset(#[from] datasets::DatasetError),
    /// Input that is readable but inconsistent (dimension mismatch, empty
    /// point cloud, unknown class name, ...).
    #[error("{0}")]
    Invalid(String),
}

impl OpsError {
    /// An [`OpsError::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    /// An [`OpsError::Json`] for `path`.
    pub fn json(path: impl Into<PathBuf>, message: impl ToString) -> Self {
        Self::Json {
            path: path.into(),
            message: message.to_string(),
        }
    }
}
