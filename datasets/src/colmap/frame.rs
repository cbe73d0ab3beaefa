//! The scene frame of a COLMAP reconstruction, whose own world frame is
//! arbitrary (any orientation, origin and scale): up is +z, the centre is
//! the centre of the region the capture sees, and that region's largest
//! side is [`SCENE_SIZE`] units.
//!
//! * Up: the normalised mean of the cameras' up vectors (`-y` of each
//!   OpenCV camera), rotated onto +z by the minimal rotation.
//! * Robust box: per axis (after that rotation) the 2nd and 98th
//!   percentiles of the sparse points. With fewer than [`MIN_POINTS`]
//!   points (COLMAP's known-poses workflow, poses exported from another
//!   system) the cameras give the frame ([`FrameFit`]): a cube centred on
//!   their focus, the point their optical axes pass closest to, as wide as
//!   the narrowest view spans at the cameras' median distance from it (what
//!   every camera sees there: an object photographed from all around fills
//!   it, as it fills the photographs); when the axes are too close to
//!   parallel for a focus (a forward-facing capture), the camera centres'
//!   own robust box.
//! * Seen region: the robust box grown to hold what every camera sees at
//!   the depth of its own points (its image corners at the median depth of
//!   the sparse points in front of it). Sparse points lie on textured
//!   surfaces only; an object photographed from a few metres fills the
//!   frame with a desk or a floor that has few of them, and a field
//!   bounded by the points alone would render that as empty.
//! * Scale: `SCENE_SIZE / largest side` of the seen region (the sampler's
//!   near plane and query radii are tuned for scenes of a few units).

use model::geometry::{Camera, Pose, SceneBox, Similarity, Vec3, cross, dot, norm};

pub use crate::poses::{MIN_AXIS_SPREAD, focus_point};

/// Largest side of the seen region in the scene frame.
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

/// What the scene frame was fitted to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameFit {
    /// The sparse points (this many).
    Points(usize),
    /// Too few sparse points (this many): the cameras' focus, spanning
    /// the camera centres mirrored through it.
    CameraFocus(usize),
    /// Too few sparse points (this many) and optical axes too close to
    /// parallel for a focus: the camera centres' robust box.
    CameraCentres(usize),
}

impl FrameFit {
    /// How the frame was fitted, in words for the user.
    pub fn describe(&self) -> String {
        match *self {
            FrameFit::Points(n) => format!("fitted to the {n} sparse points of points3D"),
            FrameFit::CameraFocus(n) => format!(
                "points3D has {n} points (fewer than {MIN_POINTS}), so the frame is fitted to the \
                 cameras: centred where their optical axes pass closest, as wide as every camera \
                 sees at its median distance from there"
            ),
            FrameFit::CameraCentres(n) => format!(
                "points3D has {n} points (fewer than {MIN_POINTS}) and the cameras' optical axes \
                 are close to parallel, so the frame is the box of the camera centres and may \
                 miss content far in front of them (a model with sparse points, or the same poses \
                 as transforms.json with a known box, avoids this)"
            ),
        }
    }
}

/// What the frame of `points` and `poses` is fitted to (see [`box_basis`]).
pub fn frame_fit(points: &[Vec3], poses: &[Pose]) -> FrameFit {
    if points.len() >= MIN_POINTS {
        FrameFit::Points(points.len())
    } else if focus_point(poses).is_some() {
        FrameFit::CameraFocus(points.len())
    } else {
        FrameFit::CameraCentres(points.len())
    }
}

/// The points the robust box is taken over: the sparse points; with fewer
/// than [`MIN_POINTS`], the corners of the cube the cameras see around
/// their [`focus_point`] ([`seen_around`]), or the camera centres alone
/// without a focus.
pub fn box_basis(points: &[Vec3], cameras: &[Camera]) -> Vec<Vec3> {
    if points.len() >= MIN_POINTS {
        return points.to_vec();
    }
    let poses: Vec<Pose> = cameras.iter().map(|c| c.pose).collect();
    match focus_point(&poses) {
        Some(f) => {
            let r = seen_around(cameras, f);
            (0..8)
                .map(|i| std::array::from_fn(|k| f[k] + if i >> k & 1 == 1 { r } else { -r }))
                .collect()
        }
        None => poses.iter().map(Pose::center).collect(),
    }
}

/// Half the width every camera sees at the cameras' median distance from
/// `focus`: that distance times the tangent of the narrowest half field
/// of view among them.
pub fn seen_around(cameras: &[Camera], focus: Vec3) -> f64 {
    let mut distances: Vec<f64> = cameras
        .iter()
        .map(|c| {
            let p = c.pose.center();
            norm([focus[0] - p[0], focus[1] - p[1], focus[2] - p[2]])
        })
        .collect();
    distances.sort_by(f64::total_cmp);
    let half_tan = cameras
        .iter()
        .map(|c| {
            let k = &c.intrinsics;
            (0.5 * f64::from(k.width) / k.fx).min(0.5 * f64::from(k.height) / k.fy)
        })
        .fold(f64::INFINITY, f64::min);
    percentile(&distances, 0.5) * half_tan
}

