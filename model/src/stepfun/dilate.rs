//! Max-dilation of a step function's density (multinerf's
//! `max_dilate_weights`), in two forms side by side: tensor ops on the
//! device ([`max_dilate_weights`]) and the host's linear-time loop
//! ([`max_dilate_weights_host`]).
//!
//! The tensor form compares every new end with every interval (`[rays,
//! 3 n + 1, n]`), which dominates a proposal round's cost on the CPU
//! backends; the host form runs in `O(n)` per ray. The intervals that cover
//! a point `x` after dilation by `d` (those with `lo_j - d <= x < hi_j + d`)
//! are a contiguous run of indices whose both ends only move forward as
//! `x` grows (the `lo` and `hi` are sorted), so the largest density over
//! them is a sliding-window maximum.

use std::collections::VecDeque;

use burn::tensor::Tensor;

use super::lo_hi;

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

/// Max-dilation of step functions, ray after ray: the same ends and weights
/// as [`max_dilate_weights`] (the ends sorted and clamped to
/// `domain`, the density on each new interval the largest dilated density
/// covering its left end, the weights that density times the new widths,
/// renormalised to sum to 1 when `renormalize`).
///
/// # Shapes
/// - `t`: `rays * (n + 1)` sorted ends, ray-major; `w`: `rays * n`.
/// - outputs: `rays * (3 n + 1)` ends and `rays * 3 n` weights.
pub fn max_dilate_weights_host(
    t: &[f32],
    w: &[f32],
    rays: usize,
    dilation: f32,
    domain: (f32, f32),
    renormalize: bool,
) -> (Vec<f32>, Vec<f32>) {
    let n = w.len() / rays.max(1);
    let eps = f32::EPSILON * f32::EPSILON;
    let mut ends_out = Vec::with_capacity(rays * (3 * n + 1));
    let mut weights_out = Vec::with_capacity(rays * 3 * n);
    let mut ends = Vec::with_capacity(3 * n + 1);
    let mut density = Vec::with_capacity(n);
    let mut window: VecDeque<usize> = VecDeque::with_capacity(n);
    for r in 0..rays {
        let t = &t[r * (n + 1)..(r + 1) * (n + 1)];
        let w = &w[r * n..(r + 1) * n];
        density.clear();
        density.extend((0..n).map(|j| w[j] / (t[j + 1] - t[j]).max(eps)));
        ends.clear();
        ends.extend_from_slice(t);
        ends.extend(t[..n].iter().map(|&lo| lo - dilation));
        ends.extend(t[1..].iter().map(|&hi| hi + dilation));
        ends.sort_by(f32::total_cmp);
        for e in ends.iter_mut() {
            *e = e.clamp(domain.0, domain.1);
        }
        window.clear();
        let (mut entered, mut start) = (0usize, 0usize);
        let row_start = weights_out.len();
        for k in 0..3 * n {
            let x = ends[k];
            // Intervals whose dilated start is at or before x join...
            while entered < n && t[entered] - dilation <= x {
                while window
                    .back()
                    .is_some_and(|&b| density[b] <= density[entered])
                {
                    window.pop_back();
                }
                window.push_back(entered);
                entered += 1;
            }
            // ...and those whose dilated end is at or before x leave.
            while start < entered && t[start + 1] + dilation <= x {
                start += 1;
            }
            while window.front().is_some_and(|&f| f < start) {
                window.pop_front();
            }
            let d = window.front().map_or(0.0, |&f| density[f]);
            weights_out.push(d * (ends[k + 1] - x));
        }
        if renormalize {
            let row = &mut weights_out[row_start..];
            let total: f32 = row.iter().sum::<f32>().max(eps);
            row.iter_mut().for_each(|v| *v /= total);
        }
        ends_out.extend_from_slice(&ends);
    }
    (ends_out, weights_out)
}
