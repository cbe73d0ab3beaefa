//! An unbounded scene in the field's normalised frame: the ball that the
//! contraction keeps as it is, where rays start and end, and the frustum
//! Gaussians (and point queries) pushed through the contraction.
//!
//! The contraction maps the ball of radius `radius` to itself and all of
//! space to the ball of radius `2 radius`; the field then sees contracted
//! coordinates scaled by [`CONTRACTED_SCALE`] / `radius`, so that they fill
//! `[-pi, pi]^3` as a box field's coordinates do and the same encoding
//! degrees apply.

use burn::config::Config;
use burn::tensor::Tensor;

use super::contract::{cast_rays_contracted, contract, contract_gaussian, cov_diagonal};
use crate::geometry::NormalizedRay;
use crate::mip::{FrustumGaussians, frustum_means};

/// Contracted coordinates (in the ball of radius 2) are scaled by this
/// (`pi / 2`) before the encoding.
pub const CONTRACTED_SCALE: f32 = std::f32::consts::FRAC_PI_2;

/// Configuration of an unbounded field (Mip-NeRF 360's contraction).
#[derive(Config, Debug)]
pub struct UnboundedConfig {
    /// Radius of the ball, in normalised units around the origin, that the
    /// contraction leaves unchanged: the region the cameras see in detail
    /// (`train` takes the ball around the scene box). Space beyond it is
    /// contracted.
    pub radius: f32,
    /// Near bound, as a distance from the ray's origin in multiples of
    /// `radius` (Mip-NeRF 360: 0.2). Samples are spaced in disparity from
    /// here, so half of them fall within twice this distance: a smaller
    /// value spends them on space next to the camera.
    #[config(default = 0.2)]
    pub near: f32,
    /// Far bound, as a distance from the ray's origin in multiples of
    /// `radius` (effectively infinite: at `1e4` a point contracts to within
    /// `1e-4` of the outer sphere).
    #[config(default = 1e4)]
    pub far: f32,
    /// Whether a ray starts where it enters the scene box when that lies
    /// beyond `near` (`Some(true)`): a capture walked around an object has
    /// its cameras outside the box, and the space between a camera and the
    /// box is seen by that camera alone, so that a field free to fill it
    /// explains each photograph with colour there, which every other view
    /// sees from elsewhere. A ray that misses the box starts where it passes
    /// closest to the box's centre. Cameras inside the box (a room) are
    /// unaffected. `None` (runs written before this key) is `false`, rays
    /// from `near` as those runs were trained; `train` sets `Some(true)`.
    pub start_at_box: Option<bool>,
}

impl UnboundedConfig {
    /// `ray` with the bounds an unbounded field renders it over: from
    /// `near * radius` normalised units from its origin (or, with
    /// [`Self::start_at_box`], from where it enters the scene box, given
    /// by the bounds the ray carries, when that is farther) to
    /// `far * radius` normalised units from its origin.
    pub fn bound(&self, ray: &NormalizedRay) -> NormalizedRay {
        let d = ray.direction;
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-20);
        let mut near = (self.near * self.radius / len).max(1e-6);
        let far = (self.far * self.radius / len).max(near);
        if self.start_at_box == Some(true) {
            near = near.max(box_entry(ray)).min(far);
        }
        NormalizedRay { near, far, ..*ray }
    }

    /// The frustums between consecutive fence posts as Gaussians, pushed
    /// through the contraction and scaled into the encoding's range.
    ///
    /// # Shapes
    /// - `t_vals`: `[rays, samples + 1]`; `origins`, `directions`:
    ///   `[rays, 3]`; `radii`: `[rays, 1]`; outputs: `[rays, samples, 3]`.
    pub fn frustums(
        &self,
        t_vals: Tensor<2>,
        origins: Tensor<2>,
        directions: Tensor<2>,
        radii: Tensor<2>,
    ) -> FrustumGaussians {
        let inv = 1.0 / self.radius;
        let g = cast_rays_contracted(
            t_vals,
            origins.mul_scalar(inv),
            directions.mul_scalar(inv),
            radii.mul_scalar(inv),
        );
        FrustumGaussians {
            mean: g.mean.mul_scalar(CONTRACTED_SCALE),
            cov_diag: g.cov_diag.mul_scalar(CONTRACTED_SCALE * CONTRACTED_SCALE),
        }
    }

    /// The means of [`UnboundedConfig::frustums`]' Gaussians alone
    /// (contracted and scaled the same way, the same bits), for a field
    /// that reads no covariance.
    ///
    /// # Shapes
    /// - `t_vals`: `[rays, samples + 1]`; `origins`, `directions`:
    ///   `[rays, 3]`; output: `[rays, samples, 3]`.
    pub fn frustum_means(
        &self,
        t_vals: Tensor<2>,
        origins: Tensor<2>,
        directions: Tensor<2>,
    ) -> Tensor<3> {
        let inv = 1.0 / self.radius;
        let mean = frustum_means(t_vals, origins.mul_scalar(inv), directions.mul_scalar(inv));
        contract(mean).mul_scalar(CONTRACTED_SCALE)
    }

    /// Points as isotropic Gaussians of standard deviation `std` (normalised
    /// units), pushed through the contraction and scaled like
    /// [`UnboundedConfig::frustums`].
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; outputs: `[n, 1, 3]`.
    pub fn points(&self, points: Tensor<2>, std: f32) -> FrustumGaussians {
        let [n, _] = points.dims();
        let device = points.device();
        let var = (std / self.radius).powi(2);
        let eye: Tensor<2> = Tensor::eye(3, &device);
        let cov = eye
            .mul_scalar(var)
            .reshape([1, 1, 3, 3])
            .expand([n, 1, 3, 3]);
        let mean = points.mul_scalar(1.0 / self.radius).unsqueeze_dim::<3>(1);
        let (mean, cov) = contract_gaussian(mean, cov);
        FrustumGaussians {
            mean: mean.mul_scalar(CONTRACTED_SCALE),
            cov_diag: cov_diagonal(cov).mul_scalar(CONTRACTED_SCALE * CONTRACTED_SCALE),
        }
    }
}

/// Where `ray` enters the scene box: its near bound when it crosses the
/// box (`far > near`, as [`crate::geometry::SceneBox::normalize_ray`]
/// makes them), else the `t` where it passes closest to the box's centre
/// (the origin of the normalised frame), and 0 where that lies behind it.
pub fn box_entry(ray: &NormalizedRay) -> f32 {
    if ray.far > ray.near {
        return ray.near;
    }
    let (o, d) = (ray.origin, ray.direction);
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let od = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
    if dd > 0.0 { (-od / dd).max(0.0) } else { 0.0 }
}
