//! Pose validation and scene-box helpers shared by the loaders.

use std::path::Path;

use model::geometry::{Camera, Pose, RIGID_TOLERANCE, SceneBox, Similarity, Vec3};

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

/// A similarity (rotation, uniform scale, translation) from a row-major
/// 3x4 or 4x4 matrix `[[sR, t], [0 0 0 1]]`, with errors naming `path` and
/// `what` (e.g. "applied_transform"): non-finite values, another shape, a
/// last row other than `0 0 0 1`, a reflection or a singular matrix, or a
/// linear part that is not a uniform scale times a rotation.
pub fn checked_similarity(
    path: &Path,
    what: &str,
    rows: &[Vec<f64>],
) -> Result<Similarity, DatasetError> {
    let bad = |m: String| DatasetError::invalid(path, format!("{what}: {m}"));
    if !(rows.len() == 3 || rows.len() == 4) || rows.iter().any(|r| r.len() != 4) {
        return Err(bad("expected a 3x4 or 4x4 matrix".into()));
    }
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(bad("matrix contains NaN or infinite values".into()));
    }
    if let Some(last) = rows.get(3)
        && last
            .iter()
            .zip([0.0, 0.0, 0.0, 1.0])
            .any(|(a, b)| (a - b).abs() > RIGID_TOLERANCE)
    {
        return Err(bad(format!("last row is {last:?}, not [0, 0, 0, 1]")));
    }
    let a: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| rows[i][j]));
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    if det <= 0.0 {
        return Err(bad(format!(
            "not a similarity: the linear part has determinant {det} (a reflection or singular)"
        )));
    }
    let scale = det.cbrt();
    let rotation = a.map(|row| row.map(|v| v / scale));
    let error = Pose {
        rotation,
        translation: [0.0; 3],
    }
    .orthonormality_error();
    if error > RIGID_TOLERANCE {
        return Err(bad(format!(
            "not a similarity (rotation, uniform scale, translation): the linear part \
             divided by its scale {scale} is {error} from a rotation"
        )));
    }
    Ok(Similarity {
        rotation,
        scale,
        translation: [rows[0][3], rows[1][3], rows[2][3]],
    })
}

/// The smallest spread of the optical axes, per camera, that gives a
/// focus: the least eigenvalue of `sum (I - d d^T)` over the cameras'
/// axes `d` divided by their number (0 for parallel axes; axes on a cone
/// of half-angle `a` about one direction give `sin^2 a`, so this is about
/// 8 degrees).
pub const MIN_AXIS_SPREAD: f64 = 0.02;

/// The point nearest to every camera's optical axis in the least-squares
/// sense; `None` for fewer than two cameras, axes spread less than
/// [`MIN_AXIS_SPREAD`], or a point behind most of the cameras.
pub fn focus_point(poses: &[Pose]) -> Option<Vec3> {
    use nalgebra::{Matrix3, Vector3};
    if poses.len() < 2 {
        return None;
    }
    let axis =
        |p: &Pose| Vector3::new(p.rotation[0][2], p.rotation[1][2], p.rotation[2][2]).normalize();
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for p in poses {
        let d = axis(p);
        let m = Matrix3::identity() - d * d.transpose();
        a += m;
        b += m * Vector3::from(p.translation);
    }
    let spread = a.symmetric_eigenvalues().min() / poses.len() as f64;
    // A NaN spread (non-finite poses) has no focus either.
    if spread.is_nan() || spread < MIN_AXIS_SPREAD {
        return None;
    }
    let f = a.cholesky()?.solve(&b);
    let in_front = poses
        .iter()
        .filter(|p| (f - Vector3::from(p.translation)).dot(&axis(p)) > 0.0)
        .count();
    (2 * in_front > poses.len() && f.iter().all(|v| v.is_finite())).then(|| [f.x, f.y, f.z])
}
