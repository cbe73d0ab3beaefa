//! The scene frame of a COLMAP reconstruction, whose own world frame is
//! arbitrary (any orientation, origin and scale): up is +z, the centre is
//! the centre of the sparse points' robust box, and that box's largest
//! side is [`SCENE_SIZE`] units.
//!
//! * Up: the normalised mean of the cameras' up vectors (`-y` of each
//!   OpenCV camera), rotated onto +z by the minimal rotation.
//! * Robust box: per axis (after that rotation) the 2nd and 98th
//!   percentiles of the sparse points, or of the camera centres when there
//!   are fewer than [`MIN_POINTS`] points.
//! * Scale: `SCENE_SIZE / largest side` of the robust box (the sampler's
//!   near plane and query radii are tuned for scenes of a few units).

use model::geometry::{Pose, SceneBox, Similarity, Vec3, cross, dot, norm};

/// Largest side of the robust box in the scene frame.
pub const SCENE_SIZE: f64 = 3.0;

/// Fewer sparse points than this: the robust box is the camera centres'.
pub const MIN_POINTS: usize = 20;

/// Lower and upper percentiles of the robust box.
pub const PERCENTILES: (f64, f64) = (0.02, 0.98);

/// The normalised mean of the cameras' up vectors (`-R[:, 1]`), `None`
/// when they cancel out (or there is no camera).
pub fn mean_up(poses: &[Pose]) -> Option<Vec3> {
    let mut sum = [0.0; 3];
    for p in poses {
        for (i, s) in sum.iter_mut().enumerate() {
            *s -= p.rotation[i][1];
        }
    }
    let n = norm(sum);
    (n > 1e-9 * poses.len() as f64 && n.is_finite()).then(|| sum.map(|v| v / n))
}

/// The minimal rotation (row-major) taking the unit vector `up` onto +z;
/// a half turn about x when `up` is -z.
pub fn rotation_onto_z(up: Vec3) -> [[f64; 3]; 3] {
    let z = [0.0, 0.0, 1.0];
    let c = dot(up, z);
    if c < -1.0 + 1e-12 {
        return [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    }
    // Rodrigues: R = I + [v]x + [v]x^2 / (1 + c), v = up x z.
    let v = cross(up, z);
    let k = [[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]];
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let k2: f64 = (0..3).map(|m| k[i][m] * k[m][j]).sum();
            let id = if i == j { 1.0 } else { 0.0 };
            id + k[i][j] + k2 / (1.0 + c)
        })
    })
}

/// The `q`-quantile of sorted values, interpolating linearly.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let x = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (i, f) = (x.floor() as usize, x - x.floor());
    let j = (i + 1).min(sorted.len() - 1);
    sorted[i] + f * (sorted[j] - sorted[i])
}

/// Per-axis [`PERCENTILES`] of `points`: `(min, max)` corners; `None`
/// without points.
pub fn robust_box(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    if points.is_empty() {
        return None;
    }
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for k in 0..3 {
        let mut v: Vec<f64> = points.iter().map(|p| p[k]).collect();
        v.sort_by(f64::total_cmp);
        lo[k] = percentile(&v, PERCENTILES.0);
        hi[k] = percentile(&v, PERCENTILES.1);
    }
    Some((lo, hi))
}

/// The points the robust box is taken over: the sparse points, or the
/// camera centres when there are fewer than [`MIN_POINTS`].
pub fn box_basis(points: &[Vec3], poses: &[Pose]) -> Vec<Vec3> {
    if points.len() >= MIN_POINTS {
        points.to_vec()
    } else {
        poses.iter().map(Pose::center).collect()
    }
}

/// The map from COLMAP's world frame to the scene frame (see the module
/// documentation), or why there is none (the points and cameras span no
/// extent).
pub fn to_scene(poses: &[Pose], points: &[Vec3]) -> Result<Similarity, String> {
    let rotation = mean_up(poses).map_or(Similarity::IDENTITY.rotation, rotation_onto_z);
    let rotate = Similarity {
        rotation,
        ..Similarity::IDENTITY
    };
    let basis: Vec<Vec3> = box_basis(points, poses)
        .into_iter()
        .map(|p| rotate.apply_point(p))
        .collect();
    let (lo, hi) =
        robust_box(&basis).ok_or("no sparse point and no camera to centre the scene on")?;
    let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    if !(side > 0.0 && side.is_finite()) {
        return Err(format!(
            "cannot scale the scene: the robust box of its {} points has no extent",
            basis.len()
        ));
    }
    let scale = SCENE_SIZE / side;
    Ok(Similarity {
        rotation,
        scale,
        translation: std::array::from_fn(|k| -scale * 0.5 * (lo[k] + hi[k])),
    })
}

/// The scene box: the robust box of the (already mapped) `points`, or of
/// the camera centres when there are too few points, grown by `margin` of
/// its largest extent.
pub fn scene_box(points: &[Vec3], poses: &[Pose], margin: f64) -> Option<SceneBox> {
    let (lo, hi) = robust_box(&box_basis(points, poses))?;
    SceneBox::from_points([lo, hi], margin)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(r: &[[f64; 3]; 3], v: Vec3) -> Vec3 {
        std::array::from_fn(|i| (0..3).map(|j| r[i][j] * v[j]).sum())
    }

    #[test]
    fn up_vectors_rotate_onto_z() {
        for up in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.3, -0.5, -0.8],
        ] {
            let n = norm(up);
            let up = up.map(|v| v / n);
            let r = rotation_onto_z(up);
            let z = apply(&r, up);
            assert!((z[2] - 1.0).abs() < 1e-12, "{up:?} -> {z:?}");
            let pose = Pose {
                rotation: r,
                translation: [0.0; 3],
            };
            assert!(pose.orthonormality_error() < 1e-12);
            let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
                - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
                + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
            assert!((det - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn percentiles_interpolate() {
        let v: Vec<f64> = (0..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 0.02), 2.0);
        assert_eq!(percentile(&[1.0, 3.0], 0.5), 2.0);
        assert_eq!(percentile(&[5.0], 0.98), 5.0);
    }

    #[test]
    fn the_robust_box_is_centred_with_side_three() {
        // Points on a 10 x 4 x 2 block around (5, 5, 5); one far outlier.
        let mut pts: Vec<Vec3> = (0..1000)
            .map(|i| {
                let f = |k: u64| crate::numeric::hash01(3 * i + k);
                [
                    5.0 + 10.0 * (f(0) - 0.5),
                    5.0 + 4.0 * (f(1) - 0.5),
                    5.0 + 2.0 * (f(2) - 0.5),
                ]
            })
            .collect();
        pts.push([1e6, 0.0, 0.0]);
        let poses = [Pose::identity()]; // up = -y
        let s = to_scene(&poses, &pts).expect("extent");
        let mapped: Vec<Vec3> = pts.iter().map(|&p| s.apply_point(p)).collect();
        let (lo, hi) = robust_box(&mapped).expect("points");
        let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        assert!((side - 3.0).abs() < 1e-9, "{side}");
        assert!((0..3).all(|k| (lo[k] + hi[k]).abs() < 1e-9));
        let up = s.apply_vector([0.0, -1.0, 0.0]);
        assert!((up[2] / s.scale - 1.0).abs() < 1e-12);
        let b = scene_box(&mapped, &poses, 0.05).expect("box");
        assert!(!b.contains(mapped[1000]));
        assert!(to_scene(&poses, &[]).is_err(), "one camera, no points");
    }
}
