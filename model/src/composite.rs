//! Volume-rendering compositing in the numerically stable form: the
//! transmittance is `exp` of an exclusive cumulative sum of optical depths,
//! never a product of `1 - alpha` or a `log(1 - alpha)`, so it stays exact for
//! densities from 0 to 1e10 and for zero-length intervals.

use burn::tensor::{Tensor, TensorData};

/// Floor on the accumulated opacity when normalising the expected depth.
pub const DEPTH_ACC_EPS: f32 = 1e-10;

/// Result of compositing one level.
#[derive(Debug, Clone)]
pub struct Composite {
    /// Compositing weights `w_i = alpha_i T_i`, `[rays, samples]`.
    pub weights: Tensor<2>,
    /// Colour, with `(1 - acc) * background` when a background is given, `[rays, 3]`.
    pub rgb: Tensor<2>,
    /// Expected metric depth `sum w t_mid / max(acc, eps)`, `[rays, 1]`.
    pub depth: Tensor<2>,
    /// Accumulated opacity `sum w`, `[rays, 1]`.
    pub acc: Tensor<2>,
}

/// Compositing weights from densities and fence posts.
///
/// `delta_i = (t_{i+1} - t_i) |d|`, `tau_i = sigma_i delta_i`,
/// `T_i = exp(-sum_{j<i} tau_j)`, `w_i = (1 - exp(-tau_i)) T_i`.
///
/// # Shapes
/// - `density`: `[rays, samples]`, non-negative.
/// - `t_vals`: `[rays, samples + 1]`.
/// - `dir_norm`: `[rays, 1]` length of the (unnormalised) direction.
/// - output: `[rays, samples]`.
pub fn compute_weights(density: Tensor<2>, t_vals: Tensor<2>, dir_norm: Tensor<2>) -> Tensor<2> {
    let [rays, _] = density.dims();
    let none = Tensor::zeros([rays, 1], &density.device());
    segment_weights(density, t_vals, dir_norm, none).0
}

/// The optical depths of one segment of consecutive samples, given the
/// optical depth `tau_before` already accumulated along each ray: what the
/// segment's weights ([`SegmentOptics::weights`]) and the depth where a
/// ray's weight crosses a level ([`depth_crossing`]) are both read from.
#[derive(Debug, Clone)]
pub struct SegmentOptics {
    /// Each interval's optical depth `sigma_i delta_i`, `[rays, samples]`.
    pub tau: Tensor<2>,
    /// The optical depth ahead of each interval (from the ray's start),
    /// `[rays, samples]`.
    pub ahead: Tensor<2>,
    /// The optical depth after the segment, `[rays, 1]` (`exp(-after)` is
    /// the transmittance left for what lies behind).
    pub after: Tensor<2>,
}

impl SegmentOptics {
    /// `delta_i = (t_{i+1} - t_i) |d|`, `tau_i = sigma_i delta_i`, and the
    /// exclusive sum of the `tau` before each interval.
    ///
    /// # Shapes
    /// - `density`: `[rays, samples]`; `t_vals`: `[rays, samples + 1]`.
    /// - `dir_norm`, `tau_before`: `[rays, 1]`.
    pub fn new(
        density: Tensor<2>,
        t_vals: Tensor<2>,
        dir_norm: Tensor<2>,
        tau_before: Tensor<2>,
    ) -> Self {
        let [_, s] = density.dims();
        let delta = t_vals
            .clone()
            .slice_dim(1, 1..s + 1)
            .sub(t_vals.slice_dim(1, 0..s))
            .mul(dir_norm);
        let tau = density.mul(delta);
        // Exclusive scan by shifting (an inclusive scan minus tau would cancel
        // catastrophically after a huge tau).
        let ahead = if s > 1 {
            Tensor::cat(
                vec![
                    tau_before.clone(),
                    tau.clone()
                        .slice_dim(1, 0..s - 1)
                        .cumsum(1)
                        .add(tau_before.clone()),
                ],
                1,
            )
        } else {
            tau_before.clone()
        };
        let after = tau.clone().sum_dim(1).add(tau_before);
        SegmentOptics { tau, ahead, after }
    }

