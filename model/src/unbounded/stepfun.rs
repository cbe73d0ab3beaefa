//! Step functions along rays (interval ends `t: [rays, n + 1]`, sorted, and
//! one weight per interval `w: [rays, n]`): Mip-NeRF 360's interlevel loss,
//! which makes a proposal histogram an upper envelope of the NeRF one, its
//! distortion loss, and the dilation and annealing applied to proposal
//! weights before resampling.
//!
//! Burn has no `searchsorted`; where a step function is looked up at the
//! ends of another, the lookup is a broadcast comparison of every end
//! against every end (`[rays, n, m]` booleans). For the proposal sizes of
//! the paper (`n, m` of 32 to 128) that is a few MB per thousand rays, and
//! it keeps the lookup differentiable in the weights without a gather.

use burn::tensor::Tensor;

/// Weight floor under the interlevel loss's division (f32 machine epsilon,
/// as multinerf): the loss is then `~ (w - outer)^2 / w` where `w > 0` and
/// exactly 0 where `w = 0`.
pub const INTERLEVEL_EPS: f32 = f32::EPSILON;

/// Interval starts and ends of `[rays, n + 1]` posts, `[rays, n]` each.
fn lo_hi(t: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
    let [_, posts] = t.dims();
    (
        t.clone().slice_dim(1, 0..posts - 1),
        t.slice_dim(1, 1..posts),
    )
}

/// The outer measure of the step function `(t_env, w_env)` on the intervals
/// of `t`: for each interval `[t_k, t_{k+1}]`, the total weight of the
/// `t_env` intervals that overlap it (multinerf's `inner_outer`, outer
/// part). With `c` the cumulative weights of `w_env`, it is
/// `c(first end > t_{k+1}) - c(last end <= t_k)`, i.e. the sum of `w_env_j`
/// with `t_env_j <= t_{k+1}` and `t_env_{j+1} > t_k`. Intervals that only
/// touch at their ends count on the right side of an interval, not on its
/// left (multinerf's convention). Differentiable in `w_env` only.
///
/// # Shapes
/// - `t`: `[rays, n + 1]`, `t_env`: `[rays, m + 1]`, both sorted, in the
///   same coordinates (metric or `s`: overlap does not depend on which).
/// - `w_env`: `[rays, m]`; output: `[rays, n]`.
pub fn outer_measure(t: Tensor<2>, t_env: Tensor<2>, w_env: Tensor<2>) -> Tensor<2> {
    let [rays, posts] = t.dims();
    let [_, env_posts] = t_env.dims();
    let shape = [rays, posts - 1, env_posts - 1];
    let (lo, hi) = lo_hi(t);
    let (env_lo, env_hi) = lo_hi(t_env);
    let starts_before_end = env_lo
        .unsqueeze_dim::<3>(1)
        .expand(shape)
        .lower_equal(hi.unsqueeze_dim::<3>(2).expand(shape));
    let ends_after_start = env_hi
        .unsqueeze_dim::<3>(1)
        .expand(shape)
        .greater(lo.unsqueeze_dim::<3>(2).expand(shape));
    let overlap = starts_before_end.bool_and(ends_after_start).float();
    overlap
        .matmul(w_env.unsqueeze_dim::<3>(2))
        .squeeze_dim::<2>(2)
}

/// Mip-NeRF 360's interlevel (proposal) loss: the NeRF weights `w` should
/// be bounded by the proposal mass over each of their intervals,
/// `outer = `[`outer_measure`]`(t; t_env, w_env)`; per ray
/// `sum_k max(0, w_k - outer_k)^2 / (w_k + eps)`, averaged over rays.
///
/// The NeRF side (`t`, `w`) and the proposal ends are detached: only the
/// proposal weights learn from this loss. (multinerf averages over rays and
/// intervals; this sums over intervals, `n` times that.)
///
/// # Shapes
/// - `t`: `[rays, n + 1]`, `w`: `[rays, n]` (NeRF step function).
/// - `t_env`: `[rays, m + 1]`, `w_env`: `[rays, m]` (proposal).
/// - output: `[1]`.
pub fn interlevel_loss(
    t: Tensor<2>,
    w: Tensor<2>,
    t_env: Tensor<2>,
    w_env: Tensor<2>,
) -> Tensor<1> {
    let w = w.detach();
    let outer = outer_measure(t.detach(), t_env.detach(), w_env);
    w.clone()
        .sub(outer)
        .clamp_min(0.0)
        .square()
        .div(w.add_scalar(INTERLEVEL_EPS))
        .sum_dim(1)
        .mean()
}

