//! Record3D's `metadata` (`metadata.json` in the EXR + JPG export): colour
//! size, intrinsics, depth size and one pose per frame.

use std::path::{Path, PathBuf};

use model::geometry::{Distortion, Intrinsics};
use serde_json::{Map, Value};

use crate::error::DatasetError;

/// Largest distance of a pose quaternion's norm from 1.
const QUATERNION_TOLERANCE: f64 = 1e-2;

/// What is read from an export's metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct Metadata {
    /// The file (or `archive:metadata`), named in errors.
    pub path: PathBuf,
    /// Intrinsics of the colour camera at `w` x `h`.
    pub intrinsics: Intrinsics,
    /// `dw` x `dh`, when stated.
    pub depth_size: Option<(u32, u32)>,
    /// `fps`, the video's frames a second, when stated (and positive).
    pub fps: Option<f64>,
    /// `poses`, one entry per frame, each checked when its frame is read
    /// ([`Metadata::pose`]).
    poses: Vec<Value>,
}

/// The number under `key` of `map` (of `path`), when there is one.
fn number(map: &Map<String, Value>, key: &str, path: &Path) -> Result<Option<f64>, DatasetError> {
    match map.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => match v.as_f64() {
            Some(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(DatasetError::invalid(
                path,
                format!("`{key}` is {v}, not a finite number"),
            )),
        },
    }
}

/// The positive whole number under `key`, when there is one.
fn size(map: &Map<String, Value>, key: &str, path: &Path) -> Result<Option<u32>, DatasetError> {
    match number(map, key, path)? {
        None => Ok(None),
        Some(x) if x >= 1.0 && x.fract() == 0.0 && x <= u32::MAX as f64 => Ok(Some(x as u32)),
        Some(x) => Err(DatasetError::invalid(
            path,
            format!("`{key}` is {x}, not a positive whole number of pixels"),
        )),
    }
}

/// `v` (the entry `what` of `path`) as `n` finite numbers.
fn numbers(
    v: &Value,
    n: usize,
    what: &str,
    layout: &str,
    path: &Path,
) -> Result<Vec<f64>, DatasetError> {
    let Some(list) = v.as_array() else {
        return Err(DatasetError::invalid(
            path,
            format!("{what} is not a list of numbers"),
        ));
    };
    if list.len() != n {
        return Err(DatasetError::invalid(
            path,
            format!("{what} has {} numbers, expected {n} ({layout})", list.len()),
        ));
    }
    list.iter()
        .map(|x| x.as_f64().filter(|x| x.is_finite()))
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| {
            DatasetError::invalid(
                path,
                format!("{what} holds a non-number or non-finite value"),
            )
        })
}

