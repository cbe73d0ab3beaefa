//! The 3D Scanner App's "All Data" export (the capture route of the
//! OpenNeRF paper's own scenes):
//!
//! ```text
//! <dir>/frame_NNNNN.json    cameraPoseARFrame (16 numbers: the 4x4 camera-to-world,
//!                           row-major, ARKit axes), intrinsics (9 numbers: the 3x3
//!                           matrix, row-major, at the image's size)
//! <dir>/frame_NNNNN.jpg     the colour image (saved for keyframes only)
//! <dir>/depth_NNNNN.png     LiDAR depth, 16-bit millimetres (256x192), where saved
//! <dir>/conf_NNNNN.png      its confidence, 8-bit levels 0, 1, 2
//! <dir>/textured_output.obj the mesh (+ .mtl and its texture image)
//! ```
//!
//! The app writes a pose for every ARKit frame but an image only for its
//! keyframes: frames are the `frame_NNNNN.json` with a `frame_NNNNN.jpg`,
//! in the order of `NNNNN`; poses without an image are counted in a note.
//! Other keys of the JSON (`projectionMatrix`, `motionQuality`, `time`,
//! exposure, ...) are not read.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use model::geometry::{Distortion, Intrinsics};

use super::source::{ConfidenceSource, DepthSource, ImageSource};
use super::{Capture, CaptureFrame};
use crate::error::DatasetError;

/// The mesh file of the export.
pub const MESH_FILE: &str = "textured_output.obj";

/// What one `frame_NNNNN.json` holds that is read.
#[derive(serde::Deserialize)]
struct FrameJson {
    #[serde(rename = "cameraPoseARFrame")]
    camera_pose_ar_frame: Option<Vec<f64>>,
    intrinsics: Option<Vec<f64>>,
}

/// The files of `dir` named `<prefix><number>.<ext>` (ext lower-cased,
/// one of `exts`), by number.
fn numbered(
    dir: &Path,
    prefix: &str,
    exts: &[&str],
) -> Result<BTreeMap<u64, PathBuf>, DatasetError> {
    let mut found = BTreeMap::new();
    let entries = std::fs::read_dir(dir).map_err(|e| DatasetError::io(dir, e))?;
    for e in entries {
        let p = e.map_err(|e| DatasetError::io(dir, e))?.path();
        let (Some(stem), Some(ext)) = (p.file_stem(), p.extension()) else {
            continue;
        };
        let ext = ext.to_string_lossy().to_lowercase();
        if exts.contains(&ext.as_str())
            && let Some(num) = stem.to_string_lossy().strip_prefix(prefix)
            && let Ok(i) = num.parse::<u64>()
            && let Some(other) = found.insert(i, p.clone())
        {
            return Err(DatasetError::invalid(
                &p,
                format!("frame {i} has two files ({})", other.display()),
            ));
        }
    }
    Ok(found)
}

/// The `side x side` matrix under `key` of `path`, row-major and finite.
fn matrix(
    path: &Path,
    key: &str,
    v: Option<Vec<f64>>,
    side: usize,
) -> Result<Vec<f64>, DatasetError> {
    let v =
        v.ok_or_else(|| DatasetError::invalid(path, format!("no `{key}` in the frame's JSON")))?;
    if v.len() != side * side {
        return Err(DatasetError::invalid(
            path,
            format!(
                "`{key}` has {} numbers, expected {} (a {side}x{side} matrix, row-major)",
                v.len(),
                side * side
            ),
        ));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(DatasetError::invalid(
            path,
            format!("`{key}` holds NaN or infinite values"),
        ));
    }
    Ok(v)
}

/// Intrinsics from the row-major 3x3 `k` of an image of `size`.
pub(crate) fn intrinsics_3x3(
    path: &Path,
    k: &[f64],
    size: (u32, u32),
) -> Result<Intrinsics, DatasetError> {
    let (fx, fy, cx, cy) = (k[0], k[4], k[2], k[5]);
    let off_diagonal = [k[1], k[3], k[6], k[7]];
    if fx <= 0.0
        || fy <= 0.0
        || off_diagonal.iter().any(|v| v.abs() > 1e-6)
        || (k[8] - 1.0).abs() > 1e-6
    {
        return Err(DatasetError::invalid(
            path,
            format!(
                "`intrinsics` {k:?} is not a pinhole matrix [fx, 0, cx, 0, fy, cy, 0, 0, 1] \
                 with positive focal lengths"
            ),
        ));
    }
    Ok(Intrinsics {
        width: size.0,
        height: size.1,
        fx,
        fy,
        cx,
        cy,
        distortion: Distortion::NONE,
    })
}

/// Reads one frame's JSON: its pose and its intrinsics at `size`.
fn read_frame_json(
    path: &Path,
    size: (u32, u32),
) -> Result<([[f64; 4]; 4], Intrinsics), DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    let json: FrameJson = serde_json::from_str(&text)
        .map_err(|e| DatasetError::invalid(path, format!("not a frame JSON: {e}")))?;
    let pose = matrix(path, "cameraPoseARFrame", json.camera_pose_ar_frame, 4)?;
    let k = matrix(path, "intrinsics", json.intrinsics, 3)?;
    let pose = std::array::from_fn(|r| std::array::from_fn(|c| pose[4 * r + c]));
    Ok((pose, intrinsics_3x3(path, &k, size)?))
}

/// Reads the frames of a 3D Scanner App export.
pub fn read_capture(dir: &Path) -> Result<Capture, DatasetError> {
    if !dir.is_dir() {
        return Err(DatasetError::invalid(dir, "not a directory"));
    }
    let jsons = numbered(dir, "frame_", &["json"])?;
    let images = numbered(dir, "frame_", &["jpg", "jpeg", "png"])?;
    let depths = numbered(dir, "depth_", &["png"])?;
    let confs = numbered(dir, "conf_", &["png"])?;
    let empty = std::fs::read_dir(dir)
        .map_err(|e| DatasetError::io(dir, e))?
        .next()
        .is_none();
    if empty {
        return Err(DatasetError::invalid(dir, "the export directory is empty"));
    }
    if images.is_empty() {
        return Err(DatasetError::invalid(
            dir,
            "no frame_NNNNN.jpg images: not a 3D Scanner App export (export with \"All Data\")",
        ));
    }
    let mut capture = Capture::default();
    for (i, image) in &images {
        let Some(json) = jsons.get(i) else {
            return Err(DatasetError::invalid(
                image,
                format!("no frame_{i:05}.json with this image's pose and intrinsics"),
            ));
        };
        let size = crate::imageio::dimensions(image)?;
        let (pose, intrinsics) = read_frame_json(json, size)?;
        capture.frames.push(CaptureFrame {
            blur_score: None,
            name: format!("frame_{i:05}"),
            image: ImageSource::File(image.clone()),
            pose,
            pose_file: json.clone(),
            intrinsics,
            depth: depths.get(i).cloned().map(DepthSource::PngMillimetres),
            confidence: confs.get(i).cloned().map(ConfidenceSource::Png),
        });
    }
    let without = jsons.keys().filter(|i| !images.contains_key(i)).count();
    if without > 0 {
        capture.notes.push(format!(
            "{without} poses without an image skipped (the app saves images for keyframes only)"
        ));
    }
    capture.note_depth_coverage("the export");
    let mesh = dir.join(MESH_FILE);
    if mesh.is_file() {
        capture.mesh = Some(mesh);
    } else {
        capture.notes.push(format!(
            "no {MESH_FILE}: the point cloud is made from the depth maps"
        ));
    }
    Ok(capture)
}
