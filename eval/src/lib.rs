//! Evaluation of trained OpenNeRF runs: zero-shot 3D semantic segmentation
//! with its metrics, relevancy queries (class names, embeddings or free
//! text), and the `eval` command line (one module per subcommand in
//! [`commands`]). What a run can do that training also needs (loading it,
//! rendering, projecting, the uncertainty map, novel views) lives in the
//! `field_ops` crate.
#![warn(missing_docs)]

pub mod cameras;
pub mod checks;
pub mod cli;
// Flag help is written for `--help`: `[D]` is a shape and `<scene>` a
// placeholder there, not a link or an HTML tag.
#[allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]
pub mod commands;
pub mod figures;
pub mod metrics;
pub mod segment;

// Scoring and relevancy are shared with training's viewer: they live in
// `field_ops` and keep their paths here.
pub use field_ops::{query, similarity, text_query};

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
