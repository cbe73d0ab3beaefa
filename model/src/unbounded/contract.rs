//! The scene contraction of Mip-NeRF 360 (eq. 10),
//! `contract(x) = x` for `|x| <= 1`, else `(2 - 1/|x|) x / |x|`, which maps
//! all of space into the ball of radius 2, and Gaussians pushed through it
//! by linearisation (`mean' = contract(mean)`, `cov' = J cov J^T`).
//!
//! Both the map and its Jacobian have the form `a(r)` and `b(r)` times
//! `x`-built terms, with `r = |x|` and `n = x / r`:
//!
//! ```text
//! contract(x) = a x                      a = (2 - 1/r) / r  (1 inside)
//! J(x)        = a I + b n n^T            b = -2 (1 - 1/r) / r  (0 inside)
//! ```
//!
//! Both are continuous at `r = 1` (`a = 1`, `b = 0` there), so the
//! contraction is C1. Only `1/r` is ever formed (never `r^4` or `x x^T`
//! unnormalised), which keeps every intermediate within f32 range for
//! `|x|` up to about `1e19` (where `|x|^2` overflows).

use crate::mip::{FrustumGaussians, conical_frustum_to_gaussian, interval_ends, points_along};
use burn::tensor::{Bool, Device, Tensor, TensorData};

/// Floor on `|x|^2` (f32 machine epsilon, as multinerf): `1/|x|` stays
/// finite at the origin, and the clamp's zero gradient below it keeps the
/// square root's infinite slope at 0 out of the backward pass.
pub const NORM_EPS: f32 = f32::EPSILON;

/// Whether each point is inside the unit ball, and `1 / max(|x|, sqrt(eps))`.
fn inside_and_inv_norm<const D: usize>(x: &Tensor<D>) -> (Tensor<D, Bool>, Tensor<D>) {
    let r2 = x.clone().square().sum_dim(D - 1).clamp_min(NORM_EPS);
    let inside = r2.clone().lower_equal_elem(1.0);
    (inside, r2.sqrt().recip())
}

/// `a = (2 - 1/r) / r` (1 inside the unit ball), the factor with
/// `contract(x) = a x`.
fn scale<const D: usize>(inside: Tensor<D, Bool>, inv: Tensor<D>) -> Tensor<D> {
    inv.clone()
        .neg()
        .add_scalar(2.0)
        .mul(inv)
        .mask_fill(inside, 1.0)
}

/// `(a, b, n)` of `J = a I + b n n^T`; `a`, `b`: `[.., 1]`, `n`: `[.., 3]`.
fn jacobian_parts(x: Tensor<3>) -> (Tensor<3>, Tensor<3>, Tensor<3>) {
    let (inside, inv) = inside_and_inv_norm(&x);
    let a = scale(inside.clone(), inv.clone());
    let b = inv
        .clone()
        .neg()
        .add_scalar(1.0)
        .mul(inv.clone())
        .mul_scalar(-2.0)
        .mask_fill(inside, 0.0);
    (a, b, x.mul(inv))
}

/// `[1, 1, 3, 3]` identity, broadcast over rays and samples.
fn identity(device: &Device) -> Tensor<4> {
    let eye = vec![1.0f32, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    Tensor::from_data(TensorData::new(eye, [1, 1, 3, 3]), device)
}

/// The contraction of points: identity inside the unit ball, `(2 - 1/|x|)
/// x / |x|` outside, so every output lies in the ball of radius 2.
///
/// # Shapes
/// - `x`: `[.., 3]`; output: `[.., 3]`.
pub fn contract<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    let (inside, inv) = inside_and_inv_norm(&x);
    x.mul(scale(inside, inv))
}

/// The Jacobian of [`contract`], `J[.., i, j] = d contract_i / d x_j`:
/// the identity inside the unit ball, `a I + b n n^T` outside (see the
/// module docs). Symmetric.
///
/// # Shapes
/// - `x`: `[rays, samples, 3]`; output: `[rays, samples, 3, 3]`.
pub fn contract_jacobian(x: Tensor<3>) -> Tensor<4> {
    let device = x.device();
    let (a, b, n) = jacobian_parts(x);
    let nnt = n.clone().unsqueeze_dim::<4>(3).mul(n.unsqueeze_dim::<4>(2));
    identity(&device)
        .mul(a.unsqueeze_dim::<4>(3))
        .add(nnt.mul(b.unsqueeze_dim::<4>(3)))
}

