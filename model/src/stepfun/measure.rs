//! Measures of step functions: the outer measure of one on the intervals
//! of another, Mip-NeRF 360's interlevel loss built on it (which makes a
//! proposal histogram an upper envelope of the NeRF one), and its
//! distortion loss.
//!
//! Burn has no `searchsorted`; where a step function is looked up at the
//! ends of another, the lookup is a broadcast comparison of every end
//! against every end (`[rays, n, m]` booleans). For the proposal sizes of
//! the paper (`n, m` of 32 to 128) that is a few MB per thousand rays, and
//! it keeps the lookup differentiable in the weights without a gather.

use burn::tensor::Tensor;

use super::lo_hi;

/// Weight floor under the interlevel loss's division (f32 machine epsilon,
/// as multinerf): the loss is then `~ (w - outer)^2 / w` where `w > 0` and
/// exactly 0 where `w = 0`.
pub const INTERLEVEL_EPS: f32 = f32::EPSILON;

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
/// - `s`: `[rays, n + 1]` sorted interval ends (normalised, e.g. [`crate::unbounded::t_to_s`]).
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
