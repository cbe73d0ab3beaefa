//! Nice-SLAM Replica scenes: `results/frameNNNNNN.jpg` (or `.png`),
//! `results/depthNNNNNN.png` (16-bit, metres = value / scale), `traj.txt`
//! (one row-major 4x4 camera-to-world per line, OpenCV axes) and
//! `cam_params.json` (`{"camera": {w, h, fx, fy, cx, cy, scale}}`).

use std::path::{Path, PathBuf};

use model::geometry::{Camera, Intrinsics, Pose};

use crate::error::DatasetError;
use crate::options::LoaderOptions;
pub use crate::options::ReplicaOptions;
use crate::poses::{backproject, box_of, checked_pose};
use crate::scene::{Frame, Scene, SceneSource};
use crate::{DepthImage, imageio};

/// `cam_params.json` contents.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
pub struct CamParams {
    /// Image width.
    pub w: u32,
    /// Image height.
    pub h: u32,
    /// Focal length x, pixels.
    pub fx: f64,
    /// Focal length y, pixels.
    pub fy: f64,
    /// Principal point x (pixel centres at integers).
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
    /// Depth units per metre.
    pub scale: f64,
}

#[derive(serde::Deserialize)]
struct CamFile {
    camera: CamParams,
}

/// Reads and validates `cam_params.json`.
pub fn read_cam_params(path: &Path) -> Result<CamParams, DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    let c = serde_json::from_str::<CamFile>(&text)
        .map_err(|e| DatasetError::invalid(path, format!("bad camera parameters: {e}")))?
        .camera;
    let vals = [c.fx, c.fy, c.cx, c.cy, c.scale];
    if vals.iter().any(|v| !v.is_finite()) || c.fx <= 0.0 || c.fy <= 0.0 || c.scale <= 0.0 {
        return Err(DatasetError::invalid(
            path,
            "fx, fy and scale must be positive and all values finite",
        ));
    }
    if c.w == 0 || c.h == 0 {
        return Err(DatasetError::invalid(path, "image size is zero"));
    }
    Ok(c)
}

/// Reads `traj.txt`: one pose per non-empty line (16 numbers, row-major).
pub fn read_trajectory(path: &Path) -> Result<Vec<Pose>, DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    let mut poses = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let what = format!("line {}", i + 1);
        let vals: Vec<f64> = line
            .split_whitespace()
            .map(|w| w.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| DatasetError::invalid(path, format!("{what}: not a list of numbers")))?;
        if vals.len() != 16 {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "{what}: expected 16 numbers (a 4x4 matrix), found {}",
                    vals.len()
                ),
            ));
        }
        let m = std::array::from_fn(|r| std::array::from_fn(|c| vals[4 * r + c]));
        poses.push(checked_pose(path, &what, m, false)?);
    }
    Ok(poses)
}

/// Indices `0..n` of the colour frames in `results/`, erroring on gaps.
fn frame_files(dir: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let results = dir.join("results");
    let entries = std::fs::read_dir(&results).map_err(|e| DatasetError::io(&results, e))?;
    let mut found: Vec<(usize, PathBuf)> = Vec::new();
    for e in entries {
        let p = e.map_err(|e| DatasetError::io(&results, e))?.path();
        let (Some(stem), Some(ext)) = (p.file_stem(), p.extension()) else {
            continue;
        };
        let (stem, ext) = (stem.to_string_lossy(), ext.to_string_lossy().to_lowercase());
        if let Some(num) = stem.strip_prefix("frame")
            && matches!(ext.as_str(), "jpg" | "jpeg" | "png")
            && let Ok(i) = num.parse::<usize>()
        {
            found.push((i, p));
        }
    }
    found.sort();
    if found.is_empty() {
        return Err(DatasetError::invalid(
            &results,
            "no frameNNNNNN.jpg/.png images",
        ));
    }
    for (k, (i, p)) in found.iter().enumerate() {
        if *i != k {
            let missing = if *i > k { k } else { *i };
            return Err(DatasetError::invalid(
                results.join(format!("frame{missing:06}.jpg")),
                format!("missing frame (or duplicate before {})", p.display()),
            ));
        }
    }
    Ok(found.into_iter().map(|(_, p)| p).collect())
}

