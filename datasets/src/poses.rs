//! Pose validation and scene-box helpers shared by the loaders.

use std::path::Path;

use model::geometry::{Camera, Pose, SceneBox, Vec3};

use crate::error::DatasetError;
use crate::scene::DepthImage;

/// A camera-to-world pose from a 4x4 matrix (`opengl`: OpenGL axes), with
/// errors naming `path` and `what` (e.g. "line 3").
pub fn checked_pose(
    path: &Path,
    what: &str,
    m: [[f64; 4]; 4],
    opengl: bool,
) -> Result<Pose, DatasetError> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(DatasetError::invalid(
            path,
            format!("{what}: pose contains NaN or infinite values"),
        ));
    }
    let pose = if opengl {
        Pose::from_opengl(m)
    } else {
        Pose::from_matrix(m)
    };
    pose.map_err(|e| DatasetError::invalid(path, format!("{what}: {e}")))
}

/// World points of every `step`-th pixel (in both axes) with valid depth.
pub fn backproject(camera: &Camera, depth: &DepthImage, step: u32) -> Vec<Vec3> {
    let mut pts = Vec::new();
    for y in (0..depth.height).step_by(step.max(1) as usize) {
        for x in (0..depth.width).step_by(step.max(1) as usize) {
            let d = depth.get(x, y) as f64;
            if d > 0.0 && d.is_finite() {
                let r = camera.ray(x as f64, y as f64);
                pts.push([
                    r.origin[0] + d * r.direction[0],
                    r.origin[1] + d * r.direction[1],
                    r.origin[2] + d * r.direction[2],
                ]);
            }
        }
    }
    pts
}

/// The box of `points` grown by `margin` (fraction of the largest extent);
/// errors naming `path` when there is no finite point.
pub fn box_of(path: &Path, points: Vec<Vec3>, margin: f64) -> Result<SceneBox, DatasetError> {
    SceneBox::from_points(points, margin).ok_or_else(|| {
        DatasetError::invalid(path, "no finite camera or depth point to bound the scene")
    })
}
