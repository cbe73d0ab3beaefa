//! Cameras, poses, rays and the scene box, in plain `f64` Rust (no Burn).
//!
//! Conventions used everywhere in the workspace:
//! - Poses are camera-to-world in the OpenCV convention (x right, y down,
//!   z forward). Loaders convert at the border ([`Pose::from_opengl`]).
//! - Pixel `(i, j)` has its centre at image coordinate `(u, v) = (i, j)`, so a
//!   principal point in the middle of a `w`-wide image is `cx = (w - 1) / 2`.
//! - Ray directions are *not* normalised: their camera-space z component is
//!   1, so the ray parameter `t` is the z-depth in metres. That is what depth
//!   sensors measure, so rendered depth compares directly with depth maps.
//! - The field sees coordinates normalised into the [`SceneBox`] (a uniform
//!   scale, so cones stay circular); `t`, `near` and `far` stay metric.

use std::fmt;

mod distortion;
mod footprint;
mod scene_box;
mod similarity;

pub use distortion::Distortion;
pub use footprint::{aligning_yaw, footprint_area, yaw_rotation};
pub use scene_box::{NormalizedRay, SceneBox};
pub use similarity::Similarity;

/// A 3-vector in `f64`.
pub type Vec3 = [f64; 3];

/// Geometry errors (bad poses, degenerate look-at input).
#[derive(Debug, Clone, PartialEq)]
pub enum GeometryError {
    /// The matrix is not a rigid transform; `error` is the largest deviation
    /// of `R^T R` from the identity or of the last row from `[0, 0, 0, 1]`.
    NotRigid {
        /// Largest absolute deviation found.
        error: f64,
    },
    /// A value is NaN or infinite.
    NonFinite,
    /// `look_at` was asked to look at its own position.
    CoincidentPoints,
}

impl fmt::Display for GeometryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GeometryError::NotRigid { error } => write!(
                f,
                "pose is not a rigid transform (rotation not orthonormal or bad last row; deviation {error:.3e})"
            ),
            GeometryError::NonFinite => write!(f, "pose contains NaN or infinite values"),
            GeometryError::CoincidentPoints => {
                write!(f, "look_at: camera position equals the target")
            }
        }
    }
}

impl std::error::Error for GeometryError {}

