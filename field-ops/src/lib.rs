//! What a trained OpenNeRF run can do, shared by the `train` and `eval`
//! crates: the run directory and its reloading (including recorded novel
//! views), backend choice, rendering views, projecting points into views
//! with an occlusion test, the uncertainty map of the 2D feature maps,
//! novel cameras with their rendering and re-extraction (and the
//! ground-truth oracle), class scores and relevancy of field features
//! (with text embedded by a CLIP model), images and plots.
#![warn(missing_docs)]

pub mod allocator;
pub mod backend;
pub mod colormap;
pub mod error;
pub mod files;
pub mod frame;
pub mod images;
pub mod json;
pub mod metrics;
pub mod novel;
pub mod plot;
pub mod progress;
pub mod project;
pub mod query;
pub mod render;
pub mod run_dir;
pub mod sample;
pub mod scores;
pub mod similarity;
pub mod stages;
pub mod text_query;
pub mod uncertainty;
pub mod vlm_maps;

pub use error::OpsError;

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
