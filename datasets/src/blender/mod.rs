//! Blender / nerfstudio scenes: a `transforms.json` (or
//! `transforms_train.json`) and the files it names.
//!
//! Keys read, at the top level or per frame (a frame's own over the top
//! level's):
//! - `camera_angle_x`, or `fl_x`/`fl_y`/`cx`/`cy` (nerfstudio's principal
//!   point counts from the pixel corner, ours from the pixel centre:
//!   `cx_ours = cx - 0.5`), and `w`/`h`, the size they refer to (else the
//!   image's);
//! - `camera_model`: `PINHOLE`, `SIMPLE_PINHOLE`, `SIMPLE_RADIAL`,
//!   `RADIAL`, `OPENCV` or absent, all perspective with the distortion
//!   `k1`, `k2`, `k3`, `k4` (the `r^6`, `r^8` terms), `p1`, `p2` where given
//!   (missing ones are zero; as in nerfstudio, coefficients count whatever
//!   the perspective model's name). Fisheye, equirectangular and every other
//!   model are refused, naming the model.
//!
//! Per frame: `file_path` (extension optional), an OpenGL camera-to-world
//! `transform_matrix` (used as written), and optionally
//! - `depth_file_path`: z-depth, a 16-bit PNG or a float `.npy`, in metres
//!   after multiplying by the top-level `depth_unit_scale_factor` (default
//!   `1e-3`, millimetres, as nerfstudio); 0 = no target. It may have another
//!   resolution than the image but the same aspect, and is resampled by
//!   nearest pixel (never averaged across edges);
//! - `mask_path`: an image at the colour image's aspect, 0 = never a
//!   training target ([`Frame::mask`](crate::Frame::mask)), nonzero = keep.
//!
//! At the top level, optionally:
//! - `applied_transform` (3x4 or 4x4): nerfstudio's map from the capture's
//!   original (COLMAP) frame to the poses' frame; it must be a similarity
//!   and is recorded as the scene's [`WorldFrame`] `colmap`, so outputs can
//!   be mapped back with its inverse;
//! - `ply_file_path`: a point cloud in the poses' frame, the scene's
//!   [`points`](crate::Scene::points).
//!
//! Scene box: with a point cloud of at least
//! [`MIN_BOX_POINTS`] points, the robust box of the points (2nd to 98th
//! percentile on each axis), grown to hold what every camera sees at the
//! depth of its points (as for COLMAP, see [`crate::colmap::frame`]), plus
//! the margin: the points are the surfaces
//! the capture reconstructed, whether the cameras look in at an object,
//! forward at a scene or out from inside a room, and the percentiles drop
//! the stray points of structure from motion. The cameras are left out: in
//! an object capture they stand far outside the object and would spread the
//! field's resolution over empty space (rays from cameras outside the box
//! start where they enter it). Without points, the region the cameras look
//! at: these captures look inwards at an object, so the box is centred on
//! the point nearest (least squares) to all optical axes, with half-extent
//! the largest half-width any camera sees at that point's distance (for
//! lego: cameras 4 m away, 40 degree field of view, half-extent ~1.45 m,
//! i.e. about the object's known `[-1.5, 1.5]^3`), plus the margin.

mod keys;
mod scene_box;
mod targets;

use std::path::{Path, PathBuf};

use model::geometry::Camera;

use crate::detect::Format;
use crate::error::DatasetError;
use crate::imageio;
pub use crate::options::BlenderOptions;
use crate::options::LoaderOptions;
use crate::points::{PointCloud, read_ply};
use crate::poses::{checked_pose, checked_similarity};
use crate::scene::{Frame, Scene, SceneSource, WorldFrame};
use keys::{FrameEntry, Transforms, intrinsics, read_transforms};
pub use scene_box::{
    BOX_PERCENTILES, MIN_BOX_POINTS, focus_point, robust_points_box, seen_points_box,
    viewed_region_box,
};
pub use targets::DEFAULT_DEPTH_UNIT_SCALE;