/// Each camera's image corners at the median depth of the `points` in
/// front of it and inside its image (none for a camera that sees none).
pub fn seen_corners(cameras: &[Camera], points: &[Vec3]) -> Vec<Vec3> {
    let mut corners = Vec::new();
    for cam in cameras {
        let k = &cam.intrinsics;
        let (w, h) = (k.width as f64, k.height as f64);
        let mut depths: Vec<f64> = points
            .iter()
            .filter_map(|&p| cam.project(p))
            .filter(|q| q.u >= -0.5 && q.u <= w - 0.5 && q.v >= -0.5 && q.v <= h - 0.5)
            .map(|q| q.z)
            .collect();
        if depths.is_empty() {
            continue;
        }
        depths.sort_by(f64::total_cmp);
        let d = percentile(&depths, 0.5);
        for (u, v) in [
            (-0.5, -0.5),
            (w - 0.5, -0.5),
            (-0.5, h - 0.5),
            (w - 0.5, h - 0.5),
        ] {
            let ray = cam.ray(u, v);
            corners.push(std::array::from_fn(|i| {
                ray.origin[i] + d * ray.direction[i]
            }));
        }
    }
    corners
}

/// The region the scene frame is fitted to: the robust box of
/// [`box_basis`] grown to hold the robust box of [`seen_corners`].
pub fn seen_region(cameras: &[Camera], points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let (mut lo, mut hi) = robust_box(&box_basis(points, cameras))?;
    if let Some((clo, chi)) = robust_box(&seen_corners(cameras, points)) {
        for k in 0..3 {
            lo[k] = lo[k].min(clo[k]);
            hi[k] = hi[k].max(chi[k]);
        }
    }
    Some((lo, hi))
}

/// The map from COLMAP's frame to the scene frame (see the module docs).
pub fn to_scene(cameras: &[Camera], points: &[Vec3]) -> Result<Similarity, String> {
    let poses: Vec<Pose> = cameras.iter().map(|c| c.pose).collect();
    let rotation = mean_up(&poses).map_or(Similarity::IDENTITY.rotation, rotation_onto_z);
    let rotate = Similarity {
        rotation,
        ..Similarity::IDENTITY
    };
    let rotated: Vec<Camera> = cameras
        .iter()
        .map(|c| Camera {
            intrinsics: c.intrinsics,
            pose: rotate.apply_pose(&c.pose),
        })
        .collect();
    let points: Vec<Vec3> = points.iter().map(|&p| rotate.apply_point(p)).collect();
    let (lo, hi) = seen_region(&rotated, &points)
        .ok_or("no sparse point and no camera to centre the scene on")?;
    let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    if !(side > 0.0 && side.is_finite()) {
        return Err(format!(
            "cannot scale the scene: the robust box of its {} points has no extent",
            points.len()
        ));
    }
    let scale = SCENE_SIZE / side;
    Ok(Similarity {
        rotation,
        scale,
        translation: std::array::from_fn(|k| -scale * 0.5 * (lo[k] + hi[k])),
    })
}

