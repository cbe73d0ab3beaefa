//! The error type of every loader: always names the file and the problem.

use std::path::{Path, PathBuf};

/// A failure to read or validate a dataset file.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// The file exists but its content is wrong (bad shape, bad value, ...).
    #[error("{path}: {message}")]
    Invalid {
        /// The offending file (or directory).
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// An option the format's loader cannot honour (a resolution for a
    /// format that reads pre-sized images), named with what to use instead.
    #[error("{path}: the {format} loader does not take the {option} option: {instead}")]
    Unsupported {
        /// The scene directory.
        path: PathBuf,
        /// The format's name ([`crate::detect::Format::name`]).
        format: &'static str,
        /// The option's name, as the saved options spell it.
        option: &'static str,
        /// What to use instead.
        instead: String,
    },
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file that failed.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

impl DatasetError {
    /// A content error for `path`.
    pub fn invalid(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.as_ref().to_path_buf(),
            message: message.into(),
        }
    }

    /// An I/O error for `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }
}
