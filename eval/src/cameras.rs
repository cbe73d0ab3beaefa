//! Cameras to evaluate at: Blender / nerfstudio `transforms.json`, Nice-SLAM
//! `traj.txt` with `cam_params.json`, resizing, and smooth camera paths
//! (slerp of rotations, lerp of positions) between poses.

use std::path::Path;

use model::geometry::{Camera, Intrinsics, Pose};

use crate::error::EvalError;
use crate::run::read_json;

/// A camera with the name its output files take.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedCamera {
    /// File-name stem (e.g. `frame000010` or `r_3`).
    pub name: String,
    /// The camera.
    pub camera: Camera,
}

/// Cameras of a Blender / nerfstudio `transforms.json` (OpenGL poses,
/// converted to OpenCV). Intrinsics come from `fl_x`/`fl_y`/`cx`/`cy`/`w`/`h`
/// when present, else from `camera_angle_x` and the size of the first frame's
/// image (read from its header only).
pub fn load_transforms_json(path: &Path) -> Result<Vec<NamedCamera>, EvalError> {
    let json: serde_json::Value = read_json(path)?;
    let bad = |m: String| EvalError::json(path, m);
    let num = |v: &serde_json::Value, k: &str| v.get(k).and_then(|x| x.as_f64());
    let frames = json
        .get("frames")
        .and_then(|f| f.as_array())
        .ok_or_else(|| bad("no \"frames\" array".into()))?;
    if frames.is_empty() {
        return Err(bad("\"frames\" is empty".into()));
    }
    let (w, h) = match (num(&json, "w"), num(&json, "h")) {
        (Some(w), Some(h)) => (w as u32, h as u32),
        _ => image_size_of_first_frame(path, &frames[0])?,
    };
    if w == 0 || h == 0 {
        return Err(bad(format!("image size {w}x{h}")));
    }
    let intrinsics = match (num(&json, "fl_x"), num(&json, "camera_angle_x")) {
        (Some(fx), _) => Intrinsics {
            width: w,
            height: h,
            fx,
            fy: num(&json, "fl_y").unwrap_or(fx),
            // nerfstudio's principal point is in pixel-edge coordinates.
            cx: num(&json, "cx").map_or((w as f64 - 1.0) / 2.0, |c| c - 0.5),
            cy: num(&json, "cy").map_or((h as f64 - 1.0) / 2.0, |c| c - 0.5),
        },
        (None, Some(fov)) => Intrinsics::from_fov_x(w, h, fov),
        (None, None) => return Err(bad("neither \"fl_x\" nor \"camera_angle_x\"".into())),
    };
    frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let m = matrix4(f.get("transform_matrix"))
                .ok_or_else(|| bad(format!("frame {i}: transform_matrix is not a 4x4 matrix")))?;
            let pose = Pose::from_opengl(m).map_err(|e| bad(format!("frame {i}: {e}")))?;
            let name = f
                .get("file_path")
                .and_then(|p| p.as_str())
                .and_then(|p| {
                    Path::new(p)
                        .file_stem()
                        .and_then(|s| s.to_str())
                        .map(String::from)
                })
                .unwrap_or_else(|| format!("frame{i:04}"));
            Ok(NamedCamera {
                name,
                camera: Camera { intrinsics, pose },
            })
        })
        .collect()
}

fn matrix4(v: Option<&serde_json::Value>) -> Option<[[f64; 4]; 4]> {
    let rows = v?.as_array()?;
    if rows.len() != 4 {
        return None;
    }
    let mut m = [[0.0; 4]; 4];
    for (r, row) in rows.iter().enumerate() {
        let row = row.as_array()?;
        if row.len() != 4 {
            return None;
        }
        for (c, x) in row.iter().enumerate() {
            m[r][c] = x.as_f64()?;
        }
    }
    Some(m)
}

fn image_size_of_first_frame(
    path: &Path,
    frame: &serde_json::Value,
) -> Result<(u32, u32), EvalError> {
    let rel = frame
        .get("file_path")
        .and_then(|p| p.as_str())
        .ok_or_else(|| EvalError::json(path, "no \"w\"/\"h\" and frame 0 has no file_path"))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut img = base.join(rel);
    if img.extension().is_none() {
        img.set_extension("png");
    }
    image::image_dimensions(&img).map_err(|e| EvalError::Image {
        path: img.clone(),
        message: e.to_string(),
    })
}

