//! Cameras to evaluate at: Blender / nerfstudio `transforms.json`, Nice-SLAM
//! `traj.txt` with `cam_params.json` (parsed by the `datasets` loaders),
//! resizing, and smooth camera paths (slerp of rotations, lerp of positions)
//! between poses.

use std::path::Path;

use field_ops::OpsError;
use model::geometry::{Camera, Intrinsics, Pose};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

/// A camera with the name its output files take.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedCamera {
    /// File-name stem (e.g. `frame000010` or `r_3`).
    pub name: String,
    /// The camera.
    pub camera: Camera,
}

/// Cameras of a Blender / nerfstudio `transforms.json` (read by
/// [`datasets::blender::read_cameras`]: OpenGL poses converted to OpenCV,
/// per-frame intrinsics).
pub fn load_transforms_json(path: &Path) -> Result<Vec<NamedCamera>, OpsError> {
    Ok(datasets::blender::read_cameras(path)?
        .into_iter()
        .map(|(name, camera)| NamedCamera { name, camera })
        .collect())
}

/// Nice-SLAM cameras: `traj.txt` (one row-major 4x4 camera-to-world matrix
/// per line, OpenCV) and the intrinsics of `cam_params.json`, both read by
/// the `datasets` Replica parsers. Frames are named `frameNNNNNN` after
/// their pose index; `stride` keeps every n-th pose.
pub fn load_traj(
    traj: &Path,
    cam_params: &Path,
    stride: usize,
) -> Result<Vec<NamedCamera>, OpsError> {
    let c = datasets::replica::read_cam_params(cam_params)?;
    let intrinsics = Intrinsics {
        width: c.w,
        height: c.h,
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        distortion: model::geometry::Distortion::NONE,
    };
    Ok(datasets::replica::read_trajectory(traj)?
        .into_iter()
        .enumerate()
        .step_by(stride.max(1))
        .map(|(i, pose)| NamedCamera {
            name: format!("frame{i:06}"),
            camera: Camera { intrinsics, pose },
        })
        .collect())
}

/// The same cameras at `width x height` (intrinsics rescaled).
pub fn resized(cams: &[NamedCamera], width: u32, height: u32) -> Vec<NamedCamera> {
    cams.iter()
        .map(|c| NamedCamera {
            name: c.name.clone(),
            camera: c.camera.scaled(width, height),
        })
        .collect()
}

