//! Mip-NeRF encodings: conical frustums as Gaussians, the integrated
//! positional encoding (IPE) and the plain positional encoding (PE).
//!
//! The frequency expansion is one matrix product with a constant `[3, 6 L]`
//! matrix (columns `2^l e_k`, twice) plus a phase row (`0` then `pi / 2`), so
//! the sine and cosine halves come out of a single `sin` with no
//! concatenation in the per-sample path. Powers of two times one non-zero
//! entry per column keep the product exact.

use burn::tensor::{Device, Tensor, TensorData};
use std::f32::consts::FRAC_PI_2;

/// Means and diagonal covariances of the frustum Gaussians along each ray.
#[derive(Debug, Clone)]
pub struct FrustumGaussians {
    /// Gaussian means in normalised coordinates, `[rays, samples, 3]`.
    pub mean: Tensor<3>,
    /// Diagonal of the covariances, `[rays, samples, 3]`.
    pub cov_diag: Tensor<3>,
}

/// Mean and variances of a conical frustum along and across its axis, in the
/// numerically stable form of Mip-NeRF (no cancellation of `t1^3 - t0^3`).
///
/// Returns `(t_mean, t_var, r_var)`; `r_var` already includes `radius^2`.
///
/// # Shapes
/// - `t0`, `t1`: `[rays, samples]` interval ends.
/// - `radius`: `[rays, 1]` cone radius at `t = 1`.
/// - outputs: `[rays, samples]` each.
pub fn conical_frustum_to_gaussian(
    t0: Tensor<2>,
    t1: Tensor<2>,
    radius: Tensor<2>,
) -> (Tensor<2>, Tensor<2>, Tensor<2>) {
    let FrustumTerms {
        mu,
        mu2,
        hw2,
        denom,
    } = FrustumTerms::new(t0, t1);
    let hw4 = hw2.clone().square();
    let t_mean = frustum_t_mean(mu, hw2.clone(), denom.clone());
    let t_var = hw2.clone().div_scalar(3.0).sub(
        hw4.clone()
            .mul_scalar(4.0 / 15.0)
            .mul(mu2.clone().mul_scalar(12.0).sub(hw2.clone()))
            .div(denom.clone().square()),
    );
    let r_var = mu2
        .div_scalar(4.0)
        .add(hw2.mul_scalar(5.0 / 12.0))
        .sub(hw4.mul_scalar(4.0 / 15.0).div(denom))
        .mul(radius.square());
    (t_mean, t_var, r_var)
}

/// The terms of an interval `[t0, t1]` the frustum's moments share: its
/// middle `mu`, `mu^2`, its half-width squared and `3 mu^2 + hw^2`.
struct FrustumTerms {
    mu: Tensor<2>,
    mu2: Tensor<2>,
    hw2: Tensor<2>,
    denom: Tensor<2>,
}

impl FrustumTerms {
    fn new(t0: Tensor<2>, t1: Tensor<2>) -> Self {
        let mu = t0.clone().add(t1.clone()).mul_scalar(0.5);
        let hw = t1.sub(t0).mul_scalar(0.5);
        let mu2 = mu.clone().square();
        let hw2 = hw.square();
        // 3 mu^2 + hw^2 is 0 only for the degenerate interval [0, 0]; the
        // floor keeps that case finite (it then yields t_mean = 0 and zero
        // variances).
        let denom = mu2
            .clone()
            .mul_scalar(3.0)
            .add(hw2.clone())
            .clamp_min(1e-20);
        Self {
            mu,
            mu2,
            hw2,
            denom,
        }
    }
}

/// `mu + 2 mu hw^2 / (3 mu^2 + hw^2)`: the frustum's mean `t`.
fn frustum_t_mean(mu: Tensor<2>, hw2: Tensor<2>, denom: Tensor<2>) -> Tensor<2> {
    mu.clone().add(mu.mul(hw2).mul_scalar(2.0).div(denom))
}

/// The mean `t` of a conical frustum, as [`conical_frustum_to_gaussian`]
/// gives it (the same operations, so the same bits), without its
/// variances: what a field that reads only the Gaussians' means needs.
///
/// # Shapes
/// - `t0`, `t1`: `[rays, samples]` interval ends; output: `[rays, samples]`.
pub fn conical_frustum_mean(t0: Tensor<2>, t1: Tensor<2>) -> Tensor<2> {
    let terms = FrustumTerms::new(t0, t1);
    frustum_t_mean(terms.mu, terms.hw2, terms.denom)
}

/// The starts and ends of the intervals between consecutive fence posts.
///
/// # Shapes
/// - `t_vals`: `[rays, samples + 1]`; outputs: `[rays, samples]` each.
pub fn interval_ends(t_vals: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
    let [_, posts] = t_vals.dims();
    let t0 = t_vals.clone().slice_dim(1, 0..posts - 1);
    (t0, t_vals.slice_dim(1, 1..posts))
}

