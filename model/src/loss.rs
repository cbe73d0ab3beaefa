//! Training losses. Each returns a one-element tensor and stays finite (zero,
//! not NaN) when no element is valid.

use burn::tensor::Tensor;

/// Norm floor in the cosine loss (targets below it are skipped, predictions
/// below it are treated as having this norm, which keeps gradients finite).
pub const COSINE_EPS: f32 = 1e-6;

/// Mean squared colour error.
///
/// # Shapes
/// - `pred`, `target`: `[n, 3]`; output: `[1]`.
pub fn rgb_mse(pred: Tensor<2>, target: Tensor<2>) -> Tensor<1> {
    pred.sub(target).square().mean()
}

/// Weighted Huber loss on depth, averaged over the rays with a valid target
/// (`target > 0`; NaN targets count as invalid). Zero when none is valid.
/// `weight` scales each ray (e.g. lower for rendered depth targets); it does
/// not renormalise the mean, so weaker targets pull less.
///
/// # Shapes
/// - `pred`, `target`, `weight`: `[n, 1]`; output: `[1]`.
pub fn depth_huber(pred: Tensor<2>, target: Tensor<2>, weight: Tensor<2>, delta: f32) -> Tensor<1> {
    let valid = target.clone().greater_elem(0.0);
    let invalid = valid.clone().bool_not();
    let count = valid.float().sum().clamp_min(1.0);
    let r = pred.sub(target).mask_fill(invalid.clone(), 0.0).abs();
    let delta = delta.max(f32::MIN_POSITIVE);
    let quad = r.clone().clamp_max(delta);
    // Huber = 0.5 q^2 + delta (|r| - q) with q = min(|r|, delta).
    let huber = quad
        .clone()
        .square()
        .mul_scalar(0.5)
        .add(r.sub(quad).mul_scalar(delta));
    huber.mul(weight.mask_fill(invalid, 0.0)).sum().div(count)
}

/// Open-set loss: mean of `1 - cos(pred, target)` over rays whose target norm
/// exceeds [`COSINE_EPS`]; zero-norm targets are skipped, zero-norm
/// predictions give a finite loss and gradient. Zero when none is valid.
///
/// # Shapes
/// - `pred`, `target`: `[n, k]`; output: `[1]`.
pub fn open_set_cosine(pred: Tensor<2>, target: Tensor<2>) -> Tensor<1> {
    let eps2 = COSINE_EPS * COSINE_EPS;
    let t_norm2 = target.clone().square().sum_dim(1);
    let valid = t_norm2.clone().greater_elem(eps2);
    let count = valid.clone().float().sum().clamp_min(1.0);
    let p_norm = pred.clone().square().sum_dim(1).clamp_min(eps2).sqrt();
    let t_norm = t_norm2.clamp_min(eps2).sqrt();
    let cos = pred.mul(target).sum_dim(1).div(p_norm.mul(t_norm));
    cos.neg()
        .add_scalar(1.0)
        .mask_fill(valid.bool_not(), 0.0)
        .sum()
        .div(count)
}