/// Loads a Nice-SLAM Replica scene from `dir`, with its feature maps
/// ([`crate::load_disk`]).
pub fn load_replica(dir: &Path, options: &ReplicaOptions) -> Result<Scene, DatasetError> {
    crate::load_disk(dir, &LoaderOptions::Replica(options.clone()))
}

/// [`load_replica`] without the feature maps, which
/// [`crate::load_disk`] attaches.
pub(crate) fn load_without_features(
    dir: &Path,
    options: &ReplicaOptions,
) -> Result<Scene, DatasetError> {
    options.selection.check(dir)?;
    let cam = read_cam_params(&dir.join("cam_params.json"))?;
    let traj_path = dir.join("traj.txt");
    let poses = read_trajectory(&traj_path)?;
    let images = frame_files(dir)?;
    if poses.len() != images.len() {
        return Err(DatasetError::invalid(
            &traj_path,
            format!(
                "{} poses but {} has {} frames",
                poses.len(),
                dir.join("results").display(),
                images.len()
            ),
        ));
    }
    let base = Intrinsics {
        width: cam.w,
        height: cam.h,
        fx: cam.fx,
        fy: cam.fy,
        cx: cam.cx,
        cy: cam.cy,
        distortion: model::geometry::Distortion::NONE,
    };
    let keep = options
        .selection
        .select_sharpest((0..images.len()).collect(), |&i| {
            crate::sharpness::file_sharpness(&images[i])
        })?;
    let ((tw, th), _) = crate::footprint::plan_size(
        dir,
        &options.selection,
        keep.len(),
        (cam.w, cam.h),
        4,
        false,
    )?;
    let intrinsics = base.scaled(tw, th);
    let loaded = crate::progress::par_map(&keep, "loading frames", |&i| {
        let frame = load_frame(dir, i, &images[i], &cam, (tw, th), intrinsics, poses[i])?;
        let mut points = vec![frame.camera.pose.center()];
        if let Some(depth) = &frame.depth {
            points.extend(backproject(&frame.camera, depth, options.box_pixel_step));
        }
        Ok((frame, points))
    })?;
    let mut frames = Vec::with_capacity(loaded.len());
    let mut box_points = Vec::new();
    for (frame, points) in loaded {
        frames.push(frame);
        box_points.extend(points);
    }
    let scene_box = box_of(dir, box_points, options.box_margin)?;
    Ok(Scene {
        name: dir
            .file_name()
            .map_or("replica".into(), |n| n.to_string_lossy().into_owned()),
        frames,
        features: None,
        scene_box,
        background: None,
        points: None,
        classes: None,
        source: SceneSource::Disk {
            loader: LoaderOptions::Replica(options.clone()),
            path: dir.to_path_buf(),
        },
        world: None,
    })
}

/// Frame `i` (colour `img_path`) loaded at `(tw, th)`.
fn load_frame(
    dir: &Path,
    i: usize,
    img_path: &Path,
    cam: &CamParams,
    (tw, th): (u32, u32),
    intrinsics: Intrinsics,
    pose: Pose,
) -> Result<Frame, DatasetError> {
    let size = imageio::dimensions(img_path)?;
    if size != (cam.w, cam.h) {
        return Err(DatasetError::invalid(
            img_path,
            format!(
                "image is {}x{} but cam_params.json says {}x{}",
                size.0, size.1, cam.w, cam.h
            ),
        ));
    }
    let rgb = imageio::load_rgb(img_path, None, Some((tw, th)))?;
    let depth_path = dir.join("results").join(format!("depth{i:06}.png"));
    let depth = load_depth(&depth_path, cam, (tw, th))?;
    Ok(Frame::captured(
        format!("frame{i:06}"),
        Camera { intrinsics, pose },
        rgb,
        Some(depth),
    ))
}

/// Loads one depth map, checking its size against the camera parameters.
fn load_depth(path: &Path, cam: &CamParams, size: (u32, u32)) -> Result<DepthImage, DatasetError> {
    if !path.is_file() {
        return Err(DatasetError::invalid(
            path,
            "missing depth image for this frame",
        ));
    }
    let dims = imageio::dimensions(path)?;
    if dims != (cam.w, cam.h) {
        return Err(DatasetError::invalid(
            path,
            format!(
                "depth is {}x{} but cam_params.json says {}x{}",
                dims.0, dims.1, cam.w, cam.h
            ),
        ));
    }
    imageio::load_depth16(path, cam.scale, Some(size))
}
