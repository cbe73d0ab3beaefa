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

/// Colour squared error weighted per ray, averaged over all `3 n` values:
/// a ray of weight 0 pulls nothing, and with every weight 1 this is
/// [`rgb_mse`].
///
/// # Shapes
/// - `pred`, `target`: `[n, 3]`; `weight`: `[n, 1]`; output: `[1]`.
pub fn weighted_rgb_mse(pred: Tensor<2>, target: Tensor<2>, weight: Tensor<2>) -> Tensor<1> {
    pred.sub(target)
        .square()
        .mul(weight.repeat_dim(1, 3))
        .mean()
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

/// The expected depth the depth loss compares with its target: the
/// weighted mean of the intervals' midpoints, each capped at `cap` times
/// the ray's target. The last interval of an unbounded ray can reach
/// thousands of units past the scene; uncapped, a weight of `1e-4` there
/// moves the expected depth by a unit, and the loss's gradient on that
/// weight is as large as the interval is far. Capped, weight beyond the
/// cap counts as if it were there: the loss is unchanged where the weight
/// sits near the target. Rays without a target (not `> 0`: zero, negative
/// or NaN) get the uncapped depth, which the loss ignores.
///
/// # Shapes
/// - `weights`: `[rays, samples]`; `t_vals`: `[rays, samples + 1]`;
///   `target`: `[rays, 1]`; output: `[rays, 1]`.
pub fn capped_depth(
    weights: Tensor<2>,
    t_vals: Tensor<2>,
    target: Tensor<2>,
    cap: f32,
) -> Tensor<2> {
    let mids = crate::composite::t_mids(t_vals);
    let [rays, samples] = mids.dims();
    let limit = target
        .clone()
        .mul_scalar(cap)
        .mask_fill(target.greater_elem(0.0).bool_not(), f32::INFINITY)
        .expand([rays, samples]);
    let acc = weights.clone().sum_dim(1);
    crate::composite::expected_depth(weights.mul(mids.min_pair(limit)).sum_dim(1), acc)
}

/// The compositing weight of each ray that lies away from its depth target,
/// averaged over the rays with a valid target (`target > 0`): each
/// sample's weight times its distance from the target in units of `width`
/// times the target, capped at 1. Zero when every ray's weight lies within
/// that window of its target; a ray's whole weight when it all lies beyond
/// it. Where the expected depth ([`depth_huber`]) can be met by weight in
/// front of the surface balanced by weight behind it, this asks the weight
/// to be at the surface (DS-NeRF's ray-termination loss, without its log).
/// The posts are fixed: only the weights receive gradients.
///
/// # Shapes
/// - `t_vals`: `[n, k + 1]` posts; `weights`: `[n, k]`; `target`: `[n, 1]`;
///   output: `[1]`.
pub fn depth_window(
    t_vals: Tensor<2>,
    weights: Tensor<2>,
    target: Tensor<2>,
    width: f32,
) -> Tensor<1> {
    let [n, posts] = t_vals.dims();
    let k = posts.saturating_sub(1);
    if n == 0 || k == 0 {
        return Tensor::zeros([1], &weights.device());
    }
    let t = t_vals.detach();
    let mid = t
        .clone()
        .slice([0..n, 0..k])
        .add(t.slice([0..n, 1..posts]))
        .mul_scalar(0.5);
    let valid = target.clone().greater_elem(0.0);
    let count = valid.clone().float().sum().clamp_min(1.0);
    let scale = target
        .clone()
        .mul_scalar(width.max(f32::MIN_POSITIVE))
        .mask_fill(valid.clone().bool_not(), 1.0);
    let away = mid
        .sub(target.repeat_dim(1, k))
        .abs()
        .div(scale.repeat_dim(1, k))
        .clamp_max(1.0);
    weights
        .mul(away)
        .sum_dim(1)
        .mask_fill(valid.bool_not(), 0.0)
        .sum()
        .div(count)
}

/// The space feature predictions and targets live in, as the loss needs it.
///
/// With PCA the field predicts coefficients `c` of the lifted feature
/// `f = m + U^T c` (`U`: `k x D`, orthonormal rows). The cosine that matters
/// (for segmentation and queries) is the one between lifted features, and it
/// depends on `|c|`: a short prediction lifts towards the scene's mean `m`.
/// With orthonormal `U` it has a closed form in `O(k)` per ray:
///
/// ```text
/// f . g = |m|^2 + (U m) . (c + c') + c . c'
/// |f|^2 = |m|^2 + 2 (U m) . c + |c|^2
/// ```
#[derive(Debug, Clone)]
pub enum FeatureSpace {
    /// Features are compared as they are (no PCA).
    Identity,
    /// PCA coefficients of `m + U^T c`.
    Lifted {
        /// `U m`, `[1, k]` (boxed: the variant would dwarf `Identity`).
        mean_proj: Box<Tensor<2>>,
        /// `|m|^2`.
        mean_sq: f32,
    },
}

/// Open-set loss: mean of `1 - cos(lift(pred), lift(target))` over the rays
/// whose `mask` is 1 and whose lifted target has a norm above
/// [`COSINE_EPS`] (targets without a value are skipped, never trained
/// towards); zero-norm predictions give a finite loss and gradient. Zero
/// when no ray is valid.
///
/// # Shapes
/// - `pred`, `target`: `[n, k]`; `mask`: `[n, 1]` (1 = target, 0 = none);
///   output: `[1]`.
pub fn open_set_cosine(
    pred: Tensor<2>,
    target: Tensor<2>,
    mask: Tensor<2>,
    space: &FeatureSpace,
) -> Tensor<1> {
    let eps2 = COSINE_EPS * COSINE_EPS;
    let dot = pred.clone().mul(target.clone()).sum_dim(1);
    let p2 = pred.clone().square().sum_dim(1);
    let t2 = target.clone().square().sum_dim(1);
    let (dot, p2, t2) = match space {
        FeatureSpace::Identity => (dot, p2, t2),
        FeatureSpace::Lifted { mean_proj, mean_sq } => {
            let pm = pred.mul((**mean_proj).clone()).sum_dim(1);
            let tm = target.mul((**mean_proj).clone()).sum_dim(1);
            (
                dot.add(pm.clone()).add(tm.clone()).add_scalar(*mean_sq),
                p2.add(pm.mul_scalar(2.0)).add_scalar(*mean_sq),
                t2.add(tm.mul_scalar(2.0)).add_scalar(*mean_sq),
            )
        }
    };
    let valid = t2
        .clone()
        .greater_elem(eps2)
        .bool_and(mask.greater_elem(0.5));
    let count = valid.clone().float().sum().clamp_min(1.0);
    let p_norm = p2.clamp_min(eps2).sqrt();
    let t_norm = t2.clamp_min(eps2).sqrt();
    let cos = dot.div(p_norm.mul(t_norm));
    cos.neg()
        .add_scalar(1.0)
        .mask_fill(valid.bool_not(), 0.0)
        .sum()
        .div(count)
}

/// Depth smoothness over square patches of rays (RegNeRF, Niemeyer et al.
/// 2022, eq. 5): the mean, over every pair of horizontally or vertically
/// neighbouring rays of each patch, of their depths' squared difference.
/// Rays of a patch are row-major, patch after patch. A patch of side 1 has
/// no pairs; the loss is then zero.
///
/// # Shapes
/// - `depth`: `[patches * side * side, 1]`; output: `[1]`.
pub fn depth_smoothness(depth: Tensor<2>, side: usize) -> Tensor<1> {
    let [n, _] = depth.dims();
    let device = depth.device();
    if side < 2 || n == 0 {
        return Tensor::zeros([1], &device);
    }
    let patches = n / (side * side);
    let grid = depth.reshape([patches, side, side]);
    let across = grid.clone().slice([0..patches, 0..side, 1..side])
        - grid.clone().slice([0..patches, 0..side, 0..side - 1]);
    let down = grid.clone().slice([0..patches, 1..side, 0..side])
        - grid.slice([0..patches, 0..side - 1, 0..side]);
    let pairs = (2 * patches * side * (side - 1)) as f32;
    (across.square().sum() + down.square().sum()).div_scalar(pairs)
}
