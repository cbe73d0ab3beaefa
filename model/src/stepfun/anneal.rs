//! Annealing of proposal weights before resampling (Mip-NeRF 360): the
//! exponent over training and the annealed weights, as tensor ops
//! ([`anneal_weights`]) and on the host ([`anneal_weights_host`]).

use burn::tensor::Tensor;

use super::lo_hi;

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

/// [`anneal_weights`] in place, ray after ray: `(w + padding)^exponent`
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
