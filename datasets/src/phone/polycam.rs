//! Polycam's raw-data export ("Raw Data" in the app's export menu):
//!
//! ```text
//! <dir>/keyframes/images/<stamp>.jpg              the colour image
//! <dir>/keyframes/cameras/<stamp>.json            fx, fy, cx, cy (at width x height), width,
//!                                                 height, t_00 ... t_23 (the 3x4 camera-to-world,
//!                                                 row-major, ARKit axes)
//! <dir>/keyframes/corrected_images/<stamp>.jpg    the same after Polycam's bundle adjustment,
//! <dir>/keyframes/corrected_cameras/<stamp>.json  preferred when both folders are there
//! <dir>/keyframes/depth/<stamp>.png               LiDAR depth, 16-bit millimetres (256x192)
//! <dir>/keyframes/confidence/<stamp>.png          its confidence, 8-bit levels 0, 1, 2 (or
//!                                                 scaled to 0, 127/128, 255)
//! ```
//!
//! `path` may be the export's directory or its `keyframes` directory (newer
//! exports unzip to it). Frames are the images, in the order of their
//! stamps (numeric when every stamp is an integer); each needs its camera
//! JSON, while depth and confidence maps are optional per frame. The pose
//! is passed as Polycam writes it (ARKit's y-up world: nerfstudio's row
//! permutation to a z-up world is done by [`super::assemble`]'s rotation).
//! `blur_score` (higher is sharper) chooses frames with `sharpest_of`. Not
//! read: the cameras' other keys, the mesh and its `mesh_info.json`, and
//! any other file of the export.

#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use model::geometry::{Distortion, Intrinsics};
use serde_json::{Map, Value};

use super::source::{ConfidenceSource, DepthSource, ImageSource};
use super::{Capture, CaptureFrame};
use crate::error::DatasetError;

/// Extensions of the colour images (lower-cased).
const IMAGE_EXTS: [&str; 3] = ["jpg", "jpeg", "png"];

/// The `keyframes` directory of the export at `path`.
fn keyframes(path: &Path) -> Result<PathBuf, DatasetError> {
    let nested = path.join("keyframes");
    if nested.is_dir() {
        return Ok(nested);
    }
    if path.join("images").is_dir() || path.join("corrected_images").is_dir() {
        return Ok(path.to_path_buf());
    }
    if !path.is_dir() {
        return Err(DatasetError::invalid(path, "not a directory"));
    }
    Err(DatasetError::invalid(
        path,
        "not a Polycam raw-data export: no keyframes/ (nor images/ in it); export with \
         \"Raw Data\"",
    ))
}

/// The images of `dir` as (stamp, path), sorted by stamp: numerically when
/// every stamp is an integer, else lexicographically.
fn images(dir: &Path) -> Result<Vec<(String, PathBuf)>, DatasetError> {
    let mut found = Vec::new();
    for e in std::fs::read_dir(dir).map_err(|e| DatasetError::io(dir, e))? {
        let p = e.map_err(|e| DatasetError::io(dir, e))?.path();
        let (Some(stem), Some(ext)) = (p.file_stem().and_then(|s| s.to_str()), p.extension())
        else {
            continue;
        };
        if IMAGE_EXTS.contains(&ext.to_string_lossy().to_lowercase().as_str()) && p.is_file() {
            found.push((stem.to_owned(), p.clone()));
        }
    }
    let numbers: Option<Vec<u128>> = found.iter().map(|(s, _)| s.parse().ok()).collect();
    match numbers {
        Some(n) => {
            let mut keyed: Vec<_> = n.into_iter().zip(found).collect();
            keyed.sort_by(|a, b| (a.0, &a.1.1).cmp(&(b.0, &b.1.1)));
            found = keyed.into_iter().map(|(_, f)| f).collect();
        }
        None => found.sort(),
    }
    if let Some(w) = found.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(DatasetError::invalid(
            &w[1].1,
            format!("stamp {} has two images ({})", w[1].0, w[0].1.display()),
        ));
    }
    Ok(found)
}

/// The finite number under `key` of the camera JSON `path`.
fn number(map: &Map<String, Value>, key: &str, path: &Path) -> Result<f64, DatasetError> {
    match map.get(key) {
        None => Err(DatasetError::invalid(
            path,
            format!("no `{key}` in the camera JSON"),
        )),
        Some(v) => v.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
            DatasetError::invalid(path, format!("`{key}` is {v}, not a finite number"))
        }),
    }
}

