//! ScanNet scene exports, as ScanNet's SensReader writes them:
//!
//! ```text
//! <dir>/color/<i>.jpg                   colour (1296x968 for ScanNet)
//! <dir>/depth/<i>.png                   16-bit z-depth, millimetres (640x480); 0 = none
//! <dir>/pose/<i>.txt                    4x4 camera-to-world, OpenCV axes
//! <dir>/intrinsic/intrinsic_color.txt   4x4: fx [0][0], fy [1][1], cx [0][2], cy [1][2]
//! <dir>/intrinsic/intrinsic_depth.txt   the same for the depth camera
//! ```
//!
//! Frames are the colour images, in numerical order of `<i>`. ScanNet's
//! intrinsics follow OpenCV's pixel-centre convention and are used as they
//! are; they carry no image size, so each is checked against its images by
//! its principal point, which must lie within 10% of the image's width
//! (height) of the centre (a depth map of another size or aspect than the
//! intrinsics describe fails this).
//!
//! Depth is carried into the colour camera, not stretched: the two cameras
//! have different fields of view, and the export's depth-to-colour
//! extrinsics are the identity, so every depth pixel is back-projected with
//! the depth intrinsics and its footprint splatted into the colour camera
//! (at `resolution`, intrinsics scaled), keeping the nearest depth
//! ([`reproject_depth`]). The footprints tile the image, so nothing needs
//! filling; colour pixels outside the depth camera's view stay 0 (no
//! target).
//!
//! Poses with any infinite or NaN entry (ScanNet's mark of lost tracking)
//! are skipped and listed in the [`ScannetReport`]; [`load_scannet`] prints
//! one line about them to stderr. A finite pose that is not rigid is an
//! error. The scene box bounds the camera centres and back-projected depth
//! (every `box_pixel_step`-th pixel), plus the margin. ScanNet is metric
//! with z up: the scene stays in its frame (`world` is `None`).

mod frames;
mod reproject;

use std::path::{Path, PathBuf};

use model::geometry::{Intrinsics, Pose, Vec3};

use crate::error::DatasetError;
use crate::options::LoaderOptions;
pub use crate::options::ScannetOptions;
use crate::poses::{backproject, box_of, checked_pose};
use crate::scene::{Frame, Scene, SceneSource};
use frames::{ColourCamera, DepthCamera, load_frame, posed_images};
pub use reproject::reproject_depth;

/// Depth units per metre of ScanNet's depth PNGs.
pub const DEPTH_UNITS_PER_METRE: f64 = 1000.0;

/// Largest distance of the principal point from the image centre, as a
/// fraction of the image's side, for intrinsics to describe an image.
pub const PRINCIPAL_POINT_TOLERANCE: f64 = 0.1;

/// What [`load_scannet_with_report`] left out.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScannetReport {
    /// Pose files with infinite or NaN entries, whose frames were skipped.
    pub skipped: Vec<PathBuf>,
}

impl ScannetReport {
    /// One line about the skipped frames (up to five named, relative to
    /// `dir`), `None` when none was skipped.
    pub fn note(&self, dir: &Path) -> Option<String> {
        if self.skipped.is_empty() {
            return None;
        }
        let names: Vec<String> = self
            .skipped
            .iter()
            .take(5)
            .map(|p| p.strip_prefix(dir).unwrap_or(p).display().to_string())
            .collect();
        let more = if self.skipped.len() > 5 { ", ..." } else { "" };
        Some(format!(
            "scannet: skipped {} frames with invalid poses ({}{more})",
            self.skipped.len(),
            names.join(", ")
        ))
    }
}

/// Loads a ScanNet scene export, printing the [`ScannetReport`]'s note (if
/// any) to stderr.
pub fn load_scannet(dir: &Path, options: &ScannetOptions) -> Result<Scene, DatasetError> {
    let (scene, report) = load_scannet_with_report(dir, options)?;
    if let Some(note) = report.note(dir) {
        eprintln!("{note}");
    }
    Ok(scene)
}

/// Reads a whitespace-separated 4x4 matrix.
fn read_matrix(path: &Path) -> Result<[[f64; 4]; 4], DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    let vals: Vec<f64> = text
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| DatasetError::invalid(path, "not a list of numbers"))?;
    if vals.len() != 16 {
        return Err(DatasetError::invalid(
            path,
            format!("expected 16 numbers (a 4x4 matrix), found {}", vals.len()),
        ));
    }
    Ok(std::array::from_fn(|r| {
        std::array::from_fn(|c| vals[4 * r + c])
    }))
}

/// `fx`, `fy`, `cx`, `cy` of an intrinsic file, at the image size `size`.
pub fn read_intrinsics(path: &Path, size: (u32, u32)) -> Result<Intrinsics, DatasetError> {
    if !path.is_file() {
        return Err(DatasetError::invalid(path, "missing intrinsics file"));
    }
    let m = read_matrix(path)?;
    let (fx, fy, cx, cy) = (m[0][0], m[1][1], m[0][2], m[1][2]);
    if [fx, fy, cx, cy].iter().any(|v| !v.is_finite()) || fx <= 0.0 || fy <= 0.0 {
        return Err(DatasetError::invalid(
            path,
            "fx, fy must be positive and fx, fy, cx, cy finite",
        ));
    }
    Ok(Intrinsics {
        width: size.0,
        height: size.1,
        fx,
        fy,
        cx,
        cy,
        distortion: model::geometry::Distortion::NONE,
    })
}