/// The points `o + t d` at distances `t` along each ray.
///
/// # Shapes
/// - `origins`, `directions`: `[rays, 3]`; `t`: `[rays, samples]`;
///   output: `[rays, samples, 3]`.
pub fn points_along(origins: Tensor<2>, directions: Tensor<2>, t: Tensor<2>) -> Tensor<3> {
    directions
        .unsqueeze_dim::<3>(1)
        .mul(t.unsqueeze_dim::<3>(2))
        .add(origins.unsqueeze_dim::<3>(1))
}

/// The means of the conical frustums between consecutive fence posts
/// ([`cast_rays`]' means, without their covariances).
///
/// # Shapes
/// - `t_vals`: `[rays, samples + 1]`; `origins`, `directions`: `[rays, 3]`;
///   output: `[rays, samples, 3]`.
pub fn frustum_means(t_vals: Tensor<2>, origins: Tensor<2>, directions: Tensor<2>) -> Tensor<3> {
    let (t0, t1) = interval_ends(t_vals);
    points_along(origins, directions, conical_frustum_mean(t0, t1))
}

/// Lifts the along-axis / across-axis statistics of a frustum into a 3D
/// Gaussian with diagonal covariance around `t_mean * d` (the ray origin is
/// added by the caller).
///
/// `cov_diag = t_var d^2 + r_var (1 - d^2 / max(1e-10, |d|^2))`.
///
/// # Shapes
/// - `directions`: `[rays, 3]` unnormalised directions.
/// - `t_mean`, `t_var`, `r_var`: `[rays, samples]`.
/// - outputs: `([rays, samples, 3], [rays, samples, 3])` mean offset and covariance diagonal.
pub fn lift_gaussian(
    directions: Tensor<2>,
    t_mean: Tensor<2>,
    t_var: Tensor<2>,
    r_var: Tensor<2>,
) -> (Tensor<3>, Tensor<3>) {
    let d = directions.unsqueeze_dim::<3>(1); // [rays, 1, 3]
    let d2 = d.clone().square();
    let norm2 = d2.clone().sum_dim(2).clamp_min(1e-10);
    let null_outer = d2.clone().div(norm2).neg().add_scalar(1.0);
    let mean = d.mul(t_mean.unsqueeze_dim::<3>(2));
    let cov = d2
        .mul(t_var.unsqueeze_dim::<3>(2))
        .add(null_outer.mul(r_var.unsqueeze_dim::<3>(2)));
    (mean, cov)
}

/// The Gaussians of the conical frustums between consecutive fence posts.
///
/// # Shapes
/// - `t_vals`: `[rays, samples + 1]` fence posts (metric `t`).
/// - `origins`, `directions`: `[rays, 3]`; `radii`: `[rays, 1]`.
/// - outputs: `[rays, samples, 3]`.
pub fn cast_rays(
    t_vals: Tensor<2>,
    origins: Tensor<2>,
    directions: Tensor<2>,
    radii: Tensor<2>,
) -> FrustumGaussians {
    let (t0, t1) = interval_ends(t_vals);
    let (t_mean, t_var, r_var) = conical_frustum_to_gaussian(t0, t1, radii);
    let (offset, cov_diag) = lift_gaussian(directions, t_mean, t_var, r_var);
    FrustumGaussians {
        mean: offset.add(origins.unsqueeze_dim::<3>(1)),
        cov_diag,
    }
}

/// Output width of [`integrated_pos_enc`]: `6 (max_deg - min_deg)`.
pub fn ipe_dim(min_deg: usize, max_deg: usize) -> usize {
    6 * max_deg.saturating_sub(min_deg)
}

/// Output width of [`pos_enc`]: `6 (max_deg - min_deg)`, plus 3 with identity.
pub fn pe_dim(min_deg: usize, max_deg: usize, append_identity: bool) -> usize {
    ipe_dim(min_deg, max_deg) + if append_identity { 3 } else { 0 }
}

/// Constant `[3, 6 L]` frequency matrix (scales `2^l` or `4^l` when
/// `squared`), columns ordered `[sin block | cos block]`, each block
/// degree-major (`x 2^l, y 2^l, z 2^l` for `l = min..max`).
fn frequency_matrix(min_deg: usize, max_deg: usize, squared: bool, device: &Device) -> Tensor<2> {
    let levels = max_deg.saturating_sub(min_deg);
    let cols = 6 * levels;
    let mut m = vec![0f32; 3 * cols];
    for half in 0..2 {
        for l in 0..levels {
            let s = 2f32.powi((min_deg + l) as i32);
            let s = if squared { s * s } else { s };
            for k in 0..3 {
                m[k * cols + half * 3 * levels + 3 * l + k] = s;
            }
        }
    }
    Tensor::from_data(TensorData::new(m, [3, cols]), device)
}

