//! Anti-aliasing of a hash encoding by the sample's footprint (Zip-NeRF,
//! Barron et al. 2023, section 3: "downweighting"): a level whose cells are
//! smaller than the Gaussian a sample stands for cannot be averaged over
//! that Gaussian by one lookup, so its features are scaled down towards
//! their mean (zero) by the fraction of an isotropic Gaussian of that
//! variance that a cell of the level resolves.
//!
//! A level of `r` cells across the unit cube and a Gaussian of variance
//! `v` (unit-cube coordinates) get the weight `erf(1 / sqrt(8 v r^2))`:
//! about 1 where a cell is wider than a few standard deviations, about
//! `1 / (sqrt(2 pi) sigma r)` where it is much narrower.

use burn::tensor::{Tensor, TensorData};

/// The weight of each level for Gaussians of variance `variance`, given in
/// the encoded coordinates (a cube of side `2 * half_extent`).
///
/// # Shapes
/// - `variance`: `[n, 1]`, non-negative; output: `[n, levels]`, in `(0, 1]`.
pub fn level_weights(variance: Tensor<2>, resolutions: &[u32], half_extent: f32) -> Tensor<2> {
    let [n, _] = variance.dims();
    let levels = resolutions.len();
    // 8 v_unit r^2 with v_unit = v / (2 h)^2, per level.
    let scale: Vec<f32> = resolutions
        .iter()
        .map(|&r| {
            let cells = r as f32 / (2.0 * half_extent);
            8.0 * cells * cells
        })
        .collect();
    let scale = Tensor::<2>::from_data(TensorData::new(scale, [1, levels]), &variance.device());
    // A zero variance (a point) keeps every level: the floor keeps the
    // square root's reciprocal finite.
    let spread = variance
        .clamp_min(0.0)
        .expand([n, levels])
        .mul(scale)
        .clamp_min(1e-20);
    spread.sqrt().recip().erf()
}

/// The isotropic variance [`level_weights`] reads from a Gaussian's
/// diagonal covariance: its mean over the three axes (the same volume
/// spread along every axis).
///
/// # Shapes
/// - `cov_diag`: `[n, 3]`; output: `[n, 1]`.
pub fn isotropic_variance(cov_diag: Tensor<2>) -> Tensor<2> {
    cov_diag.mean_dim(1)
}

/// `encoded`'s features scaled by their level's weight.
///
/// # Shapes
/// - `encoded`: `[n, levels * features]`, level-major; `weights`:
///   `[n, levels]`; output: as `encoded`.
pub fn weigh_levels(encoded: Tensor<2>, weights: Tensor<2>) -> Tensor<2> {
    let [n, width] = encoded.dims();
    let [_, levels] = weights.dims();
    let features = width / levels.max(1);
    encoded
        .reshape([n, levels, features])
        .mul(weights.unsqueeze_dim::<3>(2))
        .reshape([n, width])
}
