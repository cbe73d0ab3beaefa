//! Building the scene a run trains on, from the command line or from the
//! `scene.json` of a run directory.

use std::path::PathBuf;

use datasets::blender::BlenderOptions;
use datasets::colmap::ColmapOptions;
use datasets::detect::Format;
use datasets::features::PcaSetting;
use datasets::llff::LlffOptions;
use datasets::options::{FeatureInput, FrameSelection};
use datasets::replica::ReplicaOptions;
use datasets::scannet::ScannetOptions;
use datasets::{LoaderOptions, PhoneOptions, Scene, SceneMeta, SceneSource};

use crate::cli::{Cli, DatasetKind};
use crate::error::TrainError;
use crate::settings::args::SparseDepthArg;

/// How to build the scene of a new run, from the command-line options.
pub fn source_from_cli(cli: &Cli) -> Result<SceneSource, TrainError> {
    let kind = cli.dataset_kind();
    if kind == DatasetKind::Synthetic {
        return Ok(SceneSource::Synthetic {
            seed: cli.scene_seed,
            size: cli.scene_size.to_string(),
            pca: cli.pca,
        });
    }
    let path: PathBuf = cli.data.clone().ok_or_else(|| {
        TrainError::Config(format!(
            "--dataset {} needs --data PATH (the scene directory)",
            kind.name()
        ))
    })?;
    if !path.exists() {
        return Err(TrainError::io(
            &path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "scene directory not found"),
        ));
    }
    let format = match kind.format() {
        Some(format) => format,
        None => {
            let found = datasets::detect::detect(&path)?;
            eprintln!(
                "--dataset auto: {} is a {} scene (it holds {})",
                path.display(),
                found.format,
                found.evidence
            );
            found.format
        }
    };
    let mut loader = loader_options(cli, format)?;
    // What every format shares is made once here; loader_options refused
    // what the format does not take.
    *loader.selection_mut() = frame_selection(cli);
    if format == Format::Record3d
        && cli.stride.is_none()
        && cli.sharpest_of.is_none()
        // An export the stride cannot be read from is refused by the
        // loader, with its own message.
        && let Ok(Some(video)) = datasets::phone::record3d::default_stride(&path)
    {
        loader.selection_mut().stride = video.stride;
        let kept = loader.selection().select(0..video.frames).len();
        eprintln!(
            "frames: every {} of the {} frames ({kept} kept, {:.1} a second of the {} fps \
             video; auto: about {} a second of a Record3D video, at least {}; --stride 1 keeps \
             every frame, --sharpest-of {} the sharpest of each {})",
            ordinal(video.stride),
            video.frames,
            video.fps / video.stride as f64,
            video.fps,
            datasets::phone::record3d::VIDEO_FRAMES_PER_SECOND,
            datasets::phone::record3d::MIN_VIDEO_FRAMES,
            video.stride,
            video.stride
        );
    }
    if let Some(input) = loader.feature_input_mut() {
        *input = feature_input(cli);
    }
    if let Some(margin) = cli.box_margin {
        *loader.box_margin_mut() = margin;
    }
    Ok(SceneSource::Disk { loader, path })
}

/// The loader options of `format` from the command line, refusing the
/// flags the format does not take.
fn loader_options(cli: &Cli, format: Format) -> Result<LoaderOptions, TrainError> {
    let name = format.name();
    let unsupported = |flag: &str| {
        Err(TrainError::Config(format!(
            "--{flag} is not supported for --dataset {name}"
        )))
    };
    if format != Format::Colmap && cli.colmap_depth {
        return unsupported("colmap-depth");
    }
    if format != Format::Colmap && cli.sparse_depth == Some(SparseDepthArg::On) {
        return unsupported("sparse-depth on");
    }
    if !format.is_phone()
        && let Some(flag) = first_given(&[
            (
                "min-depth-confidence (phone captures only)",
                cli.min_depth_confidence.is_some(),
            ),
            ("max-depth (phone captures only)", cli.max_depth.is_some()),
        ])
    {
        return unsupported(flag);
    }
    // Replica, COLMAP and phone captures read feature maps from disk.
    if !(matches!(format, Format::Replica | Format::Colmap) || format.is_phone())
        && let Some(flag) = first_given(&[
            ("features", cli.features.is_some()),
            ("pca (the scene has no feature maps)", cli.pca.is_some()),
        ])
    {
        return unsupported(flag);
    }
    Ok(match format {
        Format::Replica => {
            if cli.downscale.is_some() {
                return unsupported("downscale (use --resolution WxH)");
            }
            if cli.features.is_none() && cli.pca.is_some() {
                return Err(TrainError::Config(
                    "--pca needs --features (there are no feature maps to compress)".into(),
                ));
            }
            LoaderOptions::Replica(ReplicaOptions::default())
        }
        Format::Blender => {
            if cli.resolution.is_some() {
                return unsupported("resolution (use --downscale N)");
            }
            let defaults = BlenderOptions::default();
            LoaderOptions::Blender(BlenderOptions {
                downscale: cli.downscale.unwrap_or(defaults.downscale),
                ..defaults
            })
        }
        Format::Llff => {
            if cli.resolution.is_some() {
                return unsupported("resolution");
            }
            LoaderOptions::Llff(LlffOptions {
                // LLFF ships pre-downsampled folders `images_N`.
                images: cli.downscale.map(|d| format!("images_{d}")),
                ..LlffOptions::default()
            })
        }
        Format::Colmap => colmap_options(cli)?,
        Format::Scannet => {
            if cli.downscale.is_some() {
                return unsupported("downscale (use --resolution WxH)");
            }
            LoaderOptions::Scannet(ScannetOptions::default())
        }
        Format::ScannerApp | Format::Record3d | Format::Polycam => phone_options(cli, format)?,
    })
}