/// Mip-NeRF 360's distortion loss, the double integral
/// `int int w(s) w(s') |s - s'| ds ds'` of the step function (`w` spread
/// uniformly over each interval), per ray, averaged over rays:
///
/// ```text
/// sum_{i,j} w_i w_j |u_i - u_j| + 1/3 sum_i w_i^2 (s_{i+1} - s_i)
/// ```
///
/// with `u` the interval midpoints. The pairwise sum is evaluated in `O(n)`
/// with exclusive prefix sums (sorted `s`, so `u_i >= u_j` for `j < i`):
/// `2 sum_i w_i (u_i W_i - U_i)`, `W_i = sum_{j<i} w_j`,
/// `U_i = sum_{j<i} w_j u_j`.
///
/// # Shapes
/// - `s`: `[rays, n + 1]` sorted interval ends (normalised, e.g. [`super::t_to_s`]).
/// - `w`: `[rays, n]`; output: `[1]`.
pub fn distortion_loss(s: Tensor<2>, w: Tensor<2>) -> Tensor<1> {
    let (lo, hi) = lo_hi(s);
    let u = lo.clone().add(hi.clone()).mul_scalar(0.5);
    let wu = w.clone().mul(u.clone());
    // Exclusive prefix sums as inclusive minus self: no concatenation.
    let w_before = w.clone().cumsum(1).sub(w.clone());
    let wu_before = wu.clone().cumsum(1).sub(wu);
    let inter = w
        .clone()
        .mul(u.mul(w_before).sub(wu_before))
        .mul_scalar(2.0);
    let intra = w.square().mul(hi.sub(lo)).div_scalar(3.0);
    inter.add(intra).sum_dim(1).mean()
}

/// Max-dilation of a step function's density (multinerf's
/// `max_dilate_weights`): each interval's density is spread `dilation` to
/// both sides and overlapping spreads keep their maximum, so the dilated
/// histogram bounds the original one near every interval. The new ends are
/// the old ends and the dilated ones, sorted and clamped to `domain`; the
/// weights are the dilated density times the new widths, renormalised to
/// sum to 1 when `renormalize`.
///
/// Meant for the proposal weights that drive resampling (stop-gradient
/// values); the sort is not a useful gradient path.
///
/// # Shapes
/// - `t`: `[rays, n + 1]` sorted; `w`: `[rays, n]` non-negative.
/// - outputs: `([rays, 3 n + 1], [rays, 3 n])`.
pub fn max_dilate_weights(
    t: Tensor<2>,
    w: Tensor<2>,
    dilation: f32,
    domain: (f32, f32),
    renormalize: bool,
) -> (Tensor<2>, Tensor<2>) {
    let eps = f32::EPSILON * f32::EPSILON;
    let [rays, posts] = t.dims();
    let n = posts - 1;
    let (lo, hi) = lo_hi(t.clone());
    let density = w.div(hi.clone().sub(lo.clone()).clamp_min(eps));
    let lo = lo.sub_scalar(dilation);
    let hi = hi.add_scalar(dilation);
    let ends = Tensor::cat(vec![t, lo.clone(), hi.clone()], 1)
        .sort(1)
        .clamp(domain.0, domain.1);
    // The density on each new interval is the largest dilated density
    // covering its left end.
    let shape = [rays, 3 * n + 1, n];
    let at = ends.clone().unsqueeze_dim::<3>(2).expand(shape);
    let covers = lo
        .unsqueeze_dim::<3>(1)
        .expand(shape)
        .lower_equal(at.clone())
        .bool_and(hi.unsqueeze_dim::<3>(1).expand(shape).greater(at));
    let dilated = density
        .unsqueeze_dim::<3>(1)
        .expand(shape)
        .mask_fill(covers.bool_not(), 0.0)
        .max_dim(2)
        .squeeze_dim::<2>(2)
        .slice_dim(1, 0..3 * n);
    let (new_lo, new_hi) = lo_hi(ends.clone());
    let weights = dilated.mul(new_hi.sub(new_lo));
    let weights = if renormalize {
        let total = weights.clone().sum_dim(1).clamp_min(eps);
        weights.div(total)
    } else {
        weights
    };
    (ends, weights)
}

/// The exponent of the proposal-weight annealing at a fraction of training
/// (Schlick's bias curve with slope `slope`, as in multinerf):
/// `slope x / ((slope - 1) x + 1)` for `x = train_frac` clamped to `[0, 1]`,
/// rising from 0 at the start to 1 at the end; 1 throughout when
/// `slope <= 0` (annealing off).
pub fn anneal_exponent(train_frac: f32, slope: f32) -> f32 {
    if slope <= 0.0 {
        return 1.0;
    }
    let x = train_frac.clamp(0.0, 1.0);
    slope * x / ((slope - 1.0) * x + 1.0)
}

/// Annealed proposal weights for resampling: `(w + padding)^exponent` on
/// intervals of positive width, 0 on empty ones (their samples would be
/// wasted). Exponent 0 gives uniform weights over the non-empty intervals
/// (multinerf's logits `exponent log(w + padding)`, exponentiated; the
/// resampler normalises). The base is floored at the smallest normal f32 so
/// that `w + padding = 0` gives 0 (or 1 at exponent 0), never NaN.
///
/// # Shapes
/// - `t`: `[rays, n + 1]`; `w`: `[rays, n]`; output: `[rays, n]`.
pub fn anneal_weights(t: Tensor<2>, w: Tensor<2>, exponent: f32, padding: f32) -> Tensor<2> {
    let (lo, hi) = lo_hi(t);
    let empty = hi.lower_equal(lo);
    w.add_scalar(padding)
        .clamp_min(f32::MIN_POSITIVE)
        .log()
        .mul_scalar(exponent)
        .exp()
        .mask_fill(empty, 0.0)
}