/// Checks that intrinsics read from `kpath` describe `image` (of their
/// size): the principal point near the image centre.
fn check_principal_point(kpath: &Path, image: &Path, k: &Intrinsics) -> Result<(), DatasetError> {
    let off = |c: f64, side: u32| (c - (side as f64 - 1.0) / 2.0).abs() / side as f64;
    if off(k.cx, k.width) <= PRINCIPAL_POINT_TOLERANCE
        && off(k.cy, k.height) <= PRINCIPAL_POINT_TOLERANCE
    {
        return Ok(());
    }
    Err(DatasetError::invalid(
        image,
        format!(
            "image is {}x{} but the principal point ({}, {}) of {} is far from its centre: \
             the intrinsics describe an image of another size or aspect",
            k.width,
            k.height,
            k.cx,
            k.cy,
            kpath.display()
        ),
    ))
}

/// The pose of a `pose/<i>.txt`: `None` when it has an infinite or NaN
/// entry (lost tracking), an error when finite but not rigid.
pub fn read_pose(path: &Path) -> Result<Option<Pose>, DatasetError> {
    if !path.is_file() {
        return Err(DatasetError::invalid(path, "missing pose for this frame"));
    }
    let m = read_matrix(path)?;
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Ok(None);
    }
    checked_pose(path, "pose", m, false).map(Some)
}

/// The colour images of `color/`, sorted by their number `<i>`.
fn colour_files(dir: &Path) -> Result<Vec<(u64, PathBuf)>, DatasetError> {
    let colour = dir.join("color");
    let entries = std::fs::read_dir(&colour).map_err(|e| DatasetError::io(&colour, e))?;
    let mut found = Vec::new();
    for e in entries {
        let p = e.map_err(|e| DatasetError::io(&colour, e))?.path();
        let (Some(stem), Some(ext)) = (p.file_stem(), p.extension()) else {
            continue;
        };
        let ext = ext.to_string_lossy().to_lowercase();
        if matches!(ext.as_str(), "jpg" | "jpeg" | "png")
            && let Ok(i) = stem.to_string_lossy().parse::<u64>()
        {
            found.push((i, p));
        }
    }
    found.sort();
    if found.is_empty() {
        return Err(DatasetError::invalid(&colour, "no <i>.jpg colour images"));
    }
    if let Some(w) = found.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(DatasetError::invalid(
            &w[1].1,
            format!("frame {} has two colour images", w[0].0),
        ));
    }
    Ok(found)
}

/// Loads a ScanNet scene export with what was left out.
pub fn load_scannet_with_report(
    dir: &Path,
    options: &ScannetOptions,
) -> Result<(Scene, ScannetReport), DatasetError> {
    options.selection.check(dir)?;
    let colour = colour_files(dir)?;
    let camera = ColourCamera::read(dir, &colour[0].1, options)?;
    let (posed, report) = posed_images(dir, colour)?;
    let keep = options
        .selection
        .select_sharpest(posed, |p| crate::sharpness::file_sharpness(&p.path))?;
    crate::footprint::plan_size(dir, &options.selection, keep.len(), camera.size, 4, false)?;
    let mut depth_camera = DepthCamera::new(dir);
    let frames = keep
        .into_iter()
        .map(|image| load_frame(dir, image, &camera, &mut depth_camera))
        .collect::<Result<Vec<_>, _>>()?;
    let scene = assemble_scene(dir, frames, options)?;
    Ok((scene, report))
}

/// The points the scene box bounds: each frame's camera centre and its
/// depth back-projected at every `step`-th pixel.
fn box_points(frames: &[Frame], step: u32) -> Vec<Vec3> {
    let mut points = Vec::new();
    for frame in frames {
        points.push(frame.camera.pose.center());
        if let Some(depth) = &frame.depth {
            points.extend(backproject(&frame.camera, depth, step));
        }
    }
    points
}

/// The scene of the loaded frames, in a box around their cameras and depth.
fn assemble_scene(
    dir: &Path,
    frames: Vec<Frame>,
    options: &ScannetOptions,
) -> Result<Scene, DatasetError> {
    if frames.is_empty() {
        return Err(DatasetError::invalid(
            dir.join("pose"),
            "no frame with a valid pose",
        ));
    }
    let scene_box = box_of(
        dir,
        box_points(&frames, options.box_pixel_step),
        options.box_margin,
    )?;
    Ok(Scene {
        name: dir
            .file_name()
            .map_or("scannet".into(), |n| n.to_string_lossy().into_owned()),
        frames,
        features: None,
        scene_box,
        background: None,
        points: None,
        classes: None,
        source: SceneSource::Disk {
            loader: LoaderOptions::Scannet(options.clone()),
            path: dir.to_path_buf(),
        },
        world: None,
    })
}