/// The COLMAP loader's options from the command line.
fn colmap_options(cli: &Cli) -> Result<LoaderOptions, TrainError> {
    if cli.resolution.is_some() {
        return Err(TrainError::Config(
            "--resolution (use --downscale N for images_N/) is not supported for --dataset colmap"
                .into(),
        ));
    }
    if cli.features.is_none() && cli.pca.is_some() {
        return Err(TrainError::Config(
            "--pca needs --features (there are no feature maps to compress)".into(),
        ));
    }
    let defaults = ColmapOptions::default();
    Ok(LoaderOptions::Colmap(ColmapOptions {
        // COLMAP workspaces keep downscaled copies in `images_N`.
        images: match cli.downscale {
            Some(d) if d > 1 => format!("images_{d}"),
            _ => defaults.images.clone(),
        },
        depth: cli.colmap_depth,
        sparse_depth: crate::settings::depth::loader_flag(cli.sparse_depth, cli.colmap_depth)?,
        ..defaults
    }))
}

/// The loader options of a phone `format` from the command line.
fn phone_options(cli: &Cli, format: Format) -> Result<LoaderOptions, TrainError> {
    if cli.downscale.is_some() {
        return Err(TrainError::Config(format!(
            "--downscale (use --resolution WxH) is not supported for --dataset {}",
            format.name()
        )));
    }
    if cli.features.is_none() && cli.pca.is_some() {
        return Err(TrainError::Config(
            "--pca needs --features (there are no feature maps to compress)".into(),
        ));
    }
    let defaults = PhoneOptions::default();
    let o = PhoneOptions {
        min_depth_confidence: cli
            .min_depth_confidence
            .unwrap_or(defaults.min_depth_confidence),
        max_depth: cli.max_depth.unwrap_or(defaults.max_depth),
        ..defaults
    };
    Ok(match format {
        Format::ScannerApp => LoaderOptions::ScannerApp(o),
        Format::Record3d => LoaderOptions::Record3d(o),
        _ => LoaderOptions::Polycam(o),
    })
}

/// The frames every loader keeps, from `--stride`, `--max-frames` and
/// `--resolution` (each, when not given, the default of every format).
fn frame_selection(cli: &Cli) -> FrameSelection {
    let defaults = FrameSelection::default();
    FrameSelection {
        stride: cli.stride.unwrap_or(defaults.stride),
        max_frames: cli.max_frames.or(defaults.max_frames),
        sharpest_of: cli.sharpest_of,
        max_memory: cli.max_memory,
        resolution: cli
            .resolution
            .map(|r| (r.width, r.height))
            .or(defaults.resolution),
    }
}

/// The feature maps of the command line: those of `--features`,
/// compressed as `--pca` says (by default, maps on disk are compressed).
fn feature_input(cli: &Cli) -> FeatureInput {
    FeatureInput {
        features: cli.features.clone(),
        pca: match &cli.features {
            Some(_) => cli.pca.unwrap_or(PcaSetting::Auto),
            None => FeatureInput::default().pca,
        },
        ..FeatureInput::default()
    }
}

/// `n` as an ordinal ("2nd", "20th").
fn ordinal(n: usize) -> String {
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}

/// The first flag of `flags` that was given.
fn first_given<'a>(flags: &[(&'a str, bool)]) -> Option<&'a str> {
    flags
        .iter()
        .find(|(_, given)| *given)
        .map(|(flag, _)| *flag)
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
        world: scene.world.clone(),
    }
}

/// A short name for the default run directory.
pub fn run_name(source: &SceneSource) -> String {
    source.kind_name().into()
}

#[cfg(test)]
mod pca_flag_tests {
    use clap::Parser;

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
                SceneSource::Disk {
                    loader: LoaderOptions::Replica(o),
                    ..
                } => o.feature_input.pca,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(replica_pca(&[]), PcaSetting::Auto);
        assert_eq!(replica_pca(&["--pca", "off"]), PcaSetting::Off);
        assert_eq!(replica_pca(&["--pca", "16"]), PcaSetting::Components(16));
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

    /// `--box-margin` reaches the options of every format on disk; without
    /// it each keeps its default.
    #[test]
    fn box_margin_reaches_every_loader() {
        let dir = tempfile::tempdir().expect("temp dir");
        let data = dir.path().display().to_string();
        for fmt in [
            "replica",
            "blender",
            "llff",
            "colmap",
            "scannet",
            "scanner-app",
            "record3d",
            "polycam",
        ] {
            let margin = |extra: &[&str]| {
                let mut args = vec!["--dataset", fmt, "--data", &data];
                args.extend_from_slice(extra);
                match source(&args).expect(fmt) {
                    SceneSource::Disk { mut loader, .. } => *loader.box_margin_mut(),
                    other => panic!("{other:?}"),
                }
            };
            assert_eq!(margin(&["--box-margin", "0.7"]), 0.7, "{fmt}");
            assert_eq!(margin(&[]), 0.05, "{fmt}");
        }
    }
}
