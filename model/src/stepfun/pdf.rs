//! Sampling from a step function read as a piecewise-constant density:
//! Mip-NeRF's blurred weights, the quantiles, inverse-CDF sampling as tensor
//! ops ([`sample_pdf`], [`sample_pdf_at`]) and on the host
//! ([`sample_pdf_host`]), and the fine level's blur-resample
//! ([`resample_t_vals`]), on the host on the CPU backends.
//!
//! The tensor form compares every quantile with every CDF end (`[rays,
//! n + 1, k]` masks). The host form runs in `O(n + k)` per ray: the
//! quantiles `u` are sorted in each row and the CDF is non-decreasing, so
//! the interval each quantile falls in only moves forward, one merge of the
//! two sorted lists.
//!
//! All outputs are detached: the sample positions are never differentiated.

use burn::tensor::{Distribution, Tensor, TensorData};

use super::linspace_row;
use crate::host_work::{ReadReason, read_back};

/// Mip-NeRF's blurred weights: pad with the edge values, 2-tap max, 2-tap
/// mean, plus `padding`. Keeps the shape.
///
/// # Shapes
/// - `weights`: `[rays, samples]`; output: `[rays, samples]`.
pub fn blur_weights(weights: Tensor<2>, padding: f32) -> Tensor<2> {
    let [_, s] = weights.dims();
    let padded = Tensor::cat(
        vec![
            weights.clone().slice_dim(1, 0..1),
            weights.clone(),
            weights.slice_dim(1, s - 1..s),
        ],
        1,
    );
    let maxes = padded
        .clone()
        .slice_dim(1, 0..s + 1)
        .max_pair(padded.slice_dim(1, 1..s + 2));
    maxes
        .clone()
        .slice_dim(1, 0..s)
        .add(maxes.slice_dim(1, 1..s + 1))
        .mul_scalar(0.5)
        .add_scalar(padding)
}

/// The quantiles [`sample_pdf`] inverts the CDF at: `num_posts` evenly
/// spaced in `[0, 1)`, each jittered uniformly inside its own stratum when
/// `randomized` (one draw of the backend's generator), so every row is
/// sorted.
///
/// # Shapes
/// - output: `[rays, num_posts]`.
pub fn pdf_quantiles(
    rays: usize,
    num_posts: usize,
    randomized: bool,
    device: &burn::tensor::Device,
) -> Tensor<2> {
    let eps = 1e-5f32;
    if randomized {
        let step = 1.0 / num_posts as f32;
        let base = linspace_row(num_posts, step * (num_posts.max(2) - 1) as f32, device);
        let jitter = Tensor::random(
            [rays, num_posts],
            Distribution::Uniform(0.0, (step - f32::EPSILON) as f64),
            device,
        );
        base.add(jitter).clamp_max(1.0 - eps)
    } else {
        linspace_row(num_posts, 1.0 - eps, device).repeat_dim(0, rays)
    }
}

/// Inverse-CDF sampling of `num_posts` sorted values from the piecewise
/// constant density with `weights` on the intervals between `bins`
/// (Mip-NeRF's `sorted_piecewise_constant_pdf`). With `randomized`, each
/// quantile is jittered inside its own stratum, so the output stays sorted.
///
/// # Shapes
/// - `bins`: `[rays, samples + 1]`, non-decreasing.
/// - `weights`: `[rays, samples]`, non-negative.
/// - output: `[rays, num_posts]`, non-decreasing, within `[bins_0, bins_last]`.
pub fn sample_pdf(
    bins: Tensor<2>,
    weights: Tensor<2>,
    num_posts: usize,
    randomized: bool,
) -> Tensor<2> {
    let [rays, _] = weights.dims();
    let u = pdf_quantiles(rays, num_posts, randomized, &bins.device());
    sample_pdf_at(bins, weights, u)
}

