//! Errors of the viewer: each one becomes an HTTP status and a JSON body
//! `{"error": "..."}` for the page to show.

use field_ops::OpsError;

/// What can go wrong while starting the server or answering a request.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    /// The request is malformed or asks for something that does not exist
    /// (HTTP 400).
    #[error("{0}")]
    BadRequest(String),
    /// No such resource (HTTP 404).
    #[error("{0}")]
    NotFound(String),
    /// The request body exceeds the limit (HTTP 413).
    #[error("request body over {limit} bytes")]
    TooLarge {
        /// The limit in bytes.
        limit: usize,
    },
    /// Loading, rendering or scoring failed (HTTP 500).
    #[error(transparent)]
    Ops(#[from] OpsError),
    /// The server could not start (e.g. the port is taken).
    #[error("cannot serve on {addr}: {reason}")]
    Bind {
        /// The address asked for.
        addr: String,
        /// Why binding failed.
        reason: String,
    },
}

impl ViewerError {
    /// The HTTP status of this error.
    pub fn status(&self) -> u16 {
        match self {
            ViewerError::BadRequest(_) => 400,
            ViewerError::NotFound(_) => 404,
            ViewerError::TooLarge { .. } => 413,
            // A user's mistake found while scoring (an unknown class, a text
            // model of another dimension) is the request's fault.
            ViewerError::Ops(OpsError::Invalid(_)) => 400,
            ViewerError::Ops(_) | ViewerError::Bind { .. } => 500,
        }
    }
}