/// Phase row `[1, 6 L]`: `0` for the sine block, `pi / 2` for the cosine block.
fn phase_row(levels: usize, device: &Device) -> Tensor<2> {
    let mut p = vec![0f32; 6 * levels];
    p[3 * levels..].fill(FRAC_PI_2);
    Tensor::from_data(TensorData::new(p, [1, 6 * levels]), device)
}

/// Integrated positional encoding:
/// `exp(-y_var / 2) * sin([y, y + pi / 2])` with `y = 2^l mean`,
/// `y_var = 4^l cov_diag` for `l` in `[min_deg, max_deg)`; no identity term.
///
/// Huge variances give exactly 0 (the feature is integrated away), tiny
/// ones the plain sinusoid.
///
/// # Shapes
/// - `mean`, `cov_diag`: `[.., 3]`.
/// - output: `[.., 6 (max_deg - min_deg)]`, ordered sin block then cos block,
///   each degree-major.
pub fn integrated_pos_enc<const D: usize>(
    mean: Tensor<D>,
    cov_diag: Tensor<D>,
    min_deg: usize,
    max_deg: usize,
) -> Tensor<D> {
    let device = mean.device();
    let dims = mean.dims();
    let levels = max_deg.saturating_sub(min_deg);
    let mean2: Tensor<2> = mean.reshape([-1, 3]);
    let cov2: Tensor<2> = cov_diag.reshape([-1, 3]);
    let y = mean2
        .matmul(frequency_matrix(min_deg, max_deg, false, &device))
        .add(phase_row(levels, &device));
    let y_var = cov2.matmul(frequency_matrix(min_deg, max_deg, true, &device));
    let enc = y_var.mul_scalar(-0.5).exp().mul(y.sin());
    let mut out = dims;
    out[D - 1] = 6 * levels;
    enc.reshape(out)
}

/// Plain positional encoding `sin([x 2^l, x 2^l + pi / 2])` for `l` in
/// `[min_deg, max_deg)`, optionally preceded by `x` itself.
///
/// # Shapes
/// - `x`: `[.., 3]`.
/// - output: `[.., pe_dim(min_deg, max_deg, append_identity)]`.
pub fn pos_enc<const D: usize>(
    x: Tensor<D>,
    min_deg: usize,
    max_deg: usize,
    append_identity: bool,
) -> Tensor<D> {
    let device = x.device();
    let dims = x.dims();
    let levels = max_deg.saturating_sub(min_deg);
    let x2: Tensor<2> = x.reshape([-1, 3]);
    let enc = x2
        .clone()
        .matmul(frequency_matrix(min_deg, max_deg, false, &device))
        .add(phase_row(levels, &device))
        .sin();
    let enc = if append_identity {
        Tensor::cat(vec![x2, enc], 1)
    } else {
        enc
    };
    let mut out = dims;
    out[D - 1] = pe_dim(min_deg, max_deg, append_identity);
    enc.reshape(out)
}

/// Plain `f64` references of the frustum formulas, for tests and checks.
pub mod reference {
    /// Stable-form `(t_mean, t_var, r_var)` of the frustum `[t0, t1]` with
    /// cone radius `radius` at `t = 1` (same formulas as
    /// [`super::conical_frustum_to_gaussian`]).
    pub fn frustum_stable(t0: f64, t1: f64, radius: f64) -> (f64, f64, f64) {
        let mu = 0.5 * (t0 + t1);
        let hw = 0.5 * (t1 - t0);
        let denom = 3.0 * mu * mu + hw * hw;
        let t_mean = mu + 2.0 * mu * hw * hw / denom;
        let t_var =
            hw * hw / 3.0 - (4.0 / 15.0) * hw.powi(4) * (12.0 * mu * mu - hw * hw) / denom.powi(2);
        let r_var = radius
            * radius
            * (mu * mu / 4.0 + (5.0 / 12.0) * hw * hw - (4.0 / 15.0) * hw.powi(4) / denom);
        (t_mean, t_var, r_var)
    }

    /// Closed-form moments of the frustum from the integrals over the cone
    /// (Mip-NeRF appendix): with `c_n = t1^n - t0^n`,
    /// `t_mean = 3 c_4 / (4 c_3)`, `E[t^2] = 3 c_5 / (5 c_3)`,
    /// `r_var = r^2 3 c_5 / (20 c_3)`. Suffers from cancellation for thin
    /// intervals far away; that is why the stable form exists.
    pub fn frustum_naive(t0: f64, t1: f64, radius: f64) -> (f64, f64, f64) {
        let c = |n: i32| t1.powi(n) - t0.powi(n);
        let t_mean = 3.0 * c(4) / (4.0 * c(3));
        let t_var = 3.0 * c(5) / (5.0 * c(3)) - t_mean * t_mean;
        let r_var = radius * radius * 3.0 * c(5) / (20.0 * c(3));
        (t_mean, t_var, r_var)
    }
}
