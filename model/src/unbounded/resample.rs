//! The proposal sampler's resampling on the host, in `O(n + k)` per ray:
//! the same annealing as [`super::anneal_weights`] and the same inverse-CDF
//! sampling as [`crate::sampling::sample_pdf`], whose tensor form compares
//! every quantile with every CDF end (`[rays, n + 1, k]` masks, twice a
//! round) and, after the dilation ([`super::max_dilate_weights_host`],
//! already on the host), cost the CPU step more than the proposal MLP.
//!
//! The quantiles `u` are sorted in each row and the CDF is non-decreasing,
//! so the interval each quantile falls in only moves forward: one merge of
//! the two sorted lists.

/// [`super::anneal_weights`] in place, ray after ray: `(w + padding)^exponent`
/// on intervals of positive width (the base floored at the smallest normal
/// f32), 0 on empty ones.
///
/// # Shapes
/// - `t`: `rays * (n + 1)` ends, ray-major; `w`: `rays * n`.
pub fn anneal_weights_host(t: &[f32], w: &mut [f32], rays: usize, exponent: f32, padding: f32) {
    let n = w.len() / rays.max(1);
    for (r, row) in w.chunks_mut(n.max(1)).enumerate() {
        let ends = &t[r * (n + 1)..(r + 1) * (n + 1)];
        for (j, x) in row.iter_mut().enumerate() {
            *x = if ends[j + 1] <= ends[j] {
                0.0
            } else {
                (exponent * (*x + padding).max(f32::MIN_POSITIVE).ln()).exp()
            };
        }
    }
}

/// [`crate::sampling::sample_pdf`] at given quantiles, ray after ray: the
/// weights normalised into a pdf (a ray whose weights sum to less than
/// `1e-5` is padded towards uniform, as there), its CDF, and each quantile
/// `u` mapped linearly inside the interval of `bins` whose CDF range holds
/// it.
///
/// # Shapes
/// - `bins`: `rays * (n + 1)` non-decreasing ends, ray-major; `weights`:
///   `rays * n` non-negative; `u`: `rays * k`, each row sorted in `[0, 1]`
///   (e.g. [`crate::sampling::pdf_quantiles`]).
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
