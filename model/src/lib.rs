//! The OpenNeRF field and its pure math: cameras and rays ([`geometry`]),
//! Mip-NeRF encodings ([`mip`]), sampling ([`sampling`]), compositing
//! ([`render`]), the MLP with its stop-gradient open-set head ([`field`]),
//! coarse/fine rendering ([`nerf`]), inference with early ray termination ([`march`]), empty-space skipping ([`occupancy`]), the losses ([`loss`]) and the CLIP text
//! transformer that embeds free-text queries ([`clip`]). No file I/O.
#![warn(missing_docs)]

pub mod clip;
pub mod composite;
pub mod field;
pub mod geometry;
pub mod loss;
pub mod march;
pub mod mip;
pub mod nerf;
pub mod occupancy;
pub mod sampling;

pub use composite::Composite;
pub use field::{FeatureHead, FeatureHeadConfig, FieldOutputs, MipMlp, MipMlpConfig};
pub use loss::{FeatureSpace, depth_huber, open_set_cosine, rgb_mse, weighted_rgb_mse};
pub use march::{MarchedRays, Termination};
pub use nerf::{FeatureMode, LevelOutputs, OpenNerf, OpenNerfConfig, Rays, RenderOutputs};
pub use occupancy::{ClippedRays, OccupancyConfig, OccupancyGrid};

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
