//! The OpenNeRF field and its pure math: cameras and rays ([`geometry`]),
//! Mip-NeRF encodings ([`mip`]), the field's extent, a box or unbounded
//! ([`extent`], [`unbounded`]), sampling ([`sampling`]) and the step
//! functions the samplers resample and the losses measure ([`stepfun`]),
//! compositing ([`composite`]), the MLP with its stop-gradient open-set head
//! ([`field`]), the model that holds them ([`nerf`]), rendering through one
//! entry point, [`OpenNerf::render`], for training (coarse/fine, dense) and
//! inference (marched with early ray termination) ([`render`]),
//! empty-space skipping with the occupancy grid, its update and byte/hex
//! formats ([`occupancy`]), the losses ([`loss`]) and the names of CLIP's
//! dense variants, which scene files record ([`dense_variant`]; CLIP's
//! transformers are the `clip` crate's). No file I/O.
//!
//! # Use from another crate
//!
//! A field is built from its configuration (a run stores it under `"model"`
//! in `config.json`), its weights round-trip through a burnpack file (a
//! run's `model.bpk`), [`OpenNerf::render`] renders a batch of rays (here
//! for inference, [`RenderRequest::inference`]; [`RenderRequest::train`]
//! gives both levels as tensors for the losses), and
//! [`OpenNerf::query_features`] gives the open-set feature of 3D points to
//! score against a text embedding. `field_ops::run_dir::load_run` does the
//! first two for a run directory.
//!
//! ```
//! use burn::module::Module;
//! use burn::store::ModuleRecord;
//! use burn::tensor::{Bytes, Device, Tensor, TensorData};
//! use model::geometry::NormalizedRay;
//! use model::{FeatureHeadConfig, MipMlpConfig, OpenNerfConfig, RenderRequest};
//!
//! let device = Device::flex();
//! let config = OpenNerfConfig::new(FeatureHeadConfig::new(8).with_width(16))
//!     .with_mlp(MipMlpConfig::new().with_width(32).with_depth(2).with_skip_layer(1).with_max_deg(4))
//!     .with_num_samples(16);
//! // The configuration as a run stores it, and back.
//! let json = serde_json::to_string(&config).unwrap();
//! let config: OpenNerfConfig = serde_json::from_str(&json).unwrap();
//!
//! // Weights saved and loaded into a field built from the same configuration.
//! // The bytes are read whole: Burn's `try_load_file` keeps tensors
//! // file-backed and reads them on first use, so the file must outlive the
//! // field (`field_ops::run_dir::load_weights` reads it whole).
//! let field = config.init(&device);
//! let path = std::env::temp_dir().join(format!("opennerf-doc-{}.bpk", std::process::id()));
//! field.clone().save_file(&path).expect("weights written");
//! let bytes = std::fs::read(&path).expect("weights read");
//! std::fs::remove_file(&path).ok();
//! let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes)).expect("a burnpack");
//! let field = config.init(&device).try_load_record(record).expect("weights match");
//!
//! // Four rays through the normalised scene cube ([-pi, pi]^3), rendered
//! // for inference: colour, depth, opacity and feature per ray, on the host.
//! let rays: Vec<NormalizedRay> = (0..4)
//!     .map(|i| NormalizedRay {
//!         origin: [0.2 * i as f32 - 0.3, 0.0, -2.5],
//!         direction: [0.0, 0.0, 1.0],
//!         radius: 0.002,
//!         near: 0.5,
//!         far: 4.5,
//!     })
//!     .collect();
//! let out = field.render(&RenderRequest::inference(&rays)).expect("no observer, never cancelled");
//! assert_eq!((out.rgb.len(), out.depth.len(), out.feature_dim), (12, 4, 8));
//! assert!(out.acc.iter().all(|&a| (0.0..=1.0 + 1e-5).contains(&a)));
//!
//! // Two points scored against a text embedding of the head's dimension
//! // (with PCA-compressed targets, lift the features first).
//! let points = Tensor::<2>::from_data(TensorData::new(vec![0.0f32, 0.0, 0.0, 1.0, 0.5, -0.5], [2, 3]), &device);
//! let features = field.query_features(points, 0.01); // [2, 8]
//! let text = Tensor::<2>::from_data(TensorData::new(vec![1.0f32; 8], [1, 8]), &device);
//! let cosine = features.clone().mul(text.clone()).sum_dim(1)
//!     .div(features.square().sum_dim(1).sqrt().mul(text.square().sum_dim(1).sqrt()));
//! let cosine: Vec<f32> = cosine.into_data().try_to_vec().unwrap();
//! assert!(cosine.iter().all(|c| c.abs() <= 1.0 + 1e-5));
//! ```
#![warn(missing_docs)]

pub mod appearance;
pub mod composite;
pub mod dense_variant;
pub mod exposure;
pub mod extent;
pub mod fast_field;
pub mod field;
pub mod fused_adam;
pub mod geometry;
pub mod hash_footprint;
pub mod hash_kernel;
pub mod hashgrid;
pub mod host_work;
pub mod level_ramp;
pub mod loss;
pub mod mip;
pub mod nerf;
pub mod occupancy;
pub mod pose;
pub mod proposal;
pub mod rays;
pub mod render;
pub mod sampling;
pub mod sh;
pub mod stepfun;
pub mod unbounded;

pub use appearance::{AppearanceCodes, AppearanceCodesConfig};
pub use composite::Composite;
pub use exposure::{Exposure, ExposureConfig};
pub use extent::{Extent, Spacing};
pub use fast_field::{FastField, FastFieldConfig};
pub use field::{FeatureHead, FeatureHeadConfig, FieldOutputs, MipMlp, MipMlpConfig};
pub use fused_adam::{FusedAdam, FusedAdamConfig};
pub use hashgrid::{HashGrid, HashGridConfig};
pub use loss::{
    FeatureSpace, capped_depth, depth_huber, depth_smoothness, depth_window, open_set_cosine,
    rgb_mse, weighted_rgb_mse,
};
pub use nerf::{OpenNerf, OpenNerfConfig, Radiance, Rays};
pub use occupancy::{ClippedRays, GridDecodeError, OccupancyConfig, OccupancyGrid};
pub use pose::{PoseCorrection, PoseCorrectionConfig};
pub use proposal::{ProposalConfig, ProposalMlp};
pub use render::{
    Cancelled, ClipStats, FeatureMode, GridUse, Inference, Level, LevelField, LevelOutputs,
    PerPhotograph, ProposalLevel, RenderOutputs, RenderPass, RenderRequest, RenderedRays,
    Termination, Train,
};
pub use unbounded::UnboundedConfig;

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