/// [`sample_pdf`] at given quantiles `u` (`[rays, num_posts]`, each row
/// sorted in `[0, 1]`, e.g. [`pdf_quantiles`]).
///
/// # Shapes
/// - `bins`: `[rays, samples + 1]`; `weights`: `[rays, samples]`; `u`:
///   `[rays, num_posts]`; output: like `u`.
pub fn sample_pdf_at(bins: Tensor<2>, weights: Tensor<2>, u: Tensor<2>) -> Tensor<2> {
    let device = bins.device();
    let [rays, s] = weights.dims();
    let eps = 1e-5f32;
    // A ray with (near) zero total weight gets a uniform pdf.
    let weight_sum = weights.clone().sum_dim(1);
    let pad = weight_sum.clone().neg().add_scalar(eps).clamp_min(0.0);
    let weights = weights.add(pad.clone().div_scalar(s as f32));
    let pdf = weights.div(weight_sum.add(pad));
    let mut parts = vec![Tensor::zeros([rays, 1], &device)];
    if s > 1 {
        // (Empty slices are avoided: one sample per ray has cdf [0, 1].)
        parts.push(pdf.slice_dim(1, 0..s - 1).cumsum(1).clamp_max(1.0));
    }
    parts.push(Tensor::ones([rays, 1], &device));
    let cdf = Tensor::cat(parts, 1); // [rays, s + 1]
    let [_, num_posts] = u.dims();
    // mask[r, j, i] = u_i >= cdf_j: the interval of u_i starts at the last j
    // with the mask set and ends at the first j without it.
    let m = s + 1;
    let shape = [rays, m, num_posts];
    let mask = u
        .clone()
        .unsqueeze_dim::<3>(1)
        .expand(shape)
        .greater_equal(cdf.clone().unsqueeze_dim::<3>(2).expand(shape));
    let find = |x: Tensor<2>| {
        let full = x.clone().unsqueeze_dim::<3>(2).expand(shape);
        let first = x
            .clone()
            .slice_dim(1, 0..1)
            .unsqueeze_dim::<3>(2)
            .expand(shape);
        let last = x.slice_dim(1, m - 1..m).unsqueeze_dim::<3>(2).expand(shape);
        let x0 = first.mask_where(mask.clone(), full.clone()).max_dim(1);
        let x1 = full.mask_where(mask.clone(), last).min_dim(1);
        let x0: Tensor<2> = x0.squeeze_dim(1);
        let x1: Tensor<2> = x1.squeeze_dim(1);
        (x0, x1)
    };
    let (bins_g0, bins_g1) = find(bins);
    let (cdf_g0, cdf_g1) = find(cdf);
    let denom = cdf_g1.sub(cdf_g0.clone());
    let empty = denom.clone().lower_equal_elem(0.0);
    let t = u
        .sub(cdf_g0)
        .div(denom.clamp_min(1e-20))
        .mask_fill(empty, 0.0)
        .clamp(0.0, 1.0);
    bins_g0.clone().add(t.mul(bins_g1.sub(bins_g0))).detach()
}

/// [`sample_pdf`] at given quantiles, ray after ray: the
/// weights normalised into a pdf (a ray whose weights sum to less than
/// `1e-5` is padded towards uniform, as there), its CDF, and each quantile
/// `u` mapped linearly inside the interval of `bins` whose CDF range holds
/// it.
///
/// # Shapes
/// - `bins`: `rays * (n + 1)` non-decreasing ends, ray-major; `weights`:
///   `rays * n` non-negative; `u`: `rays * k`, each row sorted in `[0, 1]`
///   (e.g. [`pdf_quantiles`]).
/// - output: `rays * k`, each row non-decreasing within its bins.
pub fn sample_pdf_host(bins: &[f32], weights: &[f32], u: &[f32], rays: usize) -> Vec<f32> {
    let rays = rays.max(1);
    let n = weights.len() / rays;
    let k = u.len() / rays;
    let eps = 1e-5f32;
    let mut out = Vec::with_capacity(rays * k);
    let mut cdf = Vec::with_capacity(n + 1);
    for r in 0..rays {
        let b = &bins[r * (n + 1)..(r + 1) * (n + 1)];
        let w = &weights[r * n..(r + 1) * n];
        let sum: f32 = w.iter().sum();
        let pad = (eps - sum).max(0.0);
        let total = sum + pad;
        let per = pad / n as f32;
        cdf.clear();
        cdf.push(0.0f32);
        let mut acc = 0.0f32;
        for x in &w[..n.saturating_sub(1)] {
            acc += (x + per) / total;
            cdf.push(acc.min(1.0));
        }
        cdf.push(1.0);
        // `above`: the number of CDF ends at or below the quantile, which
        // only grows along the sorted quantiles.
        let mut above = 0usize;
        for &q in &u[r * k..(r + 1) * k] {
            while above < cdf.len() && cdf[above] <= q {
                above += 1;
            }
            let lo = above.saturating_sub(1);
            let hi = above.min(n);
            let denom = cdf[hi] - cdf[lo];
            let f = if denom <= 0.0 {
                0.0
            } else {
                ((q - cdf[lo]) / denom.max(1e-20)).clamp(0.0, 1.0)
            };
            out.push(b[lo] + f * (b[hi] - b[lo]));
        }
    }
    out
}

