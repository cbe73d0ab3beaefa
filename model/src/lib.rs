//! The OpenNeRF field and its pure math: cameras and rays ([`geometry`]),
//! Mip-NeRF encodings ([`mip`]), sampling ([`sampling`]), compositing
//! ([`composite`]), the MLP with its stop-gradient open-set head
//! ([`field`]), the model that holds them ([`nerf`]), rendering through one
//! entry point, [`OpenNerf::render`], for training (coarse/fine, dense) and
//! inference (marched with early ray termination) ([`render`]),
//! empty-space skipping with the occupancy grid, its update and byte/hex
//! formats ([`occupancy`]), the losses ([`loss`]) and the CLIP text
//! transformer that embeds free-text queries ([`clip`]). No file I/O.
#![warn(missing_docs)]

pub mod clip;
pub mod composite;
pub mod field;
pub mod geometry;
pub mod loss;
pub mod mip;
pub mod nerf;
pub mod occupancy;
pub mod render;
pub mod sampling;

pub use composite::Composite;
pub use field::{FeatureHead, FeatureHeadConfig, FieldOutputs, MipMlp, MipMlpConfig};
pub use loss::{FeatureSpace, depth_huber, open_set_cosine, rgb_mse, weighted_rgb_mse};
pub use nerf::{OpenNerf, OpenNerfConfig, Rays};
pub use occupancy::{ClippedRays, GridDecodeError, OccupancyConfig, OccupancyGrid};
pub use render::{
    Cancelled, ClipStats, FeatureMode, GridUse, Inference, LevelOutputs, RenderOutputs, RenderPass,
    RenderRequest, RenderedRays, Termination, Train,
};
