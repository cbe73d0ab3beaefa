//! The error type of the CLIP text model loader: always names the file (and
//! the tensor or field) at fault.

use std::path::{Path, PathBuf};

/// A failure to load or run a CLIP text model.
#[derive(Debug, thiserror::Error)]
pub enum ClipError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A required file is not there.
    #[error("{path}: missing ({what})")]
    Missing {
        /// The file or directory looked for.
        path: PathBuf,
        /// What it should contain.
        what: String,
    },
    /// A file exists but its content is wrong.
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A weights file lacks a tensor the model needs.
    #[error("{path}: no tensor {name:?} ({layout} naming)")]
    MissingTensor {
        /// The weights file.
        path: PathBuf,
        /// The tensor name.
        name: String,
        /// The naming scheme it was looked up in.
        layout: &'static str,
    },
    /// A tensor has the wrong shape.
    #[error("{path}: tensor {name:?} has shape {found:?}, expected {expected:?}")]
    TensorShape {
        /// The weights file.
        path: PathBuf,
        /// The tensor name.
        name: String,
        /// The shape the model needs.
        expected: Vec<usize>,
        /// The shape in the file.
        found: Vec<usize>,
    },
    /// Text that cannot be encoded (empty, or a token the vocabulary lacks).
    #[error("{0}")]
    Text(String),
    /// An image that cannot be turned into features (e.g. smaller than a patch).
    #[error("{0}")]
    Image(String),
}

impl ClipError {
    /// An [`ClipError::Io`] for `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }

    /// A content error for `path`.
    pub fn invalid(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.as_ref().to_path_buf(),
            message: message.into(),
        }
    }

    /// A missing file or directory.
    pub fn missing(path: impl AsRef<Path>, what: impl Into<String>) -> Self {
        Self::Missing {
            path: path.as_ref().to_path_buf(),
            what: what.into(),
        }
    }
}

/// Reads a whole file, naming it in the error (a missing file is
/// [`ClipError::Missing`]).
pub(crate) fn read_file(path: &Path, what: &str) -> Result<Vec<u8>, ClipError> {
    std::fs::read(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            ClipError::missing(path, what)
        } else {
            ClipError::io(path, e)
        }
    })
}

/// Reads a UTF-8 text file, naming it in the error.
pub(crate) fn read_text(path: &Path, what: &str) -> Result<String, ClipError> {
    let bytes = read_file(path, what)?;
    String::from_utf8(bytes).map_err(|e| ClipError::invalid(path, format!("not UTF-8: {e}")))
}
