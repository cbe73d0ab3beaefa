//! Building the scene a run trains on, from the command line or from the
//! `scene.json` of a run directory.

use std::path::PathBuf;

use datasets::{Scene, SceneMeta, SceneSource};

use crate::cli::{Cli, DatasetKind, SceneSizeArg};
use crate::error::TrainError;

/// How to build the scene of a new run, from the command-line options.
pub fn source_from_cli(cli: &Cli) -> Result<SceneSource, TrainError> {
    if cli.dataset == DatasetKind::Synthetic {
        return Ok(SceneSource::Synthetic {
            seed: cli.scene_seed,
            size: match cli.scene_size {
                SceneSizeArg::Ci => "ci".into(),
                SceneSizeArg::Bench => "bench".into(),
            },
        });
    }
    let path: PathBuf = cli.data.clone().ok_or_else(|| {
        TrainError::Config(format!(
            "--dataset {} needs --data PATH (the scene directory)",
            cli.dataset.name()
        ))
    })?;
    if !path.exists() {
        return Err(TrainError::io(
            &path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "scene directory not found"),
        ));
    }
    let mut options = serde_json::Map::new();
    if let Some(s) = cli.stride {
        options.insert("stride".into(), s.into());
    }
    if let Some(r) = cli.resolution {
        options.insert("resolution".into(), serde_json::json!([r.width, r.height]));
    }
    if let Some(d) = cli.downscale {
        options.insert("downscale".into(), d.into());
    }
    if let Some(f) = &cli.features {
        options.insert("features".into(), f.display().to_string().into());
    }
    Ok(SceneSource::Disk {
        format: cli.dataset.name().into(),
        path,
        options: serde_json::Value::Object(options),
    })
}

/// Builds (generates or loads) the scene described by `source`.
pub fn load(source: &SceneSource) -> Result<Scene, TrainError> {
    match source {
        SceneSource::Synthetic { seed, size } => {
            let size: datasets::synthetic::SceneSize = size.parse()?;
            Ok(datasets::synthetic::generate(*seed, size)?)
        }
        SceneSource::Disk { format, path, .. } => Err(TrainError::Config(format!(
            "{}: loading {format} scenes is not available in this build",
            path.display()
        ))),
    }
}

/// What `scene.json` records about `scene`.
pub fn meta(scene: &Scene) -> SceneMeta {
    SceneMeta {
        source: scene.source.clone(),
        scene_box: scene.scene_box,
        background: scene.background,
        pca: scene.features.as_ref().and_then(|f| f.pca.clone()),
        feature_dim: scene.features.as_ref().map(|f| f.full_dim),
    }
}

/// A short name for the default run directory.
pub fn run_name(source: &SceneSource) -> String {
    match source {
        SceneSource::Synthetic { .. } => "synthetic".into(),
        SceneSource::Disk { format, .. } => format.clone(),
    }
}
