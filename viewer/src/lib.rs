//! A local web viewer of an OpenNeRF run: one page, served by `eval view`
//! for a trained run and by `train --viewer` while training.
//!
//! The page (`assets/`, embedded in the binary: it works offline) shows the
//! scene's points coloured by captured colour, predicted class, error
//! against ground truth, uncertainty or the relevancy of a text query; the
//! training cameras as frustums; and renders of the field at the browser's
//! camera. It talks to the JSON API of [`http`] (listed in the README).
//!
//! The pieces: [`points`] chooses and encodes the cloud, [`state`] holds the
//! run's data and the current field (which training replaces), [`query`]
//! scores text against the points, [`jobs`] runs renders one at a time, and
//! [`http`] routes requests to them.
#![warn(missing_docs)]

pub mod api;
pub mod error;
pub mod http;
pub mod jobs;
pub mod points;
pub mod query;
pub mod state;

pub use error::ViewerError;
pub use http::{ServerHandle, ServerOptions, start};
pub use state::{FieldSnapshot, Viewer, ViewerData, ViewerOptions};

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
