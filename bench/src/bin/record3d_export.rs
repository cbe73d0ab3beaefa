//! Writes a Record3D "EXR + JPG" export of any number of frames at any
//! size, made from the Replica frames or the built-in synthetic scene: the
//! phone captures at their apps' own size that `docs/guide/large-captures.md`
//! measures loading and training on.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Parser;
use datasets::options::Resolution;
use datasets::replica::ReplicaOptions;
use datasets::writer::{Record3dExport, write_record3d};
use datasets::{LoaderOptions, SceneSource};

/// A Record3D export of a scene, at a phone's size.
#[derive(Debug, Parser)]
#[command(name = "record3d_export")]
struct Args {
    /// A Nice-SLAM Replica directory to take the views from (default: the
    /// built-in synthetic scene at its `ci` size).
    #[arg(long)]
    replica: Option<PathBuf>,
    /// Output directory (created; must not exist).
    #[arg(long)]
    out: PathBuf,
    /// Frames written; frame j shows view `j * views / frames`, so each
    /// view repeats over a run of consecutive frames, as in a video.
    #[arg(long, default_value_t = 345)]
    frames: usize,
    /// Colour image size, `WxH`.
    #[arg(long, default_value = "1920x1440")]
    size: Resolution,
    /// Blur all frames but one in each window of this many consecutive
    /// frames (the sharp one moves through the windows).
    #[arg(long)]
    blur_window: Option<usize>,
    /// Frames per second stated in the metadata.
    #[arg(long, default_value_t = 60.0)]
    fps: f64,
}

fn main() -> Result<()> {
    let args = Args::parse();
    if args.frames == 0 {
        bail!("--frames 0: must be at least 1");
    }
    if args.blur_window == Some(0) {
        bail!("--blur-window 0: must be at least 1");
    }
    if !(args.fps.is_finite() && args.fps > 0.0) {
        bail!("--fps {}: must be a positive number", args.fps);
    }
    if args.out.exists() {
        bail!("{}: already exists", args.out.display());
    }
    let source = match &args.replica {
        Some(dir) => SceneSource::Disk {
            loader: LoaderOptions::Replica(ReplicaOptions::default()),
            path: dir.clone(),
        },
        None => SceneSource::Synthetic {
            seed: 0,
            size: "ci".into(),
            pca: None,
        },
    };
    let scene = datasets::load_scene(&source).context("loading the views")?;
    let export = Record3dExport {
        frames: args.frames,
        size: (args.size.width, args.size.height),
        blur_window: args.blur_window,
        fps: args.fps,
        ..Record3dExport::default()
    };
    write_record3d(&scene, &args.out, &export)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "{}: {} frames at {}x{} from {} views of {}",
        args.out.display(),
        args.frames,
        args.size.width,
        args.size.height,
        scene.frames.len(),
        scene.name
    );
    Ok(())
}
