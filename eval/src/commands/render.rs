//! `eval render`: colour, depth and feature images of a run from scene
//! frames, camera files or a smooth camera path.

use std::path::{Path, PathBuf};

use super::common::{Context, evenly, select_cameras};
use crate::checks::{at_least_one, invalid, max_views};

use crate::cameras::{NamedCamera, camera_path, resized};
use datasets::imageio::save_rgb8;
use field_ops::OpsError;
use field_ops::backend::BackendArgs;
use field_ops::frame::{FrameArgs, OutputFrame};
use field_ops::images::save_view_pngs;
use field_ops::render::{ViewSettings, render_view};
use model::Termination;

/// Arguments of `render` and the camera part of `query`.
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// Run directory.
    #[arg(long)]
    pub run: PathBuf,
    /// Cameras: heldout (default), train, all, or a transforms.json / traj.txt.
    #[arg(long, default_value = "heldout")]
    pub cameras: String,
    /// cam_params.json for a traj.txt (default: next to it or its parent).
    #[arg(long)]
    pub cam_params: Option<PathBuf>,
    /// Output width (height follows the aspect ratio unless given).
    #[arg(long)]
    pub width: Option<u32>,
    /// Output height.
    #[arg(long)]
    pub height: Option<u32>,
    /// Render a smooth path of this many cameras through the selected poses instead.
    #[arg(long)]
    pub camera_path: Option<usize>,
    /// Use at most this many cameras (evenly spaced).
    #[arg(long)]
    pub max_views: Option<usize>,
    /// Rays per forward pass.
    #[arg(long, default_value_t = 4096)]
    pub chunk: usize,
    /// A ray ends once its transmittance falls below this (what lies behind
    /// can add at most this much); 0 evaluates every sample.
    #[arg(long, default_value_t = 1e-4)]
    pub termination: f32,
    /// Output directory (default: `renders/eval` in the run directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Compute backend and device.
    #[command(flatten)]
    pub compute: BackendArgs,
    /// Frame of the written camera poses (`cameras.json`) and point clouds.
    #[command(flatten)]
    pub frame: FrameArgs,
}

impl RenderArgs {
    /// How views are rendered: `--chunk`, `--termination`, and features
    /// when `features` is set.
    pub fn settings(&self, background: Option<[f32; 3]>, features: bool) -> ViewSettings<'static> {
        ViewSettings::new(background, self.chunk)
            .with_features(features)
            .with_termination(Termination {
                transmittance: self.termination,
                ..Termination::default()
            })
    }
}

/// The cameras `render` (and `query`) render at: `--cameras` by name or
/// file, resized by `--width`/`--height`, or a path through them.
pub fn render_cameras(args: &RenderArgs, ctx: &Context) -> Result<Vec<NamedCamera>, OpsError> {
    let (cams, _) = select_cameras(
        &args.cameras,
        &ctx.run,
        ctx.scene.as_ref(),
        args.cam_params.as_deref(),
    )?;
    let cams = evenly(&cams, args.max_views);
    let cams = match args.camera_path {
        Some(n) => camera_path(&cams, n)?,
        None => cams,
    };
    let Some(first) = cams.first() else {
        return Err(OpsError::Invalid(format!(
            "no cameras selected by {:?}",
            args.cameras
        )));
    };
    let k = first.camera.intrinsics;
    Ok(match (args.width, args.height) {
        (None, None) => cams,
        (w, h) => {
            let w = w.unwrap_or_else(|| {
                (h.unwrap_or(k.height) as f64 * k.width as f64 / k.height as f64).round() as u32
            });
            let h =
                h.unwrap_or_else(|| (w as f64 * k.height as f64 / k.width as f64).round() as u32);
            resized(&cams, w.max(1), h.max(1))
        }
    })
}

