//! Normalised disparity along rays (Mip-NeRF 360's "s-space"):
//! `s = (g(t) - g(near)) / (g(far) - g(near))` with `g(t) = 1/t`, so that
//! `s` runs from 0 at `near` to 1 at `far` and uniform steps in `s` are
//! uniform in disparity (dense near the camera, sparse far away).
//!
//! Both directions take `near > 0` and `far > near`; `far` may be huge
//! (`1e10`): only reciprocals of it are formed.

use burn::tensor::Tensor;

/// Metric distance to normalised disparity.
///
/// `t = near` maps to exactly 0 and `t = far` to exactly 1 (numerator and
/// denominator are then the same floating-point expression).
///
/// # Shapes
/// - `t`: `[rays, samples]`; `near`, `far`: `[rays, 1]`; output: like `t`.
pub fn t_to_s(t: Tensor<2>, near: Tensor<2>, far: Tensor<2>) -> Tensor<2> {
    let g_near = near.recip();
    let g_far = far.recip();
    t.recip().sub(g_near.clone()).div(g_far.sub(g_near))
}

/// Normalised disparity back to metric distance, the inverse of [`t_to_s`].
///
/// The disparity is interpolated as `s g(far) + (1 - s) g(near)` (not
/// `g(near) + s (g(far) - g(near))`) so that `s = 0` and `s = 1` give
/// `g(near)` and `g(far)` exactly, hence `near` and `far` up to the
/// rounding of two reciprocals.
///
/// # Shapes
/// - `s`: `[rays, samples]`; `near`, `far`: `[rays, 1]`; output: like `s`.
pub fn s_to_t(s: Tensor<2>, near: Tensor<2>, far: Tensor<2>) -> Tensor<2> {
    let g_near = near.recip();
    let g_far = far.recip();
    s.clone()
        .mul(g_far)
        .add(s.neg().add_scalar(1.0).mul(g_near))
        .recip()
}