/// The unit quaternion of a rotation matrix.
pub fn quat_from_matrix(r: &[[f64; 3]; 3]) -> UnitQuaternion<f64> {
    let m = Matrix3::from_fn(|i, j| r[i][j]);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

/// The rotation matrix of a unit quaternion.
pub fn matrix_from_quat(q: UnitQuaternion<f64>) -> [[f64; 3]; 3] {
    let m = q.to_rotation_matrix();
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

/// Pose between `a` (`s = 0`) and `b` (`s = 1`): slerped rotation, lerped centre.
pub fn interpolate_pose(a: &Pose, b: &Pose, s: f64) -> Pose {
    let (qa, qb) = (quat_from_matrix(&a.rotation), quat_from_matrix(&b.rotation));
    // Along the shorter arc; rotations too close for slerp are taken as one.
    let q = qa.try_slerp(&qb, s, 1e-12).unwrap_or(qa);
    let t = [0, 1, 2].map(|k| (1.0 - s) * a.translation[k] + s * b.translation[k]);
    Pose {
        rotation: matrix_from_quat(q),
        translation: t,
    }
}

/// `n` cameras evenly spaced in the path parameter through the key cameras
/// in order (the first and last key poses are the path's ends); intrinsics of
/// the first key camera. Named `path0000`, `path0001`, ...
pub fn camera_path(keys: &[NamedCamera], n: usize) -> Result<Vec<NamedCamera>, OpsError> {
    let Some(first) = keys.first() else {
        return Err(OpsError::Invalid(
            "a camera path needs at least one key camera".into(),
        ));
    };
    let segments = keys.len() - 1;
    Ok((0..n)
        .map(|i| {
            let s = if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.0
            } * segments as f64;
            let seg = (s.floor() as usize).min(segments.saturating_sub(1));
            let pose = if segments == 0 {
                first.camera.pose
            } else {
                interpolate_pose(
                    &keys[seg].camera.pose,
                    &keys[seg + 1].camera.pose,
                    s - seg as f64,
                )
            };
            NamedCamera {
                name: format!("path{i:04}"),
                camera: Camera {
                    intrinsics: first.camera.intrinsics,
                    pose,
                },
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geometry::look_at;

    fn rot_z(a: f64) -> [[f64; 3]; 3] {
        let (s, c) = a.sin_cos();
        [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    }

    fn max_diff(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> f64 {
        (0..9)
            .map(|i| (a[i / 3][i % 3] - b[i / 3][i % 3]).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn quaternion_round_trip_all_branches() {
        let poses = [
            look_at([1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap(),
            look_at([0.0, 0.0, 0.0], [-1.0, 0.1, 0.0], [0.0, 0.0, 1.0]).unwrap(),
            look_at([0.0, 0.0, 0.0], [0.0, -1.0, 0.2], [0.0, 0.0, 1.0]).unwrap(),
            look_at([0.0, 0.0, 0.0], [0.1, 0.0, -1.0], [0.0, 1.0, 0.0]).unwrap(),
        ];
        for p in poses {
            let back = matrix_from_quat(quat_from_matrix(&p.rotation));
            assert!(max_diff(&back, &p.rotation) < 1e-12);
        }
        let r = rot_z(std::f64::consts::PI); // trace -1: a non-trace branch
        assert!(max_diff(&matrix_from_quat(quat_from_matrix(&r)), &r) < 1e-12);
    }

    #[test]
    fn slerp_halfway_is_half_the_angle_and_lerps_position() {
        let a = Pose::identity();
        let b = Pose {
            rotation: rot_z(1.2),
            translation: [2.0, -4.0, 6.0],
        };
        let m = interpolate_pose(&a, &b, 0.5);
        assert!(max_diff(&m.rotation, &rot_z(0.6)) < 1e-12);
        assert_eq!(m.translation, [1.0, -2.0, 3.0]);
        let q = interpolate_pose(&a, &b, 0.25);
        assert!(max_diff(&q.rotation, &rot_z(0.3)) < 1e-12);
    }

    #[test]
    fn camera_path_hits_the_keys() {
        let k = Intrinsics::from_fov_x(40, 30, 1.0);
        let mk = |angle: f64, x: f64| NamedCamera {
            name: "k".into(),
            camera: Camera {
                intrinsics: k,
                pose: Pose {
                    rotation: rot_z(angle),
                    translation: [x, 0.0, 0.0],
                },
            },
        };
        let keys = [mk(0.0, 0.0), mk(0.4, 1.0), mk(0.8, 3.0)];
        let path = camera_path(&keys, 5).unwrap();
        assert_eq!(path.len(), 5);
        assert_eq!(path[0].camera.pose.translation, [0.0, 0.0, 0.0]);
        assert!((path[2].camera.pose.translation[0] - 1.0).abs() < 1e-12);
        assert!((path[4].camera.pose.translation[0] - 3.0).abs() < 1e-12);
        assert!(max_diff(&path[3].camera.pose.rotation, &rot_z(0.6)) < 1e-12);
        assert_eq!(path[1].name, "path0001");
        assert!(camera_path(&[], 3).is_err());
    }

    #[test]
    fn transforms_json_and_traj_parse() {
        let dir = std::env::temp_dir().join(format!("eval-cams-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let tj = dir.join("transforms.json");
        std::fs::write(
            &tj,
            r#"{"camera_angle_x": 0.69, "w": 80, "h": 60, "frames": [
                {"file_path": "./train/r_0", "transform_matrix": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}]}"#,
        )
        .unwrap();
        let cams = load_transforms_json(&tj).unwrap();
        assert_eq!(cams[0].name, "r_0");
        assert_eq!(cams[0].camera.pose.translation, [1.0, 2.0, 3.0]);
        // OpenGL looks down -z: the OpenCV forward axis is -z in world.
        assert_eq!(cams[0].camera.pose.forward(), [0.0, 0.0, -1.0]);
        assert_eq!(cams[0].camera.intrinsics.cx, 39.5);
        std::fs::write(&tj, r#"{"camera_angle_x": 0.69, "w": 8, "h": 6, "frames": [{"transform_matrix": [[1,0]]}]}"#).unwrap();
        assert!(load_transforms_json(&tj).is_err());

        let cp = dir.join("cam_params.json");
        std::fs::write(&cp, r#"{"camera": {"w": 1200, "h": 680, "fx": 600, "fy": 600, "cx": 599.5, "cy": 339.5, "scale": 6553.5}}"#).unwrap();
        let tr = dir.join("traj.txt");
        let row = "1 0 0 0.5 0 1 0 0 0 0 1 0 0 0 0 1\n";
        std::fs::write(&tr, row.repeat(4)).unwrap();
        let cams = load_traj(&tr, &cp, 2).unwrap();
        assert_eq!(cams.len(), 2);
        assert_eq!(cams[1].name, "frame000002");
        assert_eq!(cams[1].camera.intrinsics.fx, 600.0);
        std::fs::write(&tr, "1 0 0\n").unwrap();
        assert!(load_traj(&tr, &cp, 1).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
