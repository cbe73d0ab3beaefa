//! The content of a COLMAP sparse model (cameras, images, 3D points) as
//! COLMAP stores it, and the conversion of an image's pose to this crate's
//! geometry ([`Image::pose`]); cameras are in [`super::camera`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use model::geometry::Pose;

pub use super::camera::{Camera, CameraModel, SUPPORTED_MODELS};
use crate::error::DatasetError;

/// One 2D feature of an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point2D {
    /// Position in pixels (pixel-corner convention).
    pub xy: [f64; 2],
    /// The 3D point it observes, if any.
    pub point3d_id: Option<u64>,
}

/// A registered image: its world-to-camera pose as COLMAP stores it.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Image id.
    pub id: u32,
    /// World-to-camera rotation, unit quaternion `(w, x, y, z)`.
    pub qvec: [f64; 4],
    /// World-to-camera translation.
    pub tvec: [f64; 3],
    /// The camera it was taken with.
    pub camera_id: u32,
    /// File name, relative to the image folder.
    pub name: String,
    /// Its 2D features.
    pub points2d: Vec<Point2D>,
}

impl Image {
    /// The camera-to-world pose (OpenCV axes): `R_cw = R^T`, centre
    /// `-R^T t`, with `R` the normalised quaternion's rotation. Errors on a
    /// non-finite or zero quaternion or translation.
    pub fn pose(&self) -> Result<Pose, String> {
        let [w, x, y, z] = self.qvec;
        let n = (w * w + x * x + y * y + z * z).sqrt();
        if !(n.is_finite() && n > 1e-12) || self.tvec.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "image {} ({}): bad pose, quaternion {:?}, translation {:?}",
                self.id, self.name, self.qvec, self.tvec
            ));
        }
        let r = quaternion_matrix([w / n, x / n, y / n, z / n]);
        let t = self.tvec;
        let mut m = [[0.0, 0.0, 0.0, 1.0]; 4];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = r[j][i];
            }
            m[i][3] = -(0..3).map(|k| r[k][i] * t[k]).sum::<f64>();
        }
        Pose::from_matrix(m).map_err(|e| format!("image {} ({}): {e}", self.id, self.name))
    }
}

/// Rotation matrix (row-major) of a unit quaternion `(w, x, y, z)`.
pub fn quaternion_matrix([w, x, y, z]: [f64; 4]) -> [[f64; 3]; 3] {
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

/// A triangulated point.
#[derive(Debug, Clone, PartialEq)]
pub struct Point3D {
    /// Point id.
    pub id: u64,
    /// Position in COLMAP's world frame.
    pub xyz: [f64; 3],
    /// Colour.
    pub rgb: [u8; 3],
    /// Mean reprojection error, pixels.
    pub error: f64,
    /// Observations: `(image id, index of the 2D point in that image)`.
    pub track: Vec<(u32, u32)>,
}

/// Which files a model was read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelFormat {
    /// `cameras.bin`, `images.bin`, `points3D.bin`.
    Binary,
    /// `cameras.txt`, `images.txt`, `points3D.txt`.
    Text,
}

impl ModelFormat {
    /// File extension (`bin` or `txt`).
    pub fn extension(self) -> &'static str {
        match self {
            Self::Binary => "bin",
            Self::Text => "txt",
        }
    }
}

/// A sparse model.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// The directory it was read from.
    pub dir: PathBuf,
    /// Binary or text.
    pub format: ModelFormat,
    /// Cameras by id.
    pub cameras: BTreeMap<u32, Camera>,
    /// Registered images, in file order.
    pub images: Vec<Image>,
    /// 3D points, in file order.
    pub points: Vec<Point3D>,
}

impl Model {
    /// Path of one of the model's files: `part` is `cameras`, `images` or
    /// `points3D`.
    pub fn file(&self, part: &str) -> PathBuf {
        model_file(&self.dir, self.format, part)
    }

    /// Checks what the readers cannot check record by record: every image's
    /// camera exists, and ids are unique.
    pub fn validate(&self) -> Result<(), DatasetError> {
        let images = self.file("images");
        let mut seen = std::collections::HashSet::new();
        for im in &self.images {
            if !seen.insert(im.id) {
                return Err(DatasetError::invalid(
                    &images,
                    format!("image id {} appears twice", im.id),
                ));
            }
            if !self.cameras.contains_key(&im.camera_id) {
                return Err(DatasetError::invalid(
                    &images,
                    format!(
                        "image {} ({}) refers to camera {}, which {} does not define",
                        im.id,
                        im.name,
                        im.camera_id,
                        file_name(&self.file("cameras"))
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// `dir/part.bin` or `dir/part.txt`.
pub(crate) fn model_file(dir: &Path, format: ModelFormat, part: &str) -> PathBuf {
    dir.join(format!("{part}.{}", format.extension()))
}

/// The last component of a path, for messages.
pub(crate) fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    )
}

/// Error for a point with a non-finite coordinate.
pub(crate) fn check_point(path: &Path, p: &Point3D) -> Result<(), DatasetError> {
    if p.xyz.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(DatasetError::invalid(
            path,
            format!("point {} has a non-finite position {:?}", p.id, p.xyz),
        ))
    }
}

/// Adds a camera, refusing a repeated id.
pub(crate) fn insert_camera(
    path: &Path,
    cameras: &mut BTreeMap<u32, Camera>,
    camera: Camera,
) -> Result<(), DatasetError> {
    let id = camera.id;
    if cameras.insert(id, camera).is_some() {
        return Err(DatasetError::invalid(
            path,
            format!("camera id {id} appears twice"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_inverts_the_world_to_camera_transform() {
        // 90 degrees about z: q = (cos 45, 0, 0, sin 45).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let im = Image {
            id: 1,
            qvec: [2.0 * h, 0.0, 0.0, 2.0 * h], // unnormalised on purpose
            tvec: [1.0, 2.0, 3.0],
            camera_id: 1,
            name: "a.png".into(),
            points2d: vec![],
        };
        let pose = im.pose().expect("valid");
        let r = quaternion_matrix([h, 0.0, 0.0, h]);
        // A world point maps to R p + t in the camera; the pose maps it back.
        let p = [0.3, -0.7, 2.0];
        let cam: [f64; 3] =
            std::array::from_fn(|i| (0..3).map(|j| r[i][j] * p[j]).sum::<f64>() + im.tvec[i]);
        let back = pose.camera_to_world(cam);
        assert!((0..3).all(|i| (back[i] - p[i]).abs() < 1e-12), "{back:?}");
        let bad = Image {
            qvec: [0.0; 4],
            ..im
        };
        assert!(bad.pose().is_err());
    }
}
