//! Stratified fence posts along rays (the first level's samples; the
//! resampling of the later levels is step-function math, see
//! [`crate::stepfun`]).
//!
//! All outputs are detached: the sample positions are never differentiated.

use burn::tensor::{Distribution, Tensor};

use crate::stepfun::linspace_row;

/// Stratified fence posts in `[near, far]`: `num_samples + 1` evenly spaced
/// posts, each jittered uniformly inside its stratum (between the midpoints
/// to its neighbours) when `randomized`. The first and last post stay within
/// `[near, far]`, and posts are non-decreasing.
///
/// # Shapes
/// - `near`, `far`: `[rays, 1]`.
/// - output: `[rays, num_samples + 1]`.
pub fn stratified_t_vals(
    near: Tensor<2>,
    far: Tensor<2>,
    num_samples: usize,
    randomized: bool,
) -> Tensor<2> {
    let device = near.device();
    let [rays, _] = near.dims();
    let posts = num_samples + 1;
    let lin = linspace_row(posts, 1.0, &device);
    let t = near.clone().add(far.sub(near).mul(lin));
    if !randomized || posts < 2 {
        return t.detach();
    }
    let mids = t
        .clone()
        .slice_dim(1, 0..posts - 1)
        .add(t.clone().slice_dim(1, 1..posts))
        .mul_scalar(0.5);
    let upper = Tensor::cat(
        vec![mids.clone(), t.clone().slice_dim(1, posts - 1..posts)],
        1,
    );
    let lower = Tensor::cat(vec![t.slice_dim(1, 0..1), mids], 1);
    let u = Tensor::random([rays, posts], Distribution::Uniform(0.0, 1.0), &device);
    lower.clone().add(upper.sub(lower).mul(u)).detach()
}