/// The image file a `file_path` refers to (adding `.png`/`.jpg` when the
/// path has no extension or the file does not exist as written).
fn resolve_image(dir: &Path, file_path: &str) -> Option<PathBuf> {
    let p = dir.join(file_path);
    if p.is_file() {
        return Some(p);
    }
    ["png", "jpg", "jpeg", "PNG", "JPG"].iter().find_map(|ext| {
        let mut s = p.clone().into_os_string();
        s.push(format!(".{ext}"));
        let q = PathBuf::from(s);
        q.is_file().then_some(q)
    })
}

/// Locates the transforms file of `dir` (or `dir` itself when it is a file).
fn transforms_path(dir: &Path, options: &BlenderOptions) -> Result<PathBuf, DatasetError> {
    if dir.is_file() {
        return Ok(dir.to_path_buf());
    }
    let names = match &options.transforms {
        Some(n) => vec![n.clone()],
        None => vec!["transforms.json".into(), "transforms_train.json".into()],
    };
    names
        .iter()
        .map(|n| dir.join(n))
        .find(|p| p.is_file())
        .ok_or_else(|| DatasetError::invalid(dir.join(&names[0]), "transforms file not found"))
}

/// Loads a Blender / nerfstudio scene from a directory (or a transforms file).
pub fn load_blender(dir: &Path, options: &BlenderOptions) -> Result<Scene, DatasetError> {
    if options.downscale == 0 {
        return Err(DatasetError::invalid(dir, "downscale must be at least 1"));
    }
    // The size is the downscale's: images of one capture may differ in size.
    options
        .selection
        .check_without_resampling(dir, Format::Blender, "use downscale")?;
    let tpath = transforms_path(dir, options)?;
    let root = tpath.parent().unwrap_or(Path::new("."));
    let t = read_transforms(&tpath)?;
    let unit_scale = depth_unit_scale(&tpath, &t)?;
    // Numbered before the selection: errors and unnamed frames keep the
    // file's index.
    let frames =
        options
            .selection
            .select_sharpest(
                t.frames.iter().enumerate().collect(),
                |(_, f)| match resolve_image(root, &f.file_path) {
                    Some(p) => crate::sharpness::file_sharpness(&p),
                    None => Ok(0.0),
                },
            )?;
    if let Some(image) = frames
        .first()
        .and_then(|(_, f)| resolve_image(root, &f.file_path))
    {
        let (w, h) = imageio::dimensions(&image)?;
        let d = options.downscale;
        let depth = if frames.iter().any(|(_, f)| f.depth_file_path.is_some()) {
            4
        } else {
            0
        };
        crate::footprint::check_fits(
            dir,
            &options.selection,
            frames.len(),
            ((w / d).max(1), (h / d).max(1)),
            depth,
        )?;
    }
    let frames = frames
        .into_iter()
        .map(|entry| load_frame(root, &tpath, &t, entry, options, unit_scale))
        .collect::<Result<Vec<_>, _>>()?;
    let world = match &t.applied_transform {
        Some(m) => Some(WorldFrame {
            name: "colmap".into(),
            to_scene: checked_similarity(&tpath, "applied_transform", m)?,
            fitted_to: String::new(),
        }),
        None => None,
    };
    let points = match &t.ply_file_path {
        Some(p) => Some(read_points(&root.join(p), &tpath)?),
        None => None,
    };
    let cameras: Vec<Camera> = frames.iter().map(|f| f.camera).collect();
    let scene_box = match points
        .as_ref()
        .and_then(|p| seen_points_box(&p.positions, &cameras, options.box_margin))
    {
        Some(b) => b,
        None => viewed_region_box(&cameras, options.box_margin).ok_or_else(|| {
            DatasetError::invalid(&tpath, "cameras do not look at a common region")
        })?,
    };
    Ok(Scene {
        name: root
            .file_name()
            .map_or("blender".into(), |n| n.to_string_lossy().into_owned()),
        frames,
        features: None,
        scene_box,
        background: Some(options.background),
        points,
        classes: None,
        source: SceneSource::Disk {
            loader: LoaderOptions::Blender(options.clone()),
            path: dir.to_path_buf(),
        },
        world,
    })
}

