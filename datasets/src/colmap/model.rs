//! The content of a COLMAP sparse model (cameras, images, 3D points) as
//! COLMAP stores it, the table of COLMAP's camera models, and the
//! conversions to this crate's geometry: [`Camera::intrinsics`] and
//! [`Image::pose`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use model::geometry::{Distortion, Intrinsics, Pose};

use crate::error::DatasetError;

/// COLMAP's camera models, by id (`colmap/sensor/models.h`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CameraModel {
    /// 0: `f, cx, cy`.
    SimplePinhole,
    /// 1: `fx, fy, cx, cy`.
    Pinhole,
    /// 2: `f, cx, cy, k`.
    SimpleRadial,
    /// 3: `f, cx, cy, k1, k2`.
    Radial,
    /// 4: `fx, fy, cx, cy, k1, k2, p1, p2`.
    Opencv,
    /// 5: `fx, fy, cx, cy, k1, k2, k3, k4` (equidistant fisheye).
    OpencvFisheye,
    /// 6: `fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6`.
    FullOpencv,
    /// 7: `fx, fy, cx, cy, omega`.
    Fov,
    /// 8: `f, cx, cy, k`.
    SimpleRadialFisheye,
    /// 9: `f, cx, cy, k1, k2`.
    RadialFisheye,
    /// 10: `fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1`.
    ThinPrismFisheye,
    /// 11: `fx, fy, cx, cy, k0..k5, p0, p1, s0..s3`.
    RadTanThinPrismFisheye,
}

/// Every model with its id, name and number of parameters.
const MODELS: [(CameraModel, i32, &str, usize); 12] = [
    (CameraModel::SimplePinhole, 0, "SIMPLE_PINHOLE", 3),
    (CameraModel::Pinhole, 1, "PINHOLE", 4),
    (CameraModel::SimpleRadial, 2, "SIMPLE_RADIAL", 4),
    (CameraModel::Radial, 3, "RADIAL", 5),
    (CameraModel::Opencv, 4, "OPENCV", 8),
    (CameraModel::OpencvFisheye, 5, "OPENCV_FISHEYE", 8),
    (CameraModel::FullOpencv, 6, "FULL_OPENCV", 12),
    (CameraModel::Fov, 7, "FOV", 5),
    (
        CameraModel::SimpleRadialFisheye,
        8,
        "SIMPLE_RADIAL_FISHEYE",
        4,
    ),
    (CameraModel::RadialFisheye, 9, "RADIAL_FISHEYE", 5),
    (CameraModel::ThinPrismFisheye, 10, "THIN_PRISM_FISHEYE", 12),
    (
        CameraModel::RadTanThinPrismFisheye,
        11,
        "RAD_TAN_THIN_PRISM_FISHEYE",
        16,
    ),
];

impl CameraModel {
    fn entry(self) -> (CameraModel, i32, &'static str, usize) {
        MODELS
            .into_iter()
            .find(|m| m.0 == self)
            .unwrap_or(MODELS[0])
    }

    /// The model with COLMAP's numeric id (as binary models store it).
    pub fn from_id(id: i32) -> Option<Self> {
        MODELS.into_iter().find(|m| m.1 == id).map(|m| m.0)
    }

    /// The model with COLMAP's name (as text models store it).
    pub fn from_name(name: &str) -> Option<Self> {
        MODELS.into_iter().find(|m| m.2 == name).map(|m| m.0)
    }

    /// COLMAP's numeric id.
    pub fn id(self) -> i32 {
        self.entry().1
    }

    /// COLMAP's name (`PINHOLE`, `OPENCV`, ...).
    pub fn name(self) -> &'static str {
        self.entry().2
    }

    /// Number of parameters.
    pub fn num_params(self) -> usize {
        self.entry().3
    }

    /// True for the models whose lens this crate can represent (pinhole
    /// with at most OpenCV's radial-tangential distortion).
    pub fn is_supported(self) -> bool {
        matches!(
            self,
            Self::SimplePinhole | Self::Pinhole | Self::SimpleRadial | Self::Radial | Self::Opencv
        )
    }
}

/// Names of the models the loader reads, for messages.
pub const SUPPORTED_MODELS: &str = "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL and OPENCV";