/// Intrinsics from the column-major 3x3 `k` ([fx, 0, 0, 0, fy, 0, cx, cy,
/// 1]) of an image of `size`.
pub fn intrinsics_column_major(
    path: &Path,
    k: &[f64],
    size: (u32, u32),
) -> Result<Intrinsics, DatasetError> {
    let (fx, fy, cx, cy) = (k[0], k[4], k[6], k[7]);
    let zeros = [k[1], k[2], k[3], k[5]];
    if fx <= 0.0 || fy <= 0.0 || zeros.iter().any(|v| v.abs() > 1e-6) || (k[8] - 1.0).abs() > 1e-6 {
        return Err(DatasetError::invalid(
            path,
            format!(
                "`K` {k:?} is not a pinhole matrix in column-major order [fx, 0, 0, 0, fy, 0, \
                 cx, cy, 1] with positive focal lengths"
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

/// The camera-to-world matrix of the rotation `q` = [x, y, z, w] (a unit
/// quaternion, scalar last) and the camera centre `t`.
pub fn quaternion_pose(q: [f64; 4], t: [f64; 3]) -> [[f64; 4]; 4] {
    let [x, y, z, w] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
            t[0],
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
            t[1],
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
            t[2],
        ],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

impl Metadata {
    /// Parses the metadata `bytes` read from `path`.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Self, DatasetError> {
        let json: Value = serde_json::from_slice(bytes).map_err(|e| {
            DatasetError::invalid(path, format!("not a Record3D metadata JSON: {e}"))
        })?;
        let Some(map) = json.as_object() else {
            return Err(DatasetError::invalid(
                path,
                "not a JSON object: not Record3D metadata",
            ));
        };
        let missing = |key: &str, what: &str| {
            DatasetError::invalid(path, format!("no `{key}` ({what}) in the metadata"))
        };
        let w = size(map, "w", path)?.ok_or_else(|| missing("w", "the colour images' width"))?;
        let h = size(map, "h", path)?.ok_or_else(|| missing("h", "the colour images' height"))?;
        let k = map
            .get("K")
            .ok_or_else(|| missing("K", "the 3x3 intrinsics"))?;
        let k = numbers(k, 9, "`K`", "a 3x3 matrix, column-major", path)?;
        let intrinsics = intrinsics_column_major(path, &k, (w, h))?;
        let depth_size = match (size(map, "dw", path)?, size(map, "dh", path)?) {
            (Some(dw), Some(dh)) => Some((dw, dh)),
            (None, None) => None,
            _ => {
                return Err(DatasetError::invalid(
                    path,
                    "the metadata has only one of `dw` and `dh` (the depth maps' size)",
                ));
            }
        };
        let poses = match map.get("poses") {
            Some(Value::Array(list)) => list.clone(),
            Some(_) => {
                return Err(DatasetError::invalid(path, "`poses` is not a list"));
            }
            None => return Err(missing("poses", "one camera pose per frame")),
        };
        let fps = number(map, "fps", path)?.filter(|&f| f > 0.0);
        Ok(Self {
            path: path.to_path_buf(),
            intrinsics,
            depth_size,
            fps,
            poses,
        })
    }

    /// How many poses the metadata lists.
    pub fn pose_count(&self) -> usize {
        self.poses.len()
    }

    /// Frame `i`'s camera-to-world (ARKit conventions), from `poses[i]` =
    /// [qx, qy, qz, qw, tx, ty, tz]; `image` names the frame's image.
    pub fn pose(&self, i: u64, image: &Path) -> Result<[[f64; 4]; 4], DatasetError> {
        let path = &self.path;
        let Some(entry) = usize::try_from(i).ok().and_then(|i| self.poses.get(i)) else {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "`poses` has {} entries but {} is frame {i}: one pose per frame expected",
                    self.poses.len(),
                    image.display()
                ),
            ));
        };
        let what = format!("`poses[{i}]`");
        let v = numbers(entry, 7, &what, "qx, qy, qz, qw, tx, ty, tz", path)?;
        let norm = v[..4].iter().map(|x| x * x).sum::<f64>().sqrt();
        if !norm.is_finite() || (norm - 1.0).abs() > QUATERNION_TOLERANCE {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "{what} (frame {i}): quaternion {:?} has norm {norm}, not 1",
                    &v[..4]
                ),
            ));
        }
        let q = std::array::from_fn(|j| v[j] / norm);
        Ok(quaternion_pose(q, [v[4], v[5], v[6]]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rotation by `angle` about the unit `axis` (Rodrigues' formula).
    fn rodrigues(axis: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
        let [x, y, z] = axis;
        let k = [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]];
        let (s, c) = angle.sin_cos();
        std::array::from_fn(|r| {
            std::array::from_fn(|col| {
                let kk: f64 = (0..3).map(|m| k[r][m] * k[m][col]).sum();
                let id = if r == col { 1.0 } else { 0.0 };
                id + s * k[r][col] + (1.0 - c) * kk
            })
        })
    }

    fn assert_rotation(m: [[f64; 4]; 4], r: [[f64; 3]; 3]) {
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[i][j] - r[i][j]).abs() < 1e-12, "{m:?} vs {r:?}");
            }
        }
    }

    #[test]
    fn quaternion_is_scalar_last() {
        let a: f64 = 0.7;
        let m = quaternion_pose(
            [0.0, 0.0, (a / 2.0).sin(), (a / 2.0).cos()],
            [1.0, 2.0, 3.0],
        );
        assert_rotation(m, rodrigues([0.0, 0.0, 1.0], a));
        assert_eq!([m[0][3], m[1][3], m[2][3]], [1.0, 2.0, 3.0]);
        assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn quaternion_matches_rodrigues() {
        let n = (1.0f64 + 4.0 + 9.0).sqrt();
        let axis = [1.0 / n, -2.0 / n, 3.0 / n];
        for a in [0.1, 1.3, -2.9, 3.1] {
            let (s, c) = ((a / 2.0f64).sin(), (a / 2.0f64).cos());
            let m = quaternion_pose([axis[0] * s, axis[1] * s, axis[2] * s, c], [0.0; 3]);
            assert_rotation(m, rodrigues(axis, a));
        }
    }

    #[test]
    fn pose_normalises_and_refuses_bad_quaternions() {
        let json = br#"{"w": 4, "h": 3, "K": [2,0,0, 0,2,0, 2,1.5,1],
            "poses": [[0,0,0,1.005,1,2,3], [0,0,0,1.5,0,0,0], [0,0,0,1]]}"#;
        let meta = Metadata::parse(json, Path::new("m.json")).unwrap();
        let m = meta.pose(0, Path::new("0.jpg")).unwrap();
        assert_rotation(m, rodrigues([1.0, 0.0, 0.0], 0.0));
        let e = meta.pose(1, Path::new("1.jpg")).unwrap_err().to_string();
        assert!(
            e.contains("m.json") && e.contains("frame 1") && e.contains("norm"),
            "{e}"
        );
        let e = meta.pose(2, Path::new("2.jpg")).unwrap_err().to_string();
        assert!(e.contains("`poses[2]` has 4 numbers, expected 7"), "{e}");
        let e = meta.pose(3, Path::new("3.jpg")).unwrap_err().to_string();
        assert!(
            e.contains("`poses` has 3 entries") && e.contains("3.jpg is frame 3"),
            "{e}"
        );
    }

    #[test]
    fn k_is_column_major() {
        let json = br#"{"w": 640, "h": 480, "K": [500,0,0, 0,510,0, 321,239,1], "poses": []}"#;
        let meta = Metadata::parse(json, Path::new("m.json")).unwrap();
        let k = meta.intrinsics;
        assert_eq!((k.fx, k.fy, k.cx, k.cy), (500.0, 510.0, 321.0, 239.0));
        assert_eq!((k.width, k.height), (640, 480));
        assert_eq!(meta.depth_size, None);
        let row_major = br#"{"w": 640, "h": 480, "K": [500,0,321, 0,510,239, 0,0,1], "poses": []}"#;
        let e = Metadata::parse(row_major, Path::new("m.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("column-major"), "{e}");
    }

    #[test]
    fn bad_keys_are_named() {
        let cases: [(&[u8], &str); 5] = [
            (
                br#"{"w": 4, "h": 3, "K": [1,0,0,0,1,0,0,0], "poses": []}"#,
                "`K` has 8 numbers, expected 9 (a 3x3 matrix, column-major)",
            ),
            (
                br#"{"h": 3, "K": [1,0,0,0,1,0,0,0,1], "poses": []}"#,
                "no `w`",
            ),
            (
                br#"{"w": 4.5, "h": 3, "K": [1,0,0,0,1,0,0,0,1], "poses": []}"#,
                "`w` is 4.5",
            ),
            (
                br#"{"w": 4, "h": 3, "K": [1,0,0,0,1,0,0,0,1]}"#,
                "no `poses`",
            ),
            (
                br#"{"w": 4, "h": 3, "dw": 2, "K": [1,0,0,0,1,0,0,0,1], "poses": []}"#,
                "only one of `dw` and `dh`",
            ),
        ];
        for (json, want) in cases {
            let e = Metadata::parse(json, Path::new("meta.json"))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("meta.json: ") && e.contains(want), "{e}");
        }
    }
}
