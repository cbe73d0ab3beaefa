//! Everything that turns files on disk (or a seed) into scenes and ray
//! batches: Nice-SLAM Replica, Blender/nerfstudio and LLFF loaders, lazy
//! feature maps with PCA compression, text embeddings, point clouds, the
//! synthetic benchmark scene with its simulated 2D feature extractor, and the
//! ray sampler.
#![warn(missing_docs)]

pub mod balance;
pub mod blender;
pub mod error;
pub mod extractor;
pub mod features;
pub mod imageio;
pub mod llff;
pub mod novel;
pub mod npy;
pub mod points;
pub mod poses;
pub mod replica;
pub mod sampler;
pub mod scene;
pub mod synthetic;
pub mod text;
pub mod writer;

pub use error::DatasetError;
pub use scene::{DepthImage, FeatureMap, Frame, RgbImage, Scene, SceneMeta, SceneSource};

use std::path::PathBuf;

/// Loads (or generates) the scene `source` describes. Disk formats read
/// their options from `options` (missing fields take their defaults).
pub fn load_scene(source: &SceneSource) -> Result<Scene, DatasetError> {
    load_scene_with_basis(source, None)
}

/// [`load_scene`], compressing the feature maps with `basis` (a run's
/// stored PCA basis) instead of fitting one: a rebuilt scene then has
/// exactly the targets its field was trained on.
pub fn load_scene_with_basis(
    source: &SceneSource,
    basis: Option<&features::Pca>,
) -> Result<Scene, DatasetError> {
    match source {
        SceneSource::Synthetic { seed, size, pca } => {
            let size: synthetic::SceneSize = size.parse()?;
            let target = pca.map_or(size.pca_target(), |p| p.target());
            let mut scene = synthetic::generate_with(*seed, size, target, basis)?;
            scene.source = source.clone();
            Ok(scene)
        }
        SceneSource::Disk {
            format,
            path,
            options,
        } => {
            let opts = |o: &serde_json::Value| -> serde_json::Value {
                if o.is_null() {
                    serde_json::json!({})
                } else {
                    o.clone()
                }
            };
            let bad = |e: serde_json::Error| {
                DatasetError::invalid(path, format!("bad {format} loader options: {e}"))
            };
            match format.as_str() {
                "replica" => {
                    let mut o: replica::ReplicaOptions =
                        serde_json::from_value(opts(options)).map_err(bad)?;
                    o.basis = basis.cloned();
                    replica::load_replica(path, &o)
                }
                "blender" => blender::load_blender(
                    path,
                    &serde_json::from_value(opts(options)).map_err(bad)?,
                ),
                "llff" => {
                    llff::load_llff(path, &serde_json::from_value(opts(options)).map_err(bad)?)
                }
                other => Err(DatasetError::invalid(
                    path,
                    format!("unknown scene format {other:?} (expected replica, blender or llff)"),
                )),
            }
        }
    }
}

/// Directory of the shared real data: `$OPENNERF_DATA`, else `shared/data`
/// next to the workspace root.
pub fn data_dir() -> PathBuf {
    match std::env::var_os("OPENNERF_DATA") {
        Some(p) => PathBuf::from(p),
        None => PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")),
    }
}
