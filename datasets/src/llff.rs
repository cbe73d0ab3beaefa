//! LLFF scenes: `poses_bounds.npy` (`N x 17`: a 3x5 `[R | t | hwf]` per view,
//! row-major, with rotation columns in LLFF's `[down, right, backwards]`
//! order, then near and far bounds) and downsampled images in `images_F`
//! (factor F from the folder name).
//!
//! The principal point is taken at the image centre (`(W - 1) / 2` with pixel
//! centres at integers), and intrinsics from `hwf` are rescaled to the images
//! actually found. The scene box holds the camera centres and the corners
//! and centre of every view's frustum at its near and far bounds.

use std::path::{Path, PathBuf};

use model::geometry::{Camera, Intrinsics, Vec3};

use crate::detect::Format;
use crate::error::DatasetError;
use crate::imageio;
use crate::npy::NpyInfo;
pub use crate::options::LlffOptions;
use crate::options::LoaderOptions;
use crate::poses::{box_of, checked_pose};
use crate::scene::{Frame, Scene, SceneSource};

/// One row of `poses_bounds.npy`, converted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LlffView {
    /// Full-resolution intrinsics.
    pub intrinsics: Intrinsics,
    /// Camera-to-world pose (OpenCV).
    pub pose: model::geometry::Pose,
    /// Near bound (metres along the view axis).
    pub near: f64,
    /// Far bound.
    pub far: f64,
}

/// Reads `poses_bounds.npy`, converting every pose to OpenCV axes.
pub fn read_poses_bounds(path: &Path) -> Result<Vec<LlffView>, DatasetError> {
    let info = NpyInfo::open(path)?;
    info.expect_rank(2, "views x 17")?;
    if info.shape[1] != 17 {
        return Err(DatasetError::invalid(
            path,
            format!(
                "expected 17 columns (3x5 pose + 2 bounds), found {}",
                info.shape[1]
            ),
        ));
    }
    let data = info.read_f64_range(0, info.len())?;
    let mut views = Vec::new();
    for (i, row) in data.chunks_exact(17).enumerate() {
        let what = format!("row {i}");
        if row.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::invalid(
                path,
                format!("{what}: NaN or infinite value"),
            ));
        }
        let p = |r: usize, c: usize| row[5 * r + c];
        // LLFF columns: 0 = down, 1 = right, 2 = backwards. OpenCV: x = right,
        // y = down, z = forward.
        let m = std::array::from_fn(|r| {
            if r == 3 {
                [0.0, 0.0, 0.0, 1.0]
            } else {
                [p(r, 1), p(r, 0), -p(r, 2), p(r, 3)]
            }
        });
        let pose = checked_pose(path, &what, m, false)?;
        let (h, w, f) = (p(0, 4), p(1, 4), p(2, 4));
        let (near, far) = (row[15], row[16]);
        if !(h >= 1.0 && w >= 1.0 && f > 0.0) {
            return Err(DatasetError::invalid(
                path,
                format!("{what}: bad image size / focal {h} x {w}, {f}"),
            ));
        }
        if !(near > 0.0 && far > near) {
            return Err(DatasetError::invalid(
                path,
                format!("{what}: bad bounds near {near}, far {far}"),
            ));
        }
        let (w, h) = (w.round() as u32, h.round() as u32);
        let intrinsics = Intrinsics {
            width: w,
            height: h,
            fx: f,
            fy: f,
            cx: (w as f64 - 1.0) / 2.0,
            cy: (h as f64 - 1.0) / 2.0,
            distortion: model::geometry::Distortion::NONE,
        };
        views.push(LlffView {
            intrinsics,
            pose,
            near,
            far,
        });
    }
    Ok(views)
}

/// Downsampling factor of an `images_F` folder name (1 for `images`).
fn factor_of(name: &str) -> Option<u32> {
    if name == "images" {
        return Some(1);
    }
    name.strip_prefix("images_")?
        .parse()
        .ok()
        .filter(|&f| f > 0)
}