/// A Gaussian pushed through [`contract`] by linearisation around its mean:
/// `(contract(mean), J cov J^T)` with `J` the Jacobian at the mean.
///
/// `J cov J^T` is expanded in closed form (with `v = cov n`, `q = n^T v`:
/// `a^2 cov + a b (n v^T + v n^T) + b^2 q n n^T`), all element-wise, rather
/// than as two batched 3x3 matrix products, which are inefficient on
/// accelerators. `cov` must be symmetric.
///
/// # Shapes
/// - `mean`: `[rays, samples, 3]`; `cov`: `[rays, samples, 3, 3]`.
/// - outputs: `([rays, samples, 3], [rays, samples, 3, 3])`.
pub fn contract_gaussian(mean: Tensor<3>, cov: Tensor<4>) -> (Tensor<3>, Tensor<4>) {
    let (a, b, n) = jacobian_parts(mean.clone());
    let contracted = mean.mul(a.clone());
    let n_col = n.clone().unsqueeze_dim::<4>(3); // [r, s, 3, 1]
    let n_row = n.unsqueeze_dim::<4>(2); // [r, s, 1, 3]
    let v_col = cov.clone().mul(n_row.clone()).sum_dim(3); // [r, s, 3, 1]
    let v_row = v_col.clone().swap_dims(2, 3);
    let q = v_col.clone().mul(n_col.clone()).sum_dim(2); // [r, s, 1, 1]
    let a = a.unsqueeze_dim::<4>(3);
    let b = b.unsqueeze_dim::<4>(3);
    let cross = n_col
        .clone()
        .mul(v_row)
        .add(v_col.mul(n_row.clone()))
        .mul(a.clone().mul(b.clone()));
    let radial = n_col.mul(n_row).mul(b.square().mul(q));
    let cov = cov.mul(a.square()).add(cross).add(radial);
    (contracted, cov)
}

/// The full covariance of Mip-NeRF's frustum Gaussians (the diagonal of
/// which is [`crate::mip::lift_gaussian`]'s):
/// `t_var d d^T + r_var (I - d d^T / max(1e-10, |d|^2))`.
///
/// # Shapes
/// - `directions`: `[rays, 3]` unnormalised directions.
/// - `t_var`, `r_var`: `[rays, samples]` (from
///   [`crate::mip::conical_frustum_to_gaussian`]).
/// - output: `[rays, samples, 3, 3]`.
pub fn frustum_covariance(directions: Tensor<2>, t_var: Tensor<2>, r_var: Tensor<2>) -> Tensor<4> {
    let device = directions.device();
    let d = directions.unsqueeze_dim::<3>(1); // [rays, 1, 3]
    let norm2 = d.clone().square().sum_dim(2).clamp_min(1e-10); // [rays, 1, 1]
    let ddt = d.clone().swap_dims(1, 2).mul(d).unsqueeze_dim::<4>(1); // [rays, 1, 3, 3]
    let null = identity(&device).sub(ddt.clone().div(norm2.unsqueeze_dim::<4>(1)));
    let per_sample = |v: Tensor<2>| v.unsqueeze_dim::<3>(2).unsqueeze_dim::<4>(3);
    ddt.mul(per_sample(t_var)).add(null.mul(per_sample(r_var)))
}

/// The diagonal of covariance matrices, the input of the diagonal
/// [`crate::mip::integrated_pos_enc`].
///
/// # Shapes
/// - `cov`: `[rays, samples, 3, 3]`; output: `[rays, samples, 3]`.
pub fn cov_diagonal(cov: Tensor<4>) -> Tensor<3> {
    let device = cov.device();
    cov.mul(identity(&device)).sum_dim(3).squeeze_dim::<3>(3)
}

/// Mip-NeRF's frustum Gaussians ([`crate::mip::cast_rays`]) with full
/// covariances, pushed through the contraction: contracted means and the
/// diagonal of the contracted covariances, ready for the integrated
/// positional encoding.
///
/// The frustum moments form the fourth power of each interval's half-width
/// in f32, so intervals must be narrower than about `4e9` (a last interval
/// reaching `t = 1e10` from `1e9` overflows); the contraction itself takes
/// any finite mean.
///
/// # Shapes
/// - `t_vals`: `[rays, samples + 1]` fence posts (metric `t`).
/// - `origins`, `directions`: `[rays, 3]`; `radii`: `[rays, 1]`.
/// - outputs: `[rays, samples, 3]`.
pub fn cast_rays_contracted(
    t_vals: Tensor<2>,
    origins: Tensor<2>,
    directions: Tensor<2>,
    radii: Tensor<2>,
) -> FrustumGaussians {
    let (t0, t1) = interval_ends(t_vals);
    let (t_mean, t_var, r_var) = conical_frustum_to_gaussian(t0, t1, radii);
    let mean = points_along(origins, directions.clone(), t_mean);
    let cov = frustum_covariance(directions, t_var, r_var);
    let (mean, cov) = contract_gaussian(mean, cov);
    FrustumGaussians {
        mean,
        cov_diag: cov_diagonal(cov),
    }
}
