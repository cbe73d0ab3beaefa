//! Building the scene a run trains on, from the command line or from the
//! `scene.json` of a run directory.

use std::path::PathBuf;

use datasets::features::PcaSetting;
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
            pca: cli.pca,
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
    let format = cli.dataset.name();
    let unsupported = |flag: &str| {
        Err(TrainError::Config(format!(
            "--{flag} is not supported for --dataset {format}"
        )))
    };
    let mut options = serde_json::Map::new();
    match cli.dataset {
        DatasetKind::Replica => {
            if let Some(s) = cli.stride {
                options.insert("stride".into(), s.into());
            }
            if let Some(r) = cli.resolution {
                options.insert("resolution".into(), serde_json::json!([r.width, r.height]));
            }
            if cli.downscale.is_some() {
                return unsupported("downscale (use --resolution WxH)");
            }
            if let Some(f) = &cli.features {
                options.insert("features".into(), f.display().to_string().into());
                let setting = cli.pca.unwrap_or(PcaSetting::Auto);
                let target = serde_json::to_value(setting.target())
                    .map_err(|e| TrainError::Config(format!("--pca {setting}: {e}")))?;
                options.insert("pca".into(), target);
            } else if cli.pca.is_some() {
                return Err(TrainError::Config(
                    "--pca needs --features (there are no feature maps to compress)".into(),
                ));
            }
        }
        DatasetKind::Blender => {
            if let Some(d) = cli.downscale {
                options.insert("downscale".into(), d.into());
            }
            if cli.stride.is_some() {
                return unsupported("stride");
            }
            if cli.resolution.is_some() {
                return unsupported("resolution (use --downscale N)");
            }
            if cli.features.is_some() {
                return unsupported("features");
            }
            if cli.pca.is_some() {
                return unsupported("pca (the scene has no feature maps)");
            }
        }
        DatasetKind::Llff => {
            // LLFF ships pre-downsampled folders `images_N`.
            if let Some(d) = cli.downscale {
                options.insert("images".into(), format!("images_{d}").into());
            }
            for (flag, given) in [
                ("stride", cli.stride.is_some()),
                ("resolution", cli.resolution.is_some()),
                ("features", cli.features.is_some()),
                ("pca (the scene has no feature maps)", cli.pca.is_some()),
            ] {
                if given {
                    return unsupported(flag);
                }
            }
        }
        DatasetKind::Synthetic => {}
    }
    Ok(SceneSource::Disk {
        format: format.into(),
        path,
        options: serde_json::Value::Object(options),
    })
}

/// Builds (generates or loads) the scene described by `source`, fitting
/// its PCA basis when it has one.
pub fn load(source: &SceneSource) -> Result<Scene, TrainError> {
    Ok(datasets::load_scene(source)?)
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

#[cfg(test)]
mod pca_flag_tests {
    use clap::Parser;
    use datasets::features::PcaTarget;

    use super::*;

    fn source(args: &[&str]) -> Result<SceneSource, TrainError> {
        let mut all = vec!["train"];
        all.extend_from_slice(args);
        source_from_cli(&Cli::try_parse_from(all).expect("parses"))
    }

    /// `--pca` reaches every loader with feature maps; maps on disk are
    /// compressed by default; scenes without maps refuse it.
    #[test]
    fn pca_flag_reaches_the_loaders() {
        let dir = tempfile::tempdir().expect("temp dir");
        let data = dir.path().display().to_string();
        match source(&["--pca", "8"]).expect("synthetic") {
            SceneSource::Synthetic { pca, .. } => assert_eq!(pca, Some(PcaSetting::Components(8))),
            other => panic!("{other:?}"),
        }
        let replica_pca = |extra: &[&str]| {
            let mut args = vec!["--dataset", "replica", "--data", &data, "--features", &data];
            args.extend_from_slice(extra);
            match source(&args).expect("replica") {
                SceneSource::Disk { options, .. } => options["pca"].clone(),
                other => panic!("{other:?}"),
            }
        };
        let auto = serde_json::to_value(Some(PcaTarget::ExplainedVariance(0.99))).unwrap();
        assert_eq!(replica_pca(&[]), auto);
        assert_eq!(replica_pca(&["--pca", "off"]), serde_json::Value::Null);
        assert_eq!(
            replica_pca(&["--pca", "16"]),
            serde_json::to_value(Some(PcaTarget::Components(16))).unwrap()
        );
        for fmt in ["blender", "llff"] {
            let e = source(&["--dataset", fmt, "--data", &data, "--pca", "4"])
                .expect_err("no maps to compress");
            assert!(e.to_string().contains("--pca"), "{e}");
        }
        let e = source(&["--dataset", "replica", "--data", &data, "--pca", "4"])
            .expect_err("no --features");
        assert!(e.to_string().contains("--features"), "{e}");
        assert!(Cli::try_parse_from(["train", "--pca", "0"]).is_err());
        assert!(Cli::try_parse_from(["train", "--pca", "most"]).is_err());
    }
}