/// The image folder to use.
fn image_dir(dir: &Path, options: &LlffOptions) -> Result<(PathBuf, u32), DatasetError> {
    if let Some(name) = &options.images {
        let f = factor_of(name).ok_or_else(|| {
            DatasetError::invalid(dir.join(name), "folder name is not images or images_F")
        })?;
        return Ok((dir.join(name), f));
    }
    if dir.join("images_8").is_dir() {
        return Ok((dir.join("images_8"), 8));
    }
    let mut best: Option<(PathBuf, u32)> = None;
    for e in std::fs::read_dir(dir)
        .map_err(|e| DatasetError::io(dir, e))?
        .flatten()
    {
        let name = e.file_name().to_string_lossy().into_owned();
        if let Some(f) = factor_of(&name).filter(|_| e.path().is_dir())
            && best.as_ref().is_none_or(|b| f > b.1)
        {
            best = Some((e.path(), f));
        }
    }
    best.ok_or_else(|| DatasetError::invalid(dir, "no images or images_F folder"))
}

/// Sorted image files of a folder.
fn list_images(dir: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| DatasetError::io(dir, e))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension().is_some_and(|x| {
                matches!(
                    x.to_string_lossy().to_lowercase().as_str(),
                    "png" | "jpg" | "jpeg"
                )
            })
        })
        .collect();
    files.sort();
    Ok(files)
}

/// Loads an LLFF scene from `dir`.
pub fn load_llff(dir: &Path, options: &LlffOptions) -> Result<Scene, DatasetError> {
    options.selection.check_without_resampling(
        dir,
        Format::Llff,
        "pick the downsampled folder with images",
    )?;
    let pb = dir.join("poses_bounds.npy");
    let views = read_poses_bounds(&pb)?;
    let (img_dir, factor) = image_dir(dir, options)?;
    let images = list_images(&img_dir)?;
    if images.len() != views.len() {
        return Err(DatasetError::invalid(
            &pb,
            format!(
                "{} poses but {} has {} images",
                views.len(),
                img_dir.display(),
                images.len()
            ),
        ));
    }
    let mut frames = Vec::new();
    let mut pts: Vec<Vec3> = Vec::new();
    let kept = options
        .selection
        .select_sharpest(views.iter().zip(&images).collect(), |(_, p)| {
            crate::sharpness::file_sharpness(p)
        })?;
    if let Some((_, first)) = kept.first() {
        let size = imageio::dimensions(first)?;
        crate::footprint::check_fits(dir, &options.selection, kept.len(), size, 0)?;
    }
    for (view, path) in kept {
        let (w, h) = imageio::dimensions(path)?;
        let k = &view.intrinsics;
        let (ew, eh) = (
            k.width as f64 / factor as f64,
            k.height as f64 / factor as f64,
        );
        if (w as f64 - ew).abs() > 1.0 || (h as f64 - eh).abs() > 1.0 {
            return Err(DatasetError::invalid(
                path,
                format!("image is {w}x{h}, expected about {ew:.0}x{eh:.0} (full size / {factor})"),
            ));
        }
        let camera = Camera {
            intrinsics: k.scaled(w, h),
            pose: view.pose,
        };
        pts.push(camera.pose.center());
        let (xw, yh) = ((w - 1) as f64, (h - 1) as f64);
        for (u, v) in [
            (0.0, 0.0),
            (xw, 0.0),
            (0.0, yh),
            (xw, yh),
            (xw / 2.0, yh / 2.0),
        ] {
            let r = camera.ray(u, v);
            for t in [view.near, view.far] {
                pts.push(model::geometry::add_scaled(r.origin, t, r.direction));
            }
        }
        let rgb = imageio::load_rgb(path, None, None)?;
        frames.push(Frame {
            name: path
                .file_stem()
                .map_or("view".into(), |s| s.to_string_lossy().into_owned()),
            camera,
            rgb,
            depth: None,
            depth_weight: 0.0,
            color_weight: 1.0,
            labels: None,
            mask: None,
        });
    }
    let scene_box = box_of(&pb, pts, options.box_margin)?;
    Ok(Scene {
        name: dir
            .file_name()
            .map_or("llff".into(), |n| n.to_string_lossy().into_owned()),
        frames,
        features: None,
        scene_box,
        background: None,
        points: None,
        classes: None,
        source: SceneSource::Disk {
            loader: LoaderOptions::Llff(options.clone()),
            path: dir.to_path_buf(),
        },
        world: None,
    })
}