/// Nice-SLAM cameras: `traj.txt` (one row-major 4x4 camera-to-world matrix
/// per line, OpenCV) and the intrinsics of `cam_params.json`. Frames are named
/// `frameNNNNNN` after their line index; `stride` keeps every n-th line.
pub fn load_traj(
    traj: &Path,
    cam_params: &Path,
    stride: usize,
) -> Result<Vec<NamedCamera>, EvalError> {
    let json: serde_json::Value = read_json(cam_params)?;
    let c = json
        .get("camera")
        .ok_or_else(|| EvalError::json(cam_params, "no \"camera\" object"))?;
    let get = |k: &str| {
        c.get(k).and_then(|x| x.as_f64()).ok_or_else(|| {
            EvalError::json(cam_params, format!("camera.{k} missing or not a number"))
        })
    };
    let intrinsics = Intrinsics {
        width: get("w")? as u32,
        height: get("h")? as u32,
        fx: get("fx")?,
        fy: get("fy")?,
        cx: get("cx")?,
        cy: get("cy")?,
    };
    let text = std::fs::read_to_string(traj).map_err(|e| EvalError::io(traj, e))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() || i % stride.max(1) != 0 {
            continue;
        }
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| EvalError::Invalid(format!("{}: line {}: {e}", traj.display(), i + 1)))?;
        if v.len() != 16 {
            return Err(EvalError::Invalid(format!(
                "{}: line {}: {} numbers, expected 16",
                traj.display(),
                i + 1,
                v.len()
            )));
        }
        let mut m = [[0.0; 4]; 4];
        for r in 0..4 {
            m[r].copy_from_slice(&v[4 * r..4 * r + 4]);
        }
        let pose = Pose::from_matrix(m)
            .map_err(|e| EvalError::Invalid(format!("{}: line {}: {e}", traj.display(), i + 1)))?;
        out.push(NamedCamera {
            name: format!("frame{i:06}"),
            camera: Camera { intrinsics, pose },
        });
    }
    Ok(out)
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

/// A unit quaternion `[w, x, y, z]` from a rotation matrix (Shepperd's method).
pub fn quat_from_matrix(r: &[[f64; 3]; 3]) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            0.25 * s,
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        [
            (r[2][1] - r[1][2]) / s,
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        [
            (r[0][2] - r[2][0]) / s,
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
        ]
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        [
            (r[1][0] - r[0][1]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
        ]
    };
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    q.map(|x| x / n)
}

/// The rotation matrix of a unit quaternion `[w, x, y, z]`.
pub fn matrix_from_quat(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Spherical linear interpolation along the shorter arc, `s` in `[0, 1]`.
pub fn slerp(a: [f64; 4], b: [f64; 4], s: f64) -> [f64; 4] {
    let mut d: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    let b = if d < 0.0 {
        d = -d;
        b.map(|x| -x)
    } else {
        b
    };
    let (wa, wb) = if d > 0.9995 {
        (1.0 - s, s)
    } else {
        let theta = d.clamp(-1.0, 1.0).acos();
        let sin = theta.sin();
        (((1.0 - s) * theta).sin() / sin, (s * theta).sin() / sin)
    };
    let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| wa * x + wb * y).collect();
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
}

/// Pose between `a` (`s = 0`) and `b` (`s = 1`): slerped rotation, lerped centre.
pub fn interpolate_pose(a: &Pose, b: &Pose, s: f64) -> Pose {
    let q = slerp(
        quat_from_matrix(&a.rotation),
        quat_from_matrix(&b.rotation),
        s,
    );
    let t = [0, 1, 2].map(|k| (1.0 - s) * a.translation[k] + s * b.translation[k]);
    Pose {
        rotation: matrix_from_quat(q),
        translation: t,
    }
}

/// `n` cameras evenly spaced in the path parameter through the key cameras
/// in order (the first and last key poses are the path's ends); intrinsics of
/// the first key camera. Named `path0000`, `path0001`, ...
pub fn camera_path(keys: &[NamedCamera], n: usize) -> Result<Vec<NamedCamera>, EvalError> {
    let Some(first) = keys.first() else {
        return Err(EvalError::Invalid(
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
