//! COLMAP's camera models (the table of ids, names and parameter counts)
//! and cameras as COLMAP stores them, with their conversion to this
//! crate's [`Intrinsics`].

use model::geometry::{Distortion, Intrinsics};

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
}