/// The scene box of `points` and `cameras` already in the scene frame:
/// the seen region plus `margin` of its largest extent.
pub fn scene_box(points: &[Vec3], cameras: &[Camera], margin: f64) -> Option<SceneBox> {
    let (lo, hi) = seen_region(cameras, points)?;
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
        // A camera far behind the block with a narrow view: what it sees at
        // its points' depth lies inside their robust box. Up is -y.
        let cams = [camera([5.0, 5.0, -100.0], 1e5)];
        let s = to_scene(&cams, &pts).expect("extent");
        let mapped: Vec<Vec3> = pts.iter().map(|&p| s.apply_point(p)).collect();
        let (lo, hi) = robust_box(&mapped).expect("points");
        let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        assert!((side - 3.0).abs() < 1e-9, "{side}");
        assert!((0..3).all(|k| (lo[k] + hi[k]).abs() < 1e-9));
        let up = s.apply_vector([0.0, -1.0, 0.0]);
        assert!((up[2] / s.scale - 1.0).abs() < 1e-12);
        let mapped_cams: Vec<Camera> = cams
            .iter()
            .map(|c| Camera {
                intrinsics: c.intrinsics,
                pose: s.apply_pose(&c.pose),
            })
            .collect();
        let b = scene_box(&mapped, &mapped_cams, 0.05).expect("box");
        assert!(!b.contains(mapped[1000]));
        assert!(to_scene(&cams, &[]).is_err(), "one camera, no points");
    }

    /// A camera `(x, y, z)` looking along +z (up -y), 100x100 pixels.
    fn camera(at: Vec3, focal: f64) -> Camera {
        Camera {
            intrinsics: model::geometry::Intrinsics {
                width: 100,
                height: 100,
                fx: focal,
                fy: focal,
                cx: 49.5,
                cy: 49.5,
                distortion: model::geometry::Distortion::NONE,
            },
            pose: Pose {
                translation: at,
                ..Pose::identity()
            },
        }
    }

    /// Few points, wide view: the region grows to the image's footprint at
    /// the points' depth (a desk around a small object).
    #[test]
    fn the_region_holds_what_the_cameras_see_at_the_points_depth() {
        let pts: Vec<Vec3> = (0..50)
            .map(|i| {
                let t = i as f64 / 50.0;
                [0.2 * (t - 0.5), 0.1 * (7.0 * t).sin(), 4.0 + 0.1 * t]
            })
            .collect();
        // Focal 50 px over 100 px: the image spans +-1 at depth 1.
        let cams = [camera([0.0; 3], 50.0)];
        let (lo, hi) = seen_region(&cams, &pts).expect("region");
        let depth = {
            let mut d: Vec<f64> = pts.iter().map(|p| p[2]).collect();
            d.sort_by(f64::total_cmp);
            percentile(&d, 0.5)
        };
        for k in 0..2 {
            assert!(
                (hi[k] - depth).abs() < 1e-9 && (lo[k] + depth).abs() < 1e-9,
                "{lo:?} {hi:?}"
            );
        }
        let (plo, phi) = robust_box(&pts).expect("points");
        assert!(lo[2] <= plo[2] && hi[2] >= phi[2]);
    }

    /// Poses at `centres` looking at `target` (up +z).
    fn looking_at(centres: &[Vec3], target: Vec3) -> Vec<Pose> {
        centres
            .iter()
            .map(|&c| model::geometry::look_at(c, target, [0.0, 0.0, 1.0]).expect("pose"))
            .collect()
    }

    #[test]
    fn the_focus_is_where_the_optical_axes_meet() {
        let target = [2.0, -1.0, 3.0];
        let centres: Vec<Vec3> = (0..7)
            .map(|i| {
                let t = 0.9 * i as f64;
                [
                    target[0] + 4.0 * t.cos(),
                    target[1] + 4.0 * t.sin(),
                    target[2] + 2.0,
                ]
            })
            .collect();
        let poses = looking_at(&centres, target);
        let f = focus_point(&poses).expect("axes spread");
        assert!((0..3).all(|k| (f[k] - target[k]).abs() < 1e-9), "{f:?}");
        assert_eq!(frame_fit(&[], &poses), FrameFit::CameraFocus(0));
        // The box basis is a cube about the focus, as wide as the views
        // span there: focal 100 px over 100 px spans +-0.5 at depth 1, and
        // every camera is sqrt(4^2 + 2^2) from the target.
        let cams: Vec<Camera> = poses
            .iter()
            .map(|&pose| Camera {
                pose,
                ..camera([0.0; 3], 100.0)
            })
            .collect();
        let (lo, hi) = robust_box(&box_basis(&[], &cams)).expect("basis");
        assert!((0..3).all(|k| (lo[k] + hi[k] - 2.0 * target[k]).abs() < 1e-9));
        let half = 0.5 * 20f64.sqrt();
        assert!(
            (0..3).all(|k| (hi[k] - lo[k] - 2.0 * half).abs() < 1e-9),
            "{lo:?} {hi:?}"
        );
        // The cameras stand outside it, looking in.
        assert!(
            cams.iter()
                .all(|c| !SceneBox { min: lo, max: hi }.contains(c.pose.center()))
        );
        // Enough sparse points take precedence over the cameras.
        let pts = vec![[0.0; 3]; MIN_POINTS];
        assert_eq!(frame_fit(&pts, &poses), FrameFit::Points(MIN_POINTS));
        assert_eq!(box_basis(&pts, &cams), pts);
    }

    #[test]
    fn parallel_or_diverging_axes_have_no_focus() {
        // A forward-facing rig: every camera looks along +y (2 degrees
        // apart at most).
        let centres: Vec<Vec3> = (0..6)
            .map(|i| [0.3 * i as f64, 0.0, 0.1 * i as f64])
            .collect();
        let parallel: Vec<Pose> = centres
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                let a = (i as f64 - 2.5) * 0.007;
                model::geometry::look_at(c, [c[0] + a.sin(), c[1] + a.cos(), c[2]], [0.0, 0.0, 1.0])
                    .expect("pose")
            })
            .collect();
        assert_eq!(focus_point(&parallel), None);
        assert_eq!(frame_fit(&[], &parallel), FrameFit::CameraCentres(0));
        let parallel_cams: Vec<Camera> = parallel
            .iter()
            .map(|&pose| Camera {
                pose,
                ..camera([0.0; 3], 50.0)
            })
            .collect();
        assert_eq!(box_basis(&[], &parallel_cams), centres);
        // Cameras looking outwards from a ring: their axes meet behind them.
        let ring: Vec<Vec3> = (0..6)
            .map(|i| [(1.0 * i as f64).cos(), (1.0 * i as f64).sin(), 0.0])
            .collect();
        let outwards: Vec<Pose> = ring
            .iter()
            .map(|&c| {
                model::geometry::look_at(c, c.map(|v| 2.0 * v), [0.0, 0.0, 1.0]).expect("pose")
            })
            .collect();
        assert_eq!(focus_point(&outwards), None);
        assert_eq!(focus_point(&outwards[..1]), None, "one camera");
        assert!(FrameFit::CameraCentres(3).describe().contains("parallel"));
    }
}