    /// The compositing weights `w_i = (1 - exp(-tau_i)) exp(-ahead_i)`,
    /// `[rays, samples]`.
    pub fn weights(&self) -> Tensor<2> {
        let alpha = self.tau.clone().neg().exp().neg().add_scalar(1.0);
        alpha.mul(self.ahead.clone().neg().exp())
    }
}

/// Compositing weights of one segment of consecutive samples, given the
/// optical depth `tau_before` already accumulated along each ray: the
/// segments of a ray, composited in order, give [`compute_weights`] of the
/// whole ray. Returns the weights and the optical depth after the segment
/// (`exp(-tau_after)` is the transmittance left for what lies behind).
///
/// # Shapes
/// - `density`: `[rays, samples]`; `t_vals`: `[rays, samples + 1]`.
/// - `dir_norm`, `tau_before`: `[rays, 1]`.
/// - output: (`[rays, samples]`, `[rays, 1]`).
pub fn segment_weights(
    density: Tensor<2>,
    t_vals: Tensor<2>,
    dir_norm: Tensor<2>,
    tau_before: Tensor<2>,
) -> (Tensor<2>, Tensor<2>) {
    let optics = SegmentOptics::new(density, t_vals, dir_norm, tau_before);
    (optics.weights(), optics.after)
}

/// Midpoints of consecutive fence posts.
///
/// # Shapes
/// - `t_vals`: `[rays, samples + 1]`; output: `[rays, samples]`.
pub fn t_mids(t_vals: Tensor<2>) -> Tensor<2> {
    let [_, posts] = t_vals.dims();
    t_vals
        .clone()
        .slice_dim(1, 0..posts - 1)
        .add(t_vals.slice_dim(1, 1..posts))
        .mul_scalar(0.5)
}

/// Composites per-sample values `[rays, samples, c]` with `weights`
/// `[rays, samples]` into `[rays, c]` (`sum_i w_i v_i`).
pub fn composite_values(weights: Tensor<2>, values: Tensor<3>) -> Tensor<2> {
    let [rays, _, c] = values.dims();
    weights
        .unsqueeze_dim::<3>(1)
        .matmul(values)
        .reshape([rays, c])
}

/// Floor of the opacity a composited feature is divided by.
pub const FEATURE_ACC_EPS: f32 = 1e-6;

/// The weighted mean of features along each ray, `sum w f / sum w`, with the
/// weights detached. A feature is what the ray *hits*: dividing by the
/// opacity keeps rays with `acc < 1` (the start of training, thin surfaces,
/// top-k samples) from being pulled towards zero, which after a PCA lift
/// `m + U^T c` would mean towards the scene's mean feature.
///
/// # Shapes
/// - `weights`: `[rays, samples]`; `features`: `[rays, samples, c]`.
/// - output: `[rays, c]`.
pub fn composite_features_mean(weights: Tensor<2>, features: Tensor<3>) -> Tensor<2> {
    let weights = weights.detach();
    let acc = weights.clone().sum_dim(1).clamp_min(FEATURE_ACC_EPS);
    composite_values(weights, features).div(acc)
}

/// Full compositing of one level: weights, colour, depth and opacity.
///
/// # Shapes
/// - `density`: `[rays, samples]`; `rgb`: `[rays, samples, 3]`.
/// - `t_vals`: `[rays, samples + 1]`; `dir_norm`: `[rays, 1]`.
pub fn composite(
    density: Tensor<2>,
    rgb: Tensor<3>,
    t_vals: Tensor<2>,
    dir_norm: Tensor<2>,
    background: Option<[f32; 3]>,
) -> Composite {
    let weights = compute_weights(density, t_vals.clone(), dir_norm);
    let acc = weights.clone().sum_dim(1);
    let depth = expected_depth(weights.clone().mul(t_mids(t_vals)).sum_dim(1), acc.clone());
    let color = over_background(
        composite_values(weights.clone(), rgb),
        acc.clone(),
        background,
    );
    Composite {
        weights,
        rgb: color,
        depth,
        acc,
    }
}