/// The positive whole number of pixels under `key`.
fn pixels(map: &Map<String, Value>, key: &str, path: &Path) -> Result<u32, DatasetError> {
    let x = number(map, key, path)?;
    if x >= 1.0 && x.fract() == 0.0 && x <= u32::MAX as f64 {
        Ok(x as u32)
    } else {
        Err(DatasetError::invalid(
            path,
            format!("`{key}` is {x}, not a positive whole number of pixels"),
        ))
    }
}

/// What a camera JSON holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Camera-to-world, row-major, last row [0, 0, 0, 1].
    pub pose: [[f64; 4]; 4],
    /// The intrinsics at its `width` x `height`.
    pub intrinsics: Intrinsics,
    /// `blur_score` (higher is sharper), when it has a finite one.
    pub blur_score: Option<f64>,
}

/// One camera JSON.
pub fn read_camera(path: &Path) -> Result<Camera, DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    let json: Value = serde_json::from_str(&text)
        .map_err(|e| DatasetError::invalid(path, format!("not a camera JSON: {e}")))?;
    let Some(map) = json.as_object() else {
        return Err(DatasetError::invalid(
            path,
            "not a JSON object: not a camera JSON",
        ));
    };
    let mut pose = [[0.0, 0.0, 0.0, 1.0]; 4];
    for (r, row) in pose.iter_mut().take(3).enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = number(map, &format!("t_{r}{c}"), path)?;
        }
    }
    let [fx, fy, cx, cy] = ["fx", "fy", "cx", "cy"].map(|k| number(map, k, path));
    let (fx, fy, cx, cy) = (fx?, fy?, cx?, cy?);
    if fx <= 0.0 || fy <= 0.0 {
        return Err(DatasetError::invalid(
            path,
            format!("focal lengths fx = {fx}, fy = {fy} are not positive"),
        ));
    }
    let intrinsics = Intrinsics {
        width: pixels(map, "width", path)?,
        height: pixels(map, "height", path)?,
        fx,
        fy,
        cx,
        cy,
        distortion: Distortion::NONE,
    };
    Ok(Camera {
        pose,
        intrinsics,
        blur_score: map
            .get("blur_score")
            .and_then(Value::as_f64)
            .filter(|v| v.is_finite()),
    })
}

/// Reads the frames of a Polycam raw-data export.
pub fn read_capture(path: &Path) -> Result<Capture, DatasetError> {
    let keyframes = keyframes(path)?;
    let mut capture = Capture::default();
    let (corrected_images, corrected_cameras) = (
        keyframes.join("corrected_images"),
        keyframes.join("corrected_cameras"),
    );
    let (image_dir, camera_dir) = if corrected_images.is_dir() && corrected_cameras.is_dir() {
        capture.notes.push(
            "using keyframes/corrected_images and corrected_cameras (Polycam's bundle-adjusted \
             keyframes)"
                .into(),
        );
        (corrected_images, corrected_cameras)
    } else {
        capture.notes.push(
            "no keyframes/corrected_images and corrected_cameras: the raw keyframes and their \
             ARKit poses (not bundle-adjusted) are used"
                .into(),
        );
        (keyframes.join("images"), keyframes.join("cameras"))
    };
    let found = images(&image_dir)?;
    if found.is_empty() {
        return Err(DatasetError::invalid(
            &image_dir,
            "no images (<stamp>.jpg) in this folder",
        ));
    }
    for (stamp, image) in found {
        let camera = camera_dir.join(format!("{stamp}.json"));
        if !camera.is_file() {
            return Err(DatasetError::invalid(
                &image,
                format!(
                    "no camera {} with this image's pose and intrinsics",
                    camera.display()
                ),
            ));
        }
        let Camera {
            pose,
            intrinsics,
            blur_score,
        } = read_camera(&camera)?;
        let depth = keyframes.join("depth").join(format!("{stamp}.png"));
        let confidence = keyframes.join("confidence").join(format!("{stamp}.png"));
        capture.frames.push(CaptureFrame {
            blur_score,
            name: format!("frame_{stamp}"),
            image: ImageSource::File(image),
            pose,
            pose_file: camera,
            intrinsics,
            depth: depth
                .is_file()
                .then_some(DepthSource::PngMillimetres(depth)),
            confidence: confidence
                .is_file()
                .then_some(ConfidenceSource::PngScaled(confidence)),
        });
    }
    capture.note_depth_coverage("keyframes/depth");
    Ok(capture)
}
