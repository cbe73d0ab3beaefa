//! Similarity transforms (rotation, uniform scale, translation) between a
//! capture's own world frame and the frame a scene is trained in.

use super::{Pose, Vec3};

/// `p -> scale * R p + translation`, with `R` a rotation (row-major).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Similarity {
    /// Rotation, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Uniform scale (positive).
    pub scale: f64,
    /// Translation, applied after rotation and scale.
    pub translation: Vec3,
}

impl Similarity {
    /// The identity.
    pub const IDENTITY: Self = Self {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        scale: 1.0,
        translation: [0.0; 3],
    };

    /// Rotates (and scales) a direction: `scale * R v`.
    pub fn apply_vector(&self, v: Vec3) -> Vec3 {
        let r = &self.rotation;
        std::array::from_fn(|i| self.scale * (r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2]))
    }

    /// Maps a point.
    pub fn apply_point(&self, p: Vec3) -> Vec3 {
        let v = self.apply_vector(p);
        std::array::from_fn(|i| v[i] + self.translation[i])
    }

    /// Maps a camera-to-world pose: its centre as a point, its axes rotated
    /// (a similarity keeps them orthonormal; depths scale by `scale`).
    pub fn apply_pose(&self, pose: &Pose) -> Pose {
        let r = &self.rotation;
        let c = &pose.rotation;
        let rotation = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| r[i][k] * c[k][j]).sum())
        });
        Pose {
            rotation,
            translation: self.apply_point(pose.translation),
        }
    }

    /// The inverse map: `p -> R^T (p - translation) / scale`.
    pub fn inverse(&self) -> Self {
        let r = &self.rotation;
        let rt: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| r[j][i]));
        let s = 1.0 / self.scale;
        let t = self.translation;
        let back: Vec3 =
            std::array::from_fn(|i| -s * (rt[i][0] * t[0] + rt[i][1] * t[1] + rt[i][2] * t[2]));
        Self {
            rotation: rt,
            scale: s,
            translation: back,
        }
    }

    /// `self` after `first`: `p -> self(first(p))`.
    pub fn compose(&self, first: &Self) -> Self {
        let r = &self.rotation;
        let f = &first.rotation;
        Self {
            rotation: std::array::from_fn(|i| {
                std::array::from_fn(|j| (0..3).map(|k| r[i][k] * f[k][j]).sum())
            }),
            scale: self.scale * first.scale,
            translation: self.apply_point(first.translation),
        }
    }

    /// Row-major 4x4 matrix `[[sR, t], [0, 1]]`.
    pub fn to_matrix(&self) -> [[f64; 4]; 4] {
        let r = &self.rotation;
        let s = self.scale;
        let t = &self.translation;
        [
            [s * r[0][0], s * r[0][1], s * r[0][2], t[0]],
            [s * r[1][0], s * r[1][1], s * r[1][2], t[1]],
            [s * r[2][0], s * r[2][1], s * r[2][2], t[2]],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> Similarity {
        let (c, s) = (0.6f64, 0.8f64);
        Similarity {
            rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            scale: 2.5,
            translation: [1.0, -2.0, 0.5],
        }
    }

    #[test]
    fn inverse_and_compose_round_trip() {
        let a = example();
        let p = [0.3, -1.2, 4.0];
        let back = a.inverse().apply_point(a.apply_point(p));
        assert!((0..3).all(|i| (back[i] - p[i]).abs() < 1e-12), "{back:?}");
        let id = a.compose(&a.inverse());
        let q = id.apply_point(p);
        assert!((0..3).all(|i| (q[i] - p[i]).abs() < 1e-12));
        assert!((id.scale - 1.0).abs() < 1e-12);
        // The matrix form maps points the same way.
        let m = a.to_matrix();
        let via: Vec3 =
            std::array::from_fn(|i| (0..3).map(|j| m[i][j] * p[j]).sum::<f64>() + m[i][3]);
        let direct = a.apply_point(p);
        assert!((0..3).all(|i| (via[i] - direct[i]).abs() < 1e-12));
    }

    /// A pose's camera sees a mapped point where it saw the original one,
    /// at `scale` times the depth.
    #[test]
    fn mapped_pose_sees_mapped_points_at_scaled_depth() {
        let a = example();
        let pose =
            super::super::look_at([3.0, 1.0, 2.0], [0.0, 0.5, 0.0], [0.0, 0.0, 1.0]).expect("pose");
        let p = [0.2, 0.4, -0.3];
        let before = pose.world_to_camera(p);
        let after = a.apply_pose(&pose).world_to_camera(a.apply_point(p));
        assert!((0..3).all(|i| (after[i] - a.scale * before[i]).abs() < 1e-12));
        assert!(a.apply_pose(&pose).orthonormality_error() < 1e-12);
    }
}
