//! What a trained OpenNeRF run can do, shared by the `train` and `eval`
//! crates: the run directory and its reloading (including recorded novel
//! views), backend choice, rendering views, projecting points into views
//! with an occlusion test, the uncertainty map of the 2D feature maps,
//! novel cameras with their rendering and re-extraction (and the
//! ground-truth oracle), class scores and relevancy of field features
//! (with text embedded by a CLIP model), images (depth over a robust range,
//! held-out strips), SSIM and plots.
//!
//! # Use from another crate
//!
//! A run directory (`config.json`, `model.bpk`, `scene.json`, as `train`
//! writes it) loads with [`run_dir::load_run`]; [`render::render_view`]
//! renders it at any camera, [`sample::sampled_features`] gives the field's
//! features at world points and [`query::cosine_scores`] scores them
//! against a text embedding (lifting PCA coefficients when the run has
//! them). `cargo run -p field-ops --release --example query_run` does the
//! same on a trained run.
//!
//! ```
//! use burn::module::Module;
//! use burn::tensor::Device;
//! use datasets::SceneMeta;
//! use datasets::synthetic::{SceneSize, generate};
//! use field_ops::query::{cosine_scores, embedding_by_name};
//! use field_ops::render::{ViewSettings, render_view};
//! use field_ops::run_dir::{RunDir, load_run};
//! use field_ops::sample::sampled_features;
//! use model::{FeatureHeadConfig, MipMlpConfig, OpenNerfConfig};
//!
//! // A run directory as `train` writes it, here with an untrained field on
//! // the built-in test room.
//! let scene = generate(0, SceneSize::Ci).unwrap();
//! let maps = scene.features.as_ref().unwrap();
//! let device = Device::flex();
//! let config = OpenNerfConfig::new(FeatureHeadConfig::new(maps.dim()).with_width(16))
//!     .with_mlp(MipMlpConfig::new().with_width(32).with_depth(2).with_skip_layer(1).with_max_deg(4))
//!     .with_num_samples(8);
//! let dir = tempfile::tempdir().unwrap();
//! let run = RunDir::new(dir.path());
//! std::fs::write(run.config(), serde_json::json!({ "model": config }).to_string()).unwrap();
//! config.init(&device).save_file(run.weights()).unwrap();
//! let meta = SceneMeta {
//!     source: scene.source.clone(),
//!     scene_box: scene.scene_box,
//!     background: scene.background,
//!     pca: maps.pca.clone(),
//!     feature_dim: Some(maps.full_dim),
//!     world: None,
//! };
//! std::fs::write(run.scene(), serde_json::to_string(&meta).unwrap()).unwrap();
//!
//! // Loaded back: a camera of the scene rendered at 16x9 with features.
//! let loaded = load_run(dir.path(), &device).unwrap();
//! let camera = scene.frames[0].camera.scaled(16, 9);
//! let settings = ViewSettings::new(loaded.meta.background, 4096).with_features(true);
//! let view = render_view(&loaded.model, &camera, &loaded.meta.scene_box, &settings).unwrap();
//! assert_eq!((view.pixels(), view.feature_dim), (144, maps.dim()));
//!
//! // 100 of the room's points scored against the first class's embedding.
//! let points = &scene.points.as_ref().unwrap().positions[..100];
//! let features = sampled_features(&loaded.model, points, &loaded.meta.scene_box, 0.01, 4096, &device);
//! let classes = scene.classes.as_ref().unwrap();
//! let query = embedding_by_name(classes, &classes.names[0]).unwrap();
//! let scores = cosine_scores(&features, &query, loaded.meta.pca.as_ref()).unwrap();
//! assert_eq!(scores.len(), 100);
//! assert!(scores.iter().all(|c| c.abs() <= 1.0 + 1e-5));
//! ```
#![warn(missing_docs)]

pub mod allocator;
pub mod backend;
pub mod batch_dir;
pub mod colormap;
pub mod dataset_arg;
pub mod depth_image;
pub mod error;
pub mod files;
pub mod frame;
pub mod images;
pub mod json;
pub mod kernel_cache;
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
pub mod ssim;
pub mod stages;
pub mod strips;
pub mod subnormals;
pub mod text_query;
pub mod uncertainty;
pub mod vlm_maps;

pub use error::OpsError;

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
