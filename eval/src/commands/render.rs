//! `eval render`: colour, depth and feature images of a run from scene
//! frames, camera files or a smooth camera path.

use std::path::{Path, PathBuf};

use super::common::{Context, evenly, select_cameras};
use super::photographs::Photographs;
use crate::checks::{at_least_one, invalid, max_views};

use crate::cameras::{NamedCamera, camera_path, resized};
use field_ops::OpsError;
use field_ops::backend::BackendArgs;
use field_ops::depth_image::{DepthQuantity, DepthScale};
use field_ops::frame::{FrameArgs, OutputFrame};
use field_ops::images::ViewImages;
use field_ops::render::{ViewSettings, render_view};
use field_ops::strips::PHOTOGRAPH_FILTER;
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

/// Runs `render`: colour, depth (with its scale as JSON), opacity and
/// feature-PCA PNGs per camera, `cameras.json` with their poses, and for
/// scene frames a strip beside the photograph, the contact sheet and
/// `render_metrics.json` (PSNR, SSIM). Returns the written files.
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
    let mut photographs = Photographs::default();
    let depth = DepthQuantity::of(&ctx.run.model);
    let (start, mut rays, mut samples) = (std::time::Instant::now(), 0usize, 0usize);
    for c in &cams {
        let m = &ctx.run.meta;
        let settings = args.settings(m.background, m.feature_dim.is_some());
        let v = render_view(&ctx.run.model, &c.camera, &m.scene_box, &settings)
            .expect("never cancelled without an observer");
        rays += v.pixels();
        samples += v.samples_evaluated;
        let images = ViewImages::of(&v, depth);
        written.extend(images.save(&out, &c.name)?);
        // A scene frame is shown next to its photograph (resized to the
        // render) and scored against it.
        let truth = ctx
            .scene
            .as_ref()
            .and_then(|s| s.frames.iter().find(|f| f.name == c.name));
        if let Some(f) = truth {
            let score = photographs.add(&c.name, &f.rgb, &v, &images.depth, &out, &mut written)?;
            let ssim = score.ssim.map(|s| format!(", SSIM {s:.4}"));
            field_ops::progress::note(
                &bar,
                format!(
                    "{}: PSNR {:.3} dB{}",
                    c.name,
                    score.psnr,
                    ssim.unwrap_or_default()
                ),
            );
        }
        if args.camera_path.is_some() {
            animation.push((images.rgb, v.depth, v.acc));
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
    if let Some((psnr, ssim)) = photographs.means() {
        let resized = photographs
            .scores
            .iter()
            .any(|s| s.photograph_resized_from.is_some());
        println!(
            "PSNR against the {} scene frame(s): {psnr:.3} dB (of the mean squared error, every \
             pixel){}{}",
            photographs.scores.len(),
            ssim.map(|s| format!(", SSIM {s:.4} (mean over views)"))
                .unwrap_or_default(),
            if resized {
                format!("; photographs resized to the renders: {PHOTOGRAPH_FILTER}")
            } else {
                String::new()
            }
        );
        written.extend(photographs.finish(&out, &contact_sheet_name(&args.cameras))?);
    }
    if let Some(first) = cams.first().filter(|_| !animation.is_empty()) {
        let k = first.camera.intrinsics;
        written.extend(write_path_gifs(&out, k.width, k.height, &animation, depth)?);
    }
    Ok(written)
}

/// Writes `path.gif` (colour) and `path_depth.gif` (depth on one scale over
/// the whole path, so that its colours do not flicker from frame to frame;
/// the scale in `path_depth.json`) of the camera path's `frames` (colour
/// bytes, depth and opacity of each). Returns the written paths.
fn write_path_gifs(
    out: &Path,
    width: u32,
    height: u32,
    frames: &[(Vec<u8>, Vec<f32>, Vec<f32>)],
    quantity: DepthQuantity,
) -> Result<Vec<PathBuf>, OpsError> {
    let colour: Vec<Vec<u8>> = frames.iter().map(|f| f.0.clone()).collect();
    let path = out.join("path.gif");
    crate::figures::write_gif(&path, width, height, &colour, 10)?;
    let all_depth: Vec<f32> = frames.iter().flat_map(|f| f.1.iter().copied()).collect();
    let all_acc: Vec<f32> = frames.iter().flat_map(|f| f.2.iter().copied()).collect();
    let scale = DepthScale::of(&all_depth, &all_acc, quantity);
    let depth: Vec<Vec<u8>> = frames.iter().map(|f| scale.colours(&f.1, &f.2)).collect();
    let depth_gif = out.join("path_depth.gif");
    crate::figures::write_gif(&depth_gif, width, height, &depth, 10)?;
    let json = out.join("path_depth.json");
    field_ops::json::write_json(&json, &scale)?;
    Ok(vec![path, depth_gif, json])
}

/// The contact sheet's file name for the cameras selected by `--cameras`:
/// `heldout.png`, `train.png` or `all.png` (`strips.png` for a camera file).
fn contact_sheet_name(cameras: &str) -> String {
    match cameras {
        "heldout" | "train" | "all" => format!("{cameras}.png"),
        _ => "strips.png".to_string(),
    }
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
