//! Per-photograph camera pose corrections, learned with the field.
//!
//! Poses estimated from a few widely spaced photographs (COLMAP on 20
//! views, a phone's SLAM) can be off by more than a pixel. A field then
//! fits each photograph by placing colour along its slightly wrong rays,
//! which other views see from elsewhere. Six numbers per photograph, a
//! small rotation of the camera about its own centre and a shift of that
//! centre, let the photographs' rays move into agreement instead, as
//! nerfstudio's camera optimiser and BARF do.
//!
//! The correction is applied to a ray on the device (so that the loss
//! reaches it, [`crate::Rays::corrected`]): the origin moves by `t`, the direction turns by the
//! rotation `exp([w]x)` (Rodrigues' formula), both in the scene's axes.
//! Radii and bounds stay. A frame without a correction (a novel view, a
//! photograph past the table) gets none.

use burn::config::Config;
use burn::module::{Module, Param};
use burn::tensor::{Bool, Device, Tensor};

use crate::exposure::frame_rows;

/// Configuration of [`PoseCorrection`].
#[derive(Config, Debug)]
pub struct PoseCorrectionConfig {
    /// Photographs with a correction each: frames `0..images` of the scene.
    pub images: usize,
}

impl PoseCorrectionConfig {
    /// Builds the corrections, all zero (the poses as given) to start.
    pub fn init(&self, device: &Device) -> PoseCorrection {
        PoseCorrection {
            params: Param::from_tensor(Tensor::zeros([self.images.max(1), 6], device)),
            images: self.images,
        }
    }
}

/// The learned pose correction of each training photograph (see the module
/// docs).
#[derive(Module, Debug)]
pub struct PoseCorrection {
    /// `[images, 6]`: per photograph, the rotation vector `w` (axis times
    /// angle in radians), then the shift `t` of the camera centre.
    pub params: Param<Tensor<2>>,
    /// Photographs with a correction.
    #[module(skip)]
    pub images: usize,
}

impl PoseCorrection {
    /// The correction of each ray, from the frame it was drawn from; zero
    /// rows for frames without one.
    ///
    /// # Shapes
    /// - output: `[frames.len(), 6]`.
    pub fn per_ray(&self, frames: &[usize]) -> Tensor<2> {
        frame_rows(self.params.val(), frames, self.images)
    }
}

/// Below this squared angle the rotation's coefficients come from their
/// Taylor series (exact to float precision there): the closed forms divide
/// by the angle, whose gradient at zero is not finite.
const SMALL_ANGLE_SQ: f32 = 1e-4;

/// `a x b` row by row.
///
/// # Shapes
/// - `a`, `b`: `[n, 3]`; output `[n, 3]`.
pub fn cross(a: Tensor<2>, b: Tensor<2>) -> Tensor<2> {
    let [n, _] = a.dims();
    let c = |t: &Tensor<2>, i: usize| t.clone().slice([0..n, i..i + 1]);
    let (a0, a1, a2) = (c(&a, 0), c(&a, 1), c(&a, 2));
    let (b0, b1, b2) = (c(&b, 0), c(&b, 1), c(&b, 2));
    Tensor::cat(
        vec![
            a1.clone() * b2.clone() - a2.clone() * b1.clone(),
            a2 * b0.clone() - a0.clone() * b2,
            a0 * b1 - a1 * b0,
        ],
        1,
    )
}

/// `v` turned by the rotation `exp([w]x)`, row by row (Rodrigues' formula):
/// `v + sin(θ)/θ (w x v) + (1 - cos θ)/θ² (w x (w x v))` with `θ = |w|`,
/// the second coefficient as `2 sin²(θ/2)/θ²` (no cancellation for small
/// angles), both from their Taylor series where `θ² < 1e-4`. Finite values
/// and gradients for every `w`, `w = 0` included.
///
/// # Shapes
/// - `v`, `w`: `[n, 3]`; output `[n, 3]`.
pub fn rotate(v: Tensor<2>, w: Tensor<2>) -> Tensor<2> {
    let theta_sq = w.clone().square().sum_dim(1); // [n, 1]
    let small: Tensor<2, Bool> = theta_sq.clone().lower_elem(SMALL_ANGLE_SQ);
    // The closed forms never see a small angle, so their (masked-out)
    // gradient there is finite too.
    let safe = theta_sq.clone().mask_fill(small.clone(), 1.0);
    let theta = safe.clone().sqrt();
    let sinc = theta.clone().sin() / theta.clone();
    let half = theta.clone().div_scalar(2.0);
    let versine = (half.clone().sin() / half).square().div_scalar(2.0);
    // sin θ/θ = 1 - θ²/6 + θ⁴/120, (1 - cos θ)/θ² = 1/2 - θ²/24 + θ⁴/720.
    let t2 = theta_sq.clone();
    let t4 = theta_sq.clone().square();
    let sinc_series = t2.clone().div_scalar(-6.0).add_scalar(1.0) + t4.clone().div_scalar(120.0);
    let versine_series = t2.div_scalar(-24.0).add_scalar(0.5) + t4.div_scalar(720.0);
    let sinc = sinc.mask_where(small.clone(), sinc_series);
    let versine = versine.mask_where(small, versine_series);
    let wv = cross(w.clone(), v.clone());
    let wwv = cross(w, wv.clone());
    v + wv * sinc + wwv * versine
}