/// A camera as COLMAP stores it (principal point counted from the pixel
/// corner).
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Camera id.
    pub id: u32,
    /// Camera model.
    pub model: CameraModel,
    /// Image width, pixels.
    pub width: u64,
    /// Image height, pixels.
    pub height: u64,
    /// The model's parameters, in COLMAP's order.
    pub params: Vec<f64>,
}

impl Camera {
    /// This camera as [`Intrinsics`] (pixel-centre convention:
    /// `cx = cx_colmap - 0.5`), or why it cannot be: a model other than the
    /// [supported ones](SUPPORTED_MODELS), a bad size or a bad parameter.
    pub fn intrinsics(&self) -> Result<Intrinsics, String> {
        let name = self.model.name();
        if !self.model.is_supported() {
            return Err(format!(
                "camera {} uses the {name} model, which this loader does not read (it reads \
                 {SUPPORTED_MODELS}); run COLMAP's image_undistorter on the reconstruction, \
                 which writes undistorted images with PINHOLE cameras, and load its output",
                self.id
            ));
        }
        if self.params.len() != self.model.num_params() {
            return Err(format!(
                "camera {}: {name} takes {} parameters, found {}",
                self.id,
                self.model.num_params(),
                self.params.len()
            ));
        }
        if let Some(v) = self.params.iter().find(|v| !v.is_finite()) {
            return Err(format!("camera {}: non-finite parameter {v}", self.id));
        }
        let (Ok(width), Ok(height)) = (u32::try_from(self.width), u32::try_from(self.height))
        else {
            return Err(format!(
                "camera {}: size {}x{} is too large",
                self.id, self.width, self.height
            ));
        };
        if width == 0 || height == 0 {
            return Err(format!("camera {}: size {width}x{height}", self.id));
        }
        let p = &self.params;
        let mut d = Distortion::NONE;
        let (fx, fy, cx, cy) = match self.model {
            CameraModel::SimplePinhole => (p[0], p[0], p[1], p[2]),
            CameraModel::SimpleRadial => {
                d.k1 = p[3];
                (p[0], p[0], p[1], p[2])
            }
            CameraModel::Radial => {
                (d.k1, d.k2) = (p[3], p[4]);
                (p[0], p[0], p[1], p[2])
            }
            CameraModel::Opencv => {
                (d.k1, d.k2, d.p1, d.p2) = (p[4], p[5], p[6], p[7]);
                (p[0], p[1], p[2], p[3])
            }
            _ => (p[0], p[1], p[2], p[3]),
        };
        if !(fx > 0.0 && fy > 0.0) {
            return Err(format!(
                "camera {}: focal length must be positive, found {fx}, {fy}",
                self.id
            ));
        }
        Ok(Intrinsics {
            width,
            height,
            fx,
            fy,
            cx: cx - 0.5,
            cy: cy - 0.5,
            distortion: d,
        })
    }
}

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
    fn model_table_round_trips_and_counts_parameters() {
        for id in 0..12 {
            let m = CameraModel::from_id(id).expect("known id");
            assert_eq!(m.id(), id);
            assert_eq!(CameraModel::from_name(m.name()), Some(m));
        }
        assert_eq!(CameraModel::from_id(12), None);
        assert_eq!(CameraModel::from_name("pinhole"), None);
        let counts: Vec<usize> = (0..12)
            .filter_map(CameraModel::from_id)
            .map(CameraModel::num_params)
            .collect();
        assert_eq!(counts, [3, 4, 4, 5, 8, 8, 12, 5, 4, 5, 12, 16]);
    }

    #[test]
    fn opencv_parameters_map_to_the_distortion() {
        let cam = Camera {
            id: 1,
            model: CameraModel::Opencv,
            width: 64,
            height: 48,
            params: vec![50.0, 52.0, 32.0, 24.0, 0.1, -0.02, 0.003, -0.004],
        };
        let k = cam.intrinsics().expect("supported");
        assert_eq!((k.fx, k.fy, k.cx, k.cy), (50.0, 52.0, 31.5, 23.5));
        let d = k.distortion;
        assert_eq!(
            (d.k1, d.k2, d.p1, d.p2, d.k3),
            (0.1, -0.02, 0.003, -0.004, 0.0)
        );
        let fisheye = Camera {
            model: CameraModel::OpencvFisheye,
            ..cam
        };
        let msg = fisheye.intrinsics().expect_err("unsupported");
        assert!(msg.contains("OPENCV_FISHEYE") && msg.contains("image_undistorter"));
    }

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
