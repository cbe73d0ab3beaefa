//! Evaluation of trained OpenNeRF runs: loading run directories, rendering
//! views, projecting points into views, zero-shot 3D semantic segmentation
//! with its metrics, relevancy queries, and the uncertainty of the 2D
//! feature maps.
#![warn(missing_docs)]

pub mod backend;
pub mod cameras;
pub mod checks;
pub mod colormap;
pub mod commands;
pub mod error;
pub mod metrics;
pub mod novel;
pub mod oracle;
pub mod project;
pub mod query;
pub mod render;
pub mod run;
pub mod segment;
pub mod similarity;
pub mod text_query;
pub mod uncertainty;
pub mod visual;

pub use error::EvalError;