/// Dot product.
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product.
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Euclidean norm.
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// `a - b`.
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a + s * b`.
pub fn add_scaled(a: Vec3, s: f64, b: Vec3) -> Vec3 {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

fn normalize(a: Vec3) -> Vec3 {
    let n = norm(a);
    [a[0] / n, a[1] / n, a[2] / n]
}

/// Pinhole intrinsics in pixels (OpenCV pixel-centre convention), with the
/// lens distortion of the images they describe (none for most scenes).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x (pixel `i` has its centre at `u = i`).
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
    /// Lens distortion of the image (in normalised coordinates, so it does
    /// not change when the image is resampled).
    #[serde(default, skip_serializing_if = "Distortion::is_none")]
    pub distortion: Distortion,
}

impl Intrinsics {
    /// Intrinsics from a horizontal field of view (radians) with the principal
    /// point in the image centre, as Blender scenes specify them.
    pub fn from_fov_x(width: u32, height: u32, fov_x: f64) -> Self {
        let f = 0.5 * width as f64 / (0.5 * fov_x).tan();
        Self {
            width,
            height,
            fx: f,
            fy: f,
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
            distortion: Distortion::NONE,
        }
    }

    /// The same camera resampled to `width x height`: pixel edges map to pixel
    /// edges, so `cx' = (cx + 0.5) sx - 0.5` and `fx' = fx sx`.
    pub fn scaled(&self, width: u32, height: u32) -> Self {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        Self {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            distortion: self.distortion,
        }
    }

    /// Mip-NeRF base radius at `t = 1`: `dx * 2 / sqrt(12)`, where `dx` is the
    /// distance between neighbouring pixel directions on the `z = 1` plane.
    pub fn base_radius(&self) -> f64 {
        let dx = 0.5 * (1.0 / self.fx + 1.0 / self.fy);
        dx * 2.0 / 12f64.sqrt()
    }

    /// Direction in camera space (z = 1) through image point `(u, v)`,
    /// undistorted.
    pub fn camera_direction(&self, u: f64, v: f64) -> Vec3 {
        let (x, y) = self
            .distortion
            .undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        [x, y, 1.0]
    }

    /// Image point of the camera-space direction `(x, y, 1)`, distorted.
    pub fn image_point(&self, x: f64, y: f64) -> (f64, f64) {
        let (xd, yd) = self.distortion.distort(x, y);
        (self.fx * xd + self.cx, self.fy * yd + self.cy)
    }
}

/// A rigid camera-to-world transform, OpenCV camera axes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pose {
    /// Rotation, row-major; columns are the camera axes in world coordinates.
    pub rotation: [[f64; 3]; 3],
    /// Camera centre in world coordinates.
    pub translation: Vec3,
}

/// Tolerance used when checking that a loaded matrix is a rigid transform.
pub const RIGID_TOLERANCE: f64 = 1e-3;

impl Pose {
    /// The identity pose.
    pub fn identity() -> Self {
        Self {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
        }
    }

    /// A pose from a row-major 4x4 camera-to-world matrix in the OpenCV
    /// convention, rejecting non-finite values and non-rigid matrices.
    pub fn from_matrix(m: [[f64; 4]; 4]) -> Result<Self, GeometryError> {
        if m.iter().flatten().any(|v| !v.is_finite()) {
            return Err(GeometryError::NonFinite);
        }
        let pose = Self {
            rotation: [
                [m[0][0], m[0][1], m[0][2]],
                [m[1][0], m[1][1], m[1][2]],
                [m[2][0], m[2][1], m[2][2]],
            ],
            translation: [m[0][3], m[1][3], m[2][3]],
        };
        let mut error = (m[3][0].abs())
            .max(m[3][1].abs())
            .max(m[3][2].abs())
            .max((m[3][3] - 1.0).abs());
        error = error.max(pose.orthonormality_error());
        if error > RIGID_TOLERANCE {
            return Err(GeometryError::NotRigid { error });
        }
        Ok(pose)
    }

    /// A pose from a camera-to-world matrix in the OpenGL / Blender convention
    /// (x right, y up, z backward): the camera's y and z axes are flipped.
    pub fn from_opengl(m: [[f64; 4]; 4]) -> Result<Self, GeometryError> {
        let mut cv = m;
        for row in cv.iter_mut().take(3) {
            row[1] = -row[1];
            row[2] = -row[2];
        }
        Self::from_matrix(cv)
    }

    /// Row-major 4x4 camera-to-world matrix, OpenCV convention.
    pub fn to_matrix(&self) -> [[f64; 4]; 4] {
        let r = &self.rotation;
        let t = &self.translation;
        [
            [r[0][0], r[0][1], r[0][2], t[0]],
            [r[1][0], r[1][1], r[1][2], t[1]],
            [r[2][0], r[2][1], r[2][2], t[2]],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// Row-major 4x4 camera-to-world matrix, OpenGL convention.
    pub fn to_opengl(&self) -> [[f64; 4]; 4] {
        let mut m = self.to_matrix();
        for row in m.iter_mut().take(3) {
            row[1] = -row[1];
            row[2] = -row[2];
        }
        m
    }

    /// Largest deviation of `R^T R` from the identity.
    pub fn orthonormality_error(&self) -> f64 {
        let r = &self.rotation;
        let mut err: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                let target = if i == j { 1.0 } else { 0.0 };
                err = err.max((v - target).abs());
            }
        }
        err
    }

    /// Camera centre in world coordinates.
    pub fn center(&self) -> Vec3 {
        self.translation
    }

    /// Rotates a camera-space vector into world space.
    pub fn rotate(&self, v: Vec3) -> Vec3 {
        let r = &self.rotation;
        [
            r[0][0] * v[0] + r[0][1] * v[1] + r[0][2] * v[2],
            r[1][0] * v[0] + r[1][1] * v[1] + r[1][2] * v[2],
            r[2][0] * v[0] + r[2][1] * v[1] + r[2][2] * v[2],
        ]
    }

    /// Maps a camera-space point into world space.
    pub fn camera_to_world(&self, p: Vec3) -> Vec3 {
        let v = self.rotate(p);
        [
            v[0] + self.translation[0],
            v[1] + self.translation[1],
            v[2] + self.translation[2],
        ]
    }

    /// Maps a world-space point into camera space.
    pub fn world_to_camera(&self, p: Vec3) -> Vec3 {
        let d = sub(p, self.translation);
        let r = &self.rotation;
        [
            r[0][0] * d[0] + r[1][0] * d[1] + r[2][0] * d[2],
            r[0][1] * d[0] + r[1][1] * d[1] + r[2][1] * d[2],
            r[0][2] * d[0] + r[1][2] * d[1] + r[2][2] * d[2],
        ]
    }

    /// Viewing direction (camera z axis) in world space.
    pub fn forward(&self) -> Vec3 {
        [
            self.rotation[0][2],
            self.rotation[1][2],
            self.rotation[2][2],
        ]
    }
}

/// A ray in world coordinates: `origin + t * direction`, `t` = z-depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Ray origin (camera centre).
    pub origin: Vec3,
    /// Unnormalised direction with camera-space z = 1.
    pub direction: Vec3,
    /// Cone radius at `t = 1` (Mip-NeRF base radius).
    pub radius: f64,
}

/// A point projected into an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// Image x coordinate (pixel centres at integers).
    pub u: f64,
    /// Image y coordinate.
    pub v: f64,
    /// Depth along the camera z axis, metres.
    pub z: f64,
}

/// Intrinsics and pose of one view.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Camera-to-world pose (OpenCV).
    pub pose: Pose,
}

impl Camera {
    /// The ray through image point `(u, v)`; pixel `(i, j)` is `(i as f64, j as f64)`.
    pub fn ray(&self, u: f64, v: f64) -> Ray {
        Ray {
            origin: self.pose.center(),
            direction: self.pose.rotate(self.intrinsics.camera_direction(u, v)),
            radius: self.intrinsics.base_radius(),
        }
    }

    /// Projects a world point; `None` when it lies behind the camera (z <= 0).
    /// The result may fall outside the image.
    pub fn project(&self, p: Vec3) -> Option<Projection> {
        let c = self.pose.world_to_camera(p);
        if c[2] <= 0.0 || !c[2].is_finite() {
            return None;
        }
        let (u, v) = self.intrinsics.image_point(c[0] / c[2], c[1] / c[2]);
        Some(Projection { u, v, z: c[2] })
    }

    /// The same view at another resolution.
    pub fn scaled(&self, width: u32, height: u32) -> Self {
        Self {
            intrinsics: self.intrinsics.scaled(width, height),
            pose: self.pose,
        }
    }
}

/// Pose of a camera at `position` looking at `target` (OpenCV axes: z towards
/// the target, y pointing away from `up`). When the view direction is parallel
/// to `up`, another world axis is used as the up hint, so the result is always
/// a valid rotation.
pub fn look_at(position: Vec3, target: Vec3, up: Vec3) -> Result<Pose, GeometryError> {
    if position
        .iter()
        .chain(&target)
        .chain(&up)
        .any(|v| !v.is_finite())
    {
        return Err(GeometryError::NonFinite);
    }
    let forward = sub(target, position);
    if norm(forward) < 1e-12 {
        return Err(GeometryError::CoincidentPoints);
    }
    let z = normalize(forward);
    let mut hint = up;
    if norm(hint) < 1e-12 || norm(cross(z, normalize(hint))) < 1e-6 {
        // Pick the world axis least aligned with the view direction.
        let abs = [z[0].abs(), z[1].abs(), z[2].abs()];
        let i = (0..3)
            .min_by(|&a, &b| abs[a].total_cmp(&abs[b]))
            .unwrap_or(0);
        hint = [0.0; 3];
        hint[i] = 1.0;
    }
    // x = z x up and y = z x x = -(up minus its component along z): y points
    // away from up, as the OpenCV convention wants, and x, y, z is right-handed.
    let x = normalize(cross(z, hint));
    let y = cross(z, x);
    Ok(Pose {
        rotation: [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]],
        translation: position,
    })
}