/// The expected depth from the weighted sum of a ray's sample midpoints
/// (over one segment or several): `sum w t_mid / max(acc, eps)`.
///
/// # Shapes
/// - `depth_sum`, `acc`: `[rays, 1]`; output: `[rays, 1]`.
pub fn expected_depth(depth_sum: Tensor<2>, acc: Tensor<2>) -> Tensor<2> {
    depth_sum.div(acc.clamp_min(DEPTH_ACC_EPS))
}

/// The colour from the weighted sum of a ray's sample colours (over one
/// segment or several): `sum w c + (1 - acc) background`, or the sum as it
/// is without a background.
///
/// # Shapes
/// - `rgb_sum`: `[rays, 3]`; `acc`: `[rays, 1]`; output: `[rays, 3]`.
pub fn over_background(
    rgb_sum: Tensor<2>,
    acc: Tensor<2>,
    background: Option<[f32; 3]>,
) -> Tensor<2> {
    match background {
        Some(bg) => {
            let bg = Tensor::from_data(TensorData::new(bg.to_vec(), [1, 3]), &rgb_sum.device());
            rgb_sum.add(acc.neg().add_scalar(1.0).mul(bg))
        }
        None => rgb_sum,
    }
}

/// Where along a segment of a ray the accumulated weight first reaches
/// `level` (the median depth at `level = 0.5`), for the rays whose crossing
/// lies in this segment. It is found in optical depth, where it is exact:
/// the weight reaches `level` where the optical depth from the ray's start
/// reaches `-ln(1 - level)`, and inside an interval of constant density
/// the optical depth grows linearly with `t`. An opaque interval (however
/// long: the far end of an unbounded ray) crosses at its start; no weight
/// saturating in `f32` blurs it. Returns the crossing depth (zero where the
/// ray does not cross here) and 1 where it crosses here, 0 elsewhere.
///
/// # Shapes
/// - `optics`: the segment's ([`SegmentOptics::new`]); `t_vals`:
///   `[rays, samples + 1]`, its posts.
/// - output: (`[rays, 1]`, `[rays, 1]`).
pub fn depth_crossing(
    optics: &SegmentOptics,
    t_vals: Tensor<2>,
    level: f32,
) -> (Tensor<2>, Tensor<2>) {
    let [_, s] = optics.tau.dims();
    let lo = t_vals.clone().slice_dim(1, 0..s);
    let width = t_vals.slice_dim(1, 1..s + 1).sub(lo.clone());
    let target = -(1.0 - level).ln();
    let (tau, ahead) = (optics.tau.clone(), optics.ahead.clone());
    let hit = ahead
        .clone()
        .lower_elem(target)
        .bool_and(ahead.clone().add(tau.clone()).greater_equal_elem(target))
        .float();
    let fraction = ahead
        .neg()
        .add_scalar(target)
        .div(tau.clamp_min(1e-30))
        .clamp(0.0, 1.0);
    let t = lo.add(width.mul(fraction));
    (t.mul(hit.clone()).sum_dim(1), hit.sum_dim(1))
}

/// The median depth of each ray: where its accumulated weight reaches a
/// half ([`depth_crossing`] over the whole ray). A ray whose weight never
/// reaches a half (mostly empty space) takes its expected depth
/// `expected`. Unlike the expected depth it is not pulled out by a little
/// weight far behind the surface: on an unbounded ray the last interval
/// reaches thousands of units out, and a thousandth of the weight there
/// moves the mean by metres.
///
/// # Shapes
/// - `density`: `[rays, samples]`; `t_vals`: `[rays, samples + 1]`;
///   `dir_norm`, `expected`: `[rays, 1]`; output: `[rays, 1]`.
pub fn median_depth(
    density: Tensor<2>,
    t_vals: Tensor<2>,
    dir_norm: Tensor<2>,
    expected: Tensor<2>,
) -> Tensor<2> {
    let [rays, _] = density.dims();
    let none = Tensor::zeros([rays, 1], &density.device());
    let optics = SegmentOptics::new(density, t_vals.clone(), dir_norm, none);
    let (median, found) = depth_crossing(&optics, t_vals, 0.5);
    median.mask_where(found.lower_elem(0.5), expected)
}
