//! A batch of rays on the device: what rendering uploads its host rays
//! ([`NormalizedRay`]) into, and what the extent casts its frustums along.

use burn::tensor::{Device, Tensor, TensorData};

use crate::geometry::NormalizedRay;

/// A batch of rays in the normalised frame (metric `t`) on the device: what
/// rendering uploads its host rays ([`NormalizedRay`]) into.
#[derive(Debug, Clone)]
pub struct Rays {
    /// Origins, `[n, 3]`.
    pub origins: Tensor<2>,
    /// Unnormalised directions, `[n, 3]`.
    pub directions: Tensor<2>,
    /// Cone radii at `t = 1`, `[n, 1]`.
    pub radii: Tensor<2>,
    /// Near bounds, `[n, 1]`.
    pub near: Tensor<2>,
    /// Far bounds, `[n, 1]`.
    pub far: Tensor<2>,
    /// Each ray's photograph's appearance code, `[n, appearance_dim]`, for
    /// a field with codes; `None`: the zero code (every view but a
    /// training photograph's).
    pub appearance: Option<Tensor<2>>,
}

impl Rays {
    /// Uploads normalised rays to `device`.
    pub fn from_normalized(rays: &[NormalizedRay], device: &Device) -> Rays {
        let n = rays.len();
        let vec3 = |f: &dyn Fn(&NormalizedRay) -> [f32; 3]| {
            let v: Vec<f32> = rays.iter().flat_map(f).collect();
            Tensor::from_data(TensorData::new(v, [n, 3]), device)
        };
        let scalar = |f: &dyn Fn(&NormalizedRay) -> f32| {
            let v: Vec<f32> = rays.iter().map(f).collect();
            Tensor::from_data(TensorData::new(v, [n, 1]), device)
        };
        Rays {
            origins: vec3(&|r: &NormalizedRay| r.origin),
            directions: vec3(&|r: &NormalizedRay| r.direction),
            radii: scalar(&|r: &NormalizedRay| r.radius),
            near: scalar(&|r: &NormalizedRay| r.near),
            far: scalar(&|r: &NormalizedRay| r.far.max(r.near)),
            appearance: None,
        }
    }

    /// The rays as their corrected cameras see them: origins shifted by
    /// each ray's `t`, directions turned by its `w` (see
    /// [`crate::pose::rotate`]); radii, bounds and codes as they were.
    ///
    /// # Shapes
    /// - `correction`: `[self.len(), 6]`, `[w | t]` as
    ///   [`crate::pose::PoseCorrection::per_ray`] gives it.
    pub fn corrected(self, correction: Tensor<2>) -> Rays {
        let [n, _] = correction.dims();
        let w = correction.clone().slice([0..n, 0..3]);
        let t = correction.slice([0..n, 3..6]);
        Rays {
            origins: self.origins + t,
            directions: crate::pose::rotate(self.directions, w),
            ..self
        }
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.origins.dims()[0]
    }

    /// Whether there are no rays.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