/// The top-level `depth_unit_scale_factor` (default
/// [`DEFAULT_DEPTH_UNIT_SCALE`]), checked finite and positive.
fn depth_unit_scale(path: &Path, t: &Transforms) -> Result<f64, DatasetError> {
    let s = t
        .depth_unit_scale_factor
        .unwrap_or(DEFAULT_DEPTH_UNIT_SCALE);
    if !(s.is_finite() && s > 0.0) {
        return Err(DatasetError::invalid(
            path,
            format!("depth_unit_scale_factor {s} is not finite and positive"),
        ));
    }
    Ok(s)
}

/// The `ply_file_path` point cloud, named in errors with its transforms file.
fn read_points(path: &Path, json: &Path) -> Result<PointCloud, DatasetError> {
    if !path.is_file() {
        return Err(DatasetError::invalid(
            path,
            format!("missing point cloud (ply_file_path of {})", json.display()),
        ));
    }
    read_ply(path)
}

/// Frame `i` of the transforms file `t` at `tpath` (images under `root`).
fn load_frame(
    root: &Path,
    tpath: &Path,
    t: &Transforms,
    (i, f): (usize, &FrameEntry),
    options: &BlenderOptions,
    unit_scale: f64,
) -> Result<Frame, DatasetError> {
    let what = format!("frames[{i}] ({})", f.file_path);
    let img_path = resolve_image(root, &f.file_path).ok_or_else(|| {
        DatasetError::invalid(
            root.join(&f.file_path),
            format!("missing image for {what} of {}", tpath.display()),
        )
    })?;
    let pose = checked_pose(tpath, &what, f.transform_matrix, true)?;
    let (w, h) = imageio::dimensions(&img_path)?;
    let k = intrinsics(tpath, &what, &t.camera, &f.camera, (w, h))?;
    let target = (
        (w / options.downscale).max(1),
        (h / options.downscale).max(1),
    );
    let rgb = imageio::load_rgb(&img_path, Some(options.background), Some(target))?;
    let image = (img_path.as_path(), (w, h));
    let depth = match &f.depth_file_path {
        Some(p) => Some(targets::load_depth(
            &root.join(p),
            unit_scale,
            image,
            target,
            (&what, tpath),
        )?),
        None => None,
    };
    let mask = match &f.mask_path {
        Some(p) => Some(targets::load_mask(
            &root.join(p),
            image,
            target,
            (&what, tpath),
        )?),
        None => None,
    };
    let name = img_path
        .file_stem()
        .map_or(format!("frame{i:04}"), |s| s.to_string_lossy().into_owned());
    Ok(Frame {
        name,
        camera: Camera {
            intrinsics: k.scaled(target.0, target.1),
            pose,
        },
        rgb,
        depth_weight: if depth.is_some() { 1.0 } else { 0.0 },
        color_weight: 1.0,
        depth,
        labels: None,
        mask,
    })
}

/// The cameras of a transforms file alone, named after their images' file
/// stems, as [`load_blender`] reads them: OpenGL poses converted to OpenCV,
/// intrinsics (with distortion) from the file's keys (a frame's own keys
/// over the top-level ones) at the image size `w`/`h` the file gives, else
/// at the size of the frame's image (read from its header only).
pub fn read_cameras(path: &Path) -> Result<Vec<(String, Camera)>, DatasetError> {
    let root = path.parent().unwrap_or(Path::new("."));
    let t = read_transforms(path)?;
    t.frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let what = format!("frames[{i}] ({})", f.file_path);
            let pose = checked_pose(path, &what, f.transform_matrix, true)?;
            let given = (f.camera.w.or(t.camera.w), f.camera.h.or(t.camera.h));
            let size = match given {
                (Some(w), Some(h)) => (w.round() as u32, h.round() as u32),
                _ => {
                    let img = resolve_image(root, &f.file_path).ok_or_else(|| {
                        DatasetError::invalid(
                            path,
                            format!("{what}: no \"w\"/\"h\" and no image to take the size from"),
                        )
                    })?;
                    imageio::dimensions(&img)?
                }
            };
            let intrinsics = intrinsics(path, &what, &t.camera, &f.camera, size)?;
            let name = Path::new(&f.file_path)
                .file_stem()
                .map_or(format!("frame{i:04}"), |s| s.to_string_lossy().into_owned());
            Ok((name, Camera { intrinsics, pose }))
        })
        .collect()
}
