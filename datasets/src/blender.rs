//! Blender / nerfstudio scenes: `transforms.json` with `camera_angle_x` or
//! `fl_x`/`fl_y`/`cx`/`cy` (nerfstudio's principal point counts from the
//! pixel corner, ours from the pixel centre: `cx_ours = cx - 0.5`), `w`/`h`,
//! and `frames[]` with `file_path` (extension optional) and an OpenGL
//! camera-to-world `transform_matrix`.
//!
//! Scene box: these captures look inwards at an object, so the box is the
//! region the cameras look at rather than the box of the cameras: centred on
//! the point nearest (least squares) to all optical axes, with half-extent
//! the largest half-width any camera sees at that point's distance (for lego:
//! cameras 4 m away, 40 degree field of view, half-extent ~1.45 m, i.e. about
//! the object's known `[-1.5, 1.5]^3`), plus the margin. Rays from cameras
//! outside it start where they enter the box.

use std::path::{Path, PathBuf};

use model::geometry::{Camera, Intrinsics, SceneBox, Vec3};

use crate::error::DatasetError;
use crate::imageio;
pub use crate::options::BlenderOptions;
use crate::options::LoaderOptions;
use crate::poses::checked_pose;
use crate::scene::{Frame, Scene, SceneSource};

/// Camera keys that may appear at the top level or per frame.
#[derive(Debug, Clone, Default, serde::Deserialize)]
struct CameraKeys {
    camera_angle_x: Option<f64>,
    fl_x: Option<f64>,
    fl_y: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    w: Option<f64>,
    h: Option<f64>,
}

#[derive(Debug, serde::Deserialize)]
struct FrameEntry {
    file_path: String,
    transform_matrix: [[f64; 4]; 4],
    #[serde(flatten)]
    camera: CameraKeys,
}

#[derive(Debug, serde::Deserialize)]
struct Transforms {
    #[serde(flatten)]
    camera: CameraKeys,
    frames: Vec<FrameEntry>,
}

/// Intrinsics for an image of `(w, h)` pixels from the keys (frame keys
/// override top-level ones).
fn intrinsics(
    path: &Path,
    top: &CameraKeys,
    frame: &CameraKeys,
    (w, h): (u32, u32),
) -> Result<Intrinsics, DatasetError> {
    let pick = |a: Option<f64>, b: Option<f64>| a.or(b);
    let fl_x = pick(frame.fl_x, top.fl_x);
    let angle = pick(frame.camera_angle_x, top.camera_angle_x);
    // The size the focal lengths refer to (the json's, else the image's).
    let jw = pick(frame.w, top.w).map_or(w, |v| v.round() as u32);
    let jh = pick(frame.h, top.h).map_or(h, |v| v.round() as u32);
    let k = match (fl_x, angle) {
        (Some(fx), _) => {
            let fy = pick(frame.fl_y, top.fl_y).unwrap_or(fx);
            Intrinsics {
                width: jw,
                height: jh,
                fx,
                fy,
                cx: pick(frame.cx, top.cx).map_or((jw as f64 - 1.0) / 2.0, |c| c - 0.5),
                cy: pick(frame.cy, top.cy).map_or((jh as f64 - 1.0) / 2.0, |c| c - 0.5),
                distortion: model::geometry::Distortion::NONE,
            }
        }
        (None, Some(a)) => {
            if !(a > 0.0 && a < std::f64::consts::PI) {
                return Err(DatasetError::invalid(
                    path,
                    format!("camera_angle_x {a} is not in (0, pi)"),
                ));
            }
            Intrinsics::from_fov_x(jw, jh, a)
        }
        (None, None) => {
            return Err(DatasetError::invalid(
                path,
                "neither camera_angle_x nor fl_x is given",
            ));
        }
    };
    let vals = [k.fx, k.fy, k.cx, k.cy];
    if vals.iter().any(|v| !v.is_finite()) || k.fx <= 0.0 || k.fy <= 0.0 || jw == 0 || jh == 0 {
        return Err(DatasetError::invalid(
            path,
            "intrinsics are not finite and positive",
        ));
    }
    Ok(if (jw, jh) != (w, h) {
        k.scaled(w, h)
    } else {
        k
    })
}

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
    let tpath = transforms_path(dir, options)?;
    let root = tpath.parent().unwrap_or(Path::new("."));
    let text = std::fs::read_to_string(&tpath).map_err(|e| DatasetError::io(&tpath, e))?;
    let t: Transforms = serde_json::from_str(&text)
        .map_err(|e| DatasetError::invalid(&tpath, format!("bad transforms file: {e}")))?;
    if t.frames.is_empty() {
        return Err(DatasetError::invalid(&tpath, "no frames"));
    }
    let mut frames = Vec::new();
    for (i, f) in t
        .frames
        .iter()
        .take(options.max_frames.unwrap_or(usize::MAX))
        .enumerate()
    {
        let what = format!("frames[{i}] ({})", f.file_path);
        let img_path = resolve_image(root, &f.file_path).ok_or_else(|| {
            DatasetError::invalid(
                root.join(&f.file_path),
                format!("missing image for {what} of {}", tpath.display()),
            )
        })?;
        let pose = checked_pose(&tpath, &what, f.transform_matrix, true)?;
        let (w, h) = imageio::dimensions(&img_path)?;
        let k = intrinsics(&tpath, &t.camera, &f.camera, (w, h))?;
        let target = (
            (w / options.downscale).max(1),
            (h / options.downscale).max(1),
        );
        let rgb = imageio::load_rgb(&img_path, Some(options.background), Some(target))?;
        let name = img_path
            .file_stem()
            .map_or(format!("frame{i:04}"), |s| s.to_string_lossy().into_owned());
        frames.push(Frame {
            name,
            camera: Camera {
                intrinsics: k.scaled(target.0, target.1),
                pose,
            },
            rgb,
            depth: None,
            depth_weight: 0.0,
            labels: None,
            mask: None,
        });
    }
    let cameras: Vec<Camera> = frames.iter().map(|f| f.camera).collect();
    let scene_box = viewed_region_box(&cameras, options.box_margin)
        .ok_or_else(|| DatasetError::invalid(&tpath, "cameras do not look at a common region"))?;
    Ok(Scene {
        name: root
            .file_name()
            .map_or("blender".into(), |n| n.to_string_lossy().into_owned()),
        frames,
        features: None,
        scene_box,
        background: Some(options.background),
        points: None,
        classes: None,
        source: SceneSource::Disk {
            loader: LoaderOptions::Blender(options.clone()),
            path: dir.to_path_buf(),
        },
        world: None,
    })
}