/// Runs `render`: colour, depth and feature-PCA PNGs per camera, and
/// `cameras.json` with their poses. Returns the written files.
pub fn render_command(args: &RenderArgs) -> Result<Vec<PathBuf>, OpsError> {
    check(args)?;
    let device = args.compute.device();
    let ctx = Context::load(&args.run, &device)?;
    let frame = args.frame.resolve(&ctx.run.meta)?;
    let cams = render_cameras(args, &ctx)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| ctx.run.dir.renders().join("eval"));
    let mut written = vec![write_cameras(&out, &cams, &frame, &args.frame.frame)?];
    let mut animation = Vec::new();
    let bar = field_ops::progress::progress(cams.len(), "rendering");
    let mut errors = Vec::new();
    let (start, mut rays, mut samples) = (std::time::Instant::now(), 0usize, 0usize);
    for c in &cams {
        let m = &ctx.run.meta;
        let settings = args.settings(m.background, m.feature_dim.is_some());
        let v = render_view(&ctx.run.model, &c.camera, &m.scene_box, &settings)
            .expect("never cancelled without an observer");
        rays += v.pixels();
        samples += v.samples_evaluated;
        written.extend(save_view_pngs(&v, &out, &c.name)?);
        // A scene frame rendered at its own size is shown next to its
        // ground truth and the error between them.
        let truth = ctx
            .scene
            .as_ref()
            .and_then(|s| s.frames.iter().find(|f| f.name == c.name));
        if let Some(mse) = truth.and_then(|f| crate::figures::rgb_mse(&f.rgb, &v)) {
            errors.push(mse);
            field_ops::progress::note(
                &bar,
                format!("{}: PSNR {:.3} dB", c.name, field_ops::metrics::psnr(mse)),
            );
        }
        if let Some((w, h, px)) = truth.and_then(|f| crate::figures::comparison(&f.rgb, &v)) {
            let path = out.join(format!("{}_compare.png", c.name));
            save_rgb8(&path, w, h, &px)?;
            written.push(path);
        }
        if args.camera_path.is_some() {
            animation.push(
                v.rgb
                    .iter()
                    .map(|&x| field_ops::colormap::to_u8(x))
                    .collect(),
            );
        }
        bar.inc(1);
        field_ops::progress::note(&bar, format!("rendered {}", c.name));
    }
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "rendered {} view(s), {rays} rays in {secs:.1} s ({:.0} rays/s), {:.1} samples a ray \
         evaluated of {}",
        cams.len(),
        rays as f64 / secs.max(1e-9),
        samples as f64 / rays.max(1) as f64,
        ctx.run.model.samples_per_ray()
    );
    if !errors.is_empty() {
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        println!(
            "PSNR against the {} scene frame(s): {:.3} dB (of the mean squared error, every pixel)",
            errors.len(),
            field_ops::metrics::psnr(mean)
        );
    }
    if let Some(first) = cams.first().filter(|_| !animation.is_empty()) {
        let k = first.camera.intrinsics;
        let path = out.join("path.gif");
        crate::figures::write_gif(&path, k.width, k.height, &animation, 10)?;
        written.push(path);
    }
    Ok(written)
}

/// One rendered camera as `cameras.json` lists it.
#[derive(serde::Serialize)]
struct WrittenCamera<'a> {
    name: &'a str,
    intrinsics: model::geometry::Intrinsics,
    /// Row-major 4x4, OpenCV axes.
    camera_to_world: [[f64; 4]; 4],
}

/// Writes `cameras.json` into `out`: the cameras rendered, their poses in
/// `frame` (named `frame_name`), so that renders can be placed in the
/// capture's own coordinates.
pub fn write_cameras(
    out: &Path,
    cams: &[NamedCamera],
    frame: &OutputFrame,
    frame_name: &str,
) -> Result<PathBuf, OpsError> {
    std::fs::create_dir_all(out).map_err(|e| OpsError::io(out, e))?;
    let list: Vec<WrittenCamera<'_>> = cams
        .iter()
        .map(|c| WrittenCamera {
            name: &c.name,
            intrinsics: c.camera.intrinsics,
            camera_to_world: frame.camera(&c.camera).pose.to_matrix(),
        })
        .collect();
    let path = out.join("cameras.json");
    field_ops::json::write_json(
        &path,
        &serde_json::json!({ "frame": frame_name, "cameras": list }),
    )?;
    Ok(path)
}

/// Checks `render` (and the camera part of `query`).
pub fn check(a: &RenderArgs) -> Result<(), OpsError> {
    for (flag, value) in [("width", a.width), ("height", a.height)] {
        if value == Some(0) {
            return Err(invalid(format!(
                "--{flag} 0: an image needs at least 1 pixel"
            )));
        }
    }
    max_views(a.max_views)?;
    at_least_one(
        "camera-path",
        a.camera_path,
        " (the number of cameras along the path)",
    )?;
    at_least_one("chunk", Some(a.chunk), "")?;
    if !(0.0..1.0).contains(&a.termination) {
        return Err(invalid(format!(
            "--termination {}: a transmittance in [0, 1) (0 evaluates every sample)",
            a.termination
        )));
    }
    a.compute.check().map_err(OpsError::Invalid)
}