/// Mip-NeRF's blurred weights ([`blur_weights`]) on the host, ray after
/// ray.
///
/// # Shapes
/// - `weights`: `rays * samples`, ray-major; output: the same.
pub fn blur_weights_host(weights: &[f32], rays: usize, padding: f32) -> Vec<f32> {
    let n = weights.len() / rays.max(1);
    let mut out = Vec::with_capacity(weights.len());
    for w in weights.chunks(n.max(1)) {
        // The 2-tap max of the edge-padded row: `max(w[i - 1], w[i])` with
        // `w[-1] = w[0]` and `w[n] = w[n - 1]`.
        let max_at = |i: usize| w[i.saturating_sub(1).min(n - 1)].max(w[i.min(n - 1)]);
        out.extend((0..n).map(|i| 0.5 * (max_at(i) + max_at(i + 1)) + padding));
    }
    out
}

/// The fine level's fence posts: blur-resample of the coarse `weights`
/// (see [`blur_weights`]) and inverse-CDF sampling of `t_vals.len()` new
/// posts, detached. The new posts replace the coarse ones (no merge).
///
/// On the CPU backends the work is done on the host
/// ([`resample_t_vals_on_host`]: one pass a ray, where the tensor form
/// compares every quantile with every CDF end), elsewhere with tensor ops
/// ([`resample_t_vals_on_device`], nothing read back).
///
/// # Shapes
/// - `t_vals`: `[rays, samples + 1]`; `weights`: `[rays, samples]`.
/// - output: `[rays, samples + 1]`.
pub fn resample_t_vals(
    t_vals: Tensor<2>,
    weights: Tensor<2>,
    resample_padding: f32,
    randomized: bool,
) -> Tensor<2> {
    if crate::host_work::is_cpu_backend(&t_vals.device()) {
        resample_t_vals_on_host(t_vals, weights, resample_padding, randomized)
    } else {
        resample_t_vals_on_device(t_vals, weights, resample_padding, randomized)
    }
}

/// [`resample_t_vals`] with tensor ops (see there for the shapes).
pub fn resample_t_vals_on_device(
    t_vals: Tensor<2>,
    weights: Tensor<2>,
    resample_padding: f32,
    randomized: bool,
) -> Tensor<2> {
    let [_, posts] = t_vals.dims();
    let blurred = blur_weights(weights.detach(), resample_padding);
    sample_pdf(t_vals.detach(), blurred, posts, randomized)
}

/// [`resample_t_vals`] on the host: the posts and weights read back, the
/// quantiles drawn from the device's generator as the tensor form draws
/// them, the new posts uploaded (see there for the shapes).
pub fn resample_t_vals_on_host(
    t_vals: Tensor<2>,
    weights: Tensor<2>,
    resample_padding: f32,
    randomized: bool,
) -> Tensor<2> {
    let device = t_vals.device();
    let [rays, posts] = t_vals.dims();
    let host = |t: Tensor<2>| read_back(ReadReason::FineResample, t);
    let u = host(pdf_quantiles(rays, posts, randomized, &device));
    let blurred = blur_weights_host(&host(weights), rays, resample_padding);
    let drawn = sample_pdf_host(&host(t_vals), &blurred, &u, rays);
    Tensor::from_data(TensorData::new(drawn, [rays, posts]), &device)
}
