//! The keys of a `transforms.json` and the intrinsics (with distortion)
//! they give.

use std::path::Path;

use model::geometry::{Distortion, Intrinsics};

use crate::error::DatasetError;

/// nerfstudio's perspective camera models: all read with the OpenCV
/// radial-tangential polynomial (missing coefficients are zero), as
/// nerfstudio reads them.
pub(super) const PERSPECTIVE_MODELS: [&str; 5] = [
    "PINHOLE",
    "SIMPLE_PINHOLE",
    "SIMPLE_RADIAL",
    "RADIAL",
    "OPENCV",
];

/// Camera keys that may appear at the top level or per frame.
#[derive(Debug, Clone, Default, serde::Deserialize)]
pub(super) struct CameraKeys {
    pub camera_angle_x: Option<f64>,
    pub fl_x: Option<f64>,
    pub fl_y: Option<f64>,
    pub cx: Option<f64>,
    pub cy: Option<f64>,
    pub w: Option<f64>,
    pub h: Option<f64>,
    pub camera_model: Option<String>,
    pub k1: Option<f64>,
    pub k2: Option<f64>,
    pub k3: Option<f64>,
    pub k4: Option<f64>,
    pub p1: Option<f64>,
    pub p2: Option<f64>,
}

/// One entry of `frames[]`.
#[derive(Debug, serde::Deserialize)]
pub(super) struct FrameEntry {
    pub file_path: String,
    pub transform_matrix: [[f64; 4]; 4],
    pub depth_file_path: Option<String>,
    pub mask_path: Option<String>,
    #[serde(flatten)]
    pub camera: CameraKeys,
}

/// The whole file.
#[derive(Debug, serde::Deserialize)]
pub(super) struct Transforms {
    #[serde(flatten)]
    pub camera: CameraKeys,
    pub frames: Vec<FrameEntry>,
    pub depth_unit_scale_factor: Option<f64>,
    pub applied_transform: Option<Vec<Vec<f64>>>,
    pub ply_file_path: Option<String>,
}

/// Reads and parses a transforms file.
pub(super) fn read_transforms(path: &Path) -> Result<Transforms, DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    let t: Transforms = serde_json::from_str(&text)
        .map_err(|e| DatasetError::invalid(path, format!("bad transforms file: {e}")))?;
    if t.frames.is_empty() {
        return Err(DatasetError::invalid(path, "no frames"));
    }
    Ok(t)
}

/// The lens distortion of a frame (its keys over the top-level ones),
/// refusing camera models that are not perspective.
pub(super) fn distortion(
    path: &Path,
    what: &str,
    top: &CameraKeys,
    frame: &CameraKeys,
) -> Result<Distortion, DatasetError> {
    let model = frame.camera_model.as_ref().or(top.camera_model.as_ref());
    if let Some(m) = model
        && !PERSPECTIVE_MODELS.contains(&m.as_str())
    {
        return Err(DatasetError::invalid(
            path,
            format!(
                "{what}: camera_model \"{m}\" is not supported (only the perspective models {} are)",
                PERSPECTIVE_MODELS.join(", ")
            ),
        ));
    }
    let pick = |a: Option<f64>, b: Option<f64>| a.or(b).unwrap_or(0.0);
    let d = Distortion {
        k1: pick(frame.k1, top.k1),
        k2: pick(frame.k2, top.k2),
        k3: pick(frame.k3, top.k3),
        k4: pick(frame.k4, top.k4),
        p1: pick(frame.p1, top.p1),
        p2: pick(frame.p2, top.p2),
    };
    if !d.is_finite() {
        return Err(DatasetError::invalid(
            path,
            format!("{what}: distortion coefficients are not finite"),
        ));
    }
    Ok(d)
}

/// Intrinsics for an image of `(w, h)` pixels from the keys (frame keys
/// override top-level ones), with the frame's distortion.
pub(super) fn intrinsics(
    path: &Path,
    what: &str,
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
    let distortion = distortion(path, what, top, frame)?;
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
                distortion,
            }
        }
        (None, Some(a)) => {
            if !(a > 0.0 && a < std::f64::consts::PI) {
                return Err(DatasetError::invalid(
                    path,
                    format!("camera_angle_x {a} is not in (0, pi)"),
                ));
            }
            Intrinsics {
                distortion,
                ..Intrinsics::from_fov_x(jw, jh, a)
            }
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