/// The cameras of a transforms file alone, named after their images' file
/// stems, as [`load_blender`] reads them: OpenGL poses converted to OpenCV,
/// intrinsics from the file's keys (a frame's own keys over the top-level
/// ones) at the image size `w`/`h` the file gives, else at the size of the
/// frame's image (read from its header only).
pub fn read_cameras(path: &Path) -> Result<Vec<(String, Camera)>, DatasetError> {
    let root = path.parent().unwrap_or(Path::new("."));
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    let t: Transforms = serde_json::from_str(&text)
        .map_err(|e| DatasetError::invalid(path, format!("bad transforms file: {e}")))?;
    if t.frames.is_empty() {
        return Err(DatasetError::invalid(path, "no frames"));
    }
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
            let intrinsics = intrinsics(path, &t.camera, &f.camera, size)?;
            let name = Path::new(&f.file_path)
                .file_stem()
                .map_or(format!("frame{i:04}"), |s| s.to_string_lossy().into_owned());
            Ok((name, Camera { intrinsics, pose }))
        })
        .collect()
}

/// The point minimising the summed squared distance to all optical axes.
/// `None` when the axes are (nearly) parallel.
pub fn focus_point(cameras: &[Camera]) -> Option<Vec3> {
    // sum (I - d d^T) p = sum (I - d d^T) c
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for cam in cameras {
        let d = cam.pose.forward();
        let n = model::geometry::norm(d);
        let d = [d[0] / n, d[1] / n, d[2] / n];
        let c = cam.pose.center();
        for r in 0..3 {
            for col in 0..3 {
                let m = if r == col { 1.0 } else { 0.0 } - d[r] * d[col];
                a[r][col] += m;
                b[r] += m * c[col];
            }
        }
    }
    solve3(a, b)
}

/// Solves the 3x3 system by Cramer's rule; `None` when near-singular.
fn solve3(a: [[f64; 3]; 3], b: Vec3) -> Option<Vec3> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    let scale = a.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    if d.abs() <= 1e-9 * scale.powi(3) || !d.is_finite() {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut m = a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        *xk = det(m) / d;
    }
    Some(x)
}

/// Cube centred on [`focus_point`] with half-extent the largest half-width
/// (horizontal or vertical) any camera sees at its distance to that point,
/// grown by `margin`. `None` without a well-defined focus point.
pub fn viewed_region_box(cameras: &[Camera], margin: f64) -> Option<SceneBox> {
    let p = focus_point(cameras)?;
    let mut half: f64 = 0.0;
    for cam in cameras {
        let k = &cam.intrinsics;
        let dist = model::geometry::norm(model::geometry::sub(p, cam.pose.center()));
        let tan = (0.5 * k.width as f64 / k.fx).max(0.5 * k.height as f64 / k.fy);
        half = half.max(dist * tan);
    }
    if !(half > 0.0 && half.is_finite()) {
        return None;
    }
    let h = half * (1.0 + margin);
    Some(SceneBox {
        min: [p[0] - h, p[1] - h, p[2] - h],
        max: [p[0] + h, p[1] + h, p[2] + h],
    })
}
