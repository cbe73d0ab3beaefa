//! One proposal round's resampling (Mip-NeRF 360's proposal sampler): round
//! `round` (after the first) max-dilates the previous histogram `(s, w)`,
//! the weights are annealed, and `count + 1` new posts are drawn from them
//! by inverse-CDF sampling at [`pdf_quantiles`], the first and the last
//! pinned to 0 and 1 so that every round covers the whole ray, jittered or
//! not. The posts are detached: only the proposal weights learn (from the
//! interlevel loss).
//!
//! Two forms of the same round: on the host ([`resample_on_host`], the
//! linear-time loops of [`crate::stepfun`]'s host forms: the
//! inputs read back, the posts uploaded) and with tensor ops on the
//! device ([`resample_on_device`], nothing read back). [`resample`] takes
//! the host form on the CPU backends, where it is the faster
//! ([`crate::host_work`]).

use burn::tensor::{Tensor, TensorData};

use crate::host_work::{ReadReason, read_back};
use crate::stepfun::{
    anneal_weights, anneal_weights_host, max_dilate_weights, max_dilate_weights_host,
    pdf_quantiles, sample_pdf_at, sample_pdf_host,
};

/// A round's values on the host (the CPU backends' form).
fn host<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    read_back(ReadReason::ProposalRound, t)
}

/// How one round resamples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Round {
    /// How far the previous histogram is dilated (`None`: the first round,
    /// which resamples the whole ray as it is).
    pub dilation: Option<f32>,
    /// The annealing exponent ([`crate::stepfun::anneal_exponent`]).
    pub exponent: f32,
    /// Added to the weights before annealing.
    pub padding: f32,
    /// Samples drawn (`count + 1` posts).
    pub count: usize,
    /// Jittered quantiles (one draw of the device's generator).
    pub randomized: bool,
}

/// The round's new posts, in the form the device computes fastest.
///
/// # Shapes
/// - `s`: `[n, posts]` sorted in `[0, 1]`; `w`: `[n, posts - 1]`; output:
///   `[n, count + 1]`.
pub fn resample(round: &Round, s: Tensor<2>, w: Tensor<2>) -> Tensor<2> {
    if crate::host_work::is_cpu_backend(&s.device()) {
        resample_on_host(round, s, w)
    } else {
        resample_on_device(round, s, w)
    }
}

/// The round on the host (see [`resample`] for the shapes).
pub fn resample_on_host(round: &Round, s: Tensor<2>, w: Tensor<2>) -> Tensor<2> {
    let device = s.device();
    let [n, posts] = s.dims();
    let count = round.count;
    let (ends, mut weights) = match round.dilation {
        Some(d) => {
            let (ends, weights) =
                max_dilate_weights_host(&host(s), &host(w), n, d, (0.0, 1.0), true);
            let m = 3 * (posts - 1);
            // The outermost dilated intervals are clamped to zero width.
            (inner_rows(&ends, m + 1), inner_rows(&weights, m))
        }
        None => (host(s), host(w)),
    };
    anneal_weights_host(&ends, &mut weights, n, round.exponent, round.padding);
    let u = host(pdf_quantiles(n, count + 1, round.randomized, &device));
    let mut drawn = sample_pdf_host(&ends, &weights, &u, n);
    for row in drawn.chunks_mut(count + 1) {
        row[0] = 0.0;
        row[count] = 1.0;
    }
    Tensor::from_data(TensorData::new(drawn, [n, count + 1]), &device)
}

/// Each row of `width` (at least 2) numbers of `values` without its first
/// and last.
fn inner_rows(values: &[f32], width: usize) -> Vec<f32> {
    let mut inner = Vec::with_capacity(values.len() / width * (width - 2));
    for row in values.chunks_exact(width) {
        inner.extend_from_slice(&row[1..width - 1]);
    }
    inner
}

/// Elements of the dilation's comparison tensor of one chunk of rays in
/// [`resample_on_device`]: 2^24 (64 MiB of f32), half of the largest
/// storage buffer wgpu binds by default.
pub const DEVICE_CHUNK_ELEMENTS: usize = 1 << 24;

/// The round with tensor ops on the device (see [`resample`] for the
/// shapes): the dilation compares every new end with every interval
/// (`[n, 3 (posts - 1) + 1, posts - 1]`), the sampling every quantile with
/// every CDF end, a chunk of rays at a time so that the comparisons stay
/// within [`DEVICE_CHUNK_ELEMENTS`]; the quantiles are drawn once for all.
pub fn resample_on_device(round: &Round, s: Tensor<2>, w: Tensor<2>) -> Tensor<2> {
    resample_on_device_in_chunks(round, s, w, DEVICE_CHUNK_ELEMENTS)
}

/// [`resample_on_device`] with chunks of rays whose comparison tensors
/// hold at most `chunk_elements` (at least one ray a chunk).
pub fn resample_on_device_in_chunks(
    round: &Round,
    s: Tensor<2>,
    w: Tensor<2>,
    chunk_elements: usize,
) -> Tensor<2> {
    let device = s.device();
    let [n, posts] = s.dims();
    let (s, w) = (s.detach(), w.detach());
    let u = pdf_quantiles(n, round.count + 1, round.randomized, &device);
    let per_ray = (3 * posts) * posts.max(round.count + 1);
    let chunk = (chunk_elements / per_ray.max(1)).clamp(1, n.max(1));
    let parts: Vec<Tensor<2>> = (0..n)
        .step_by(chunk)
        .map(|start| {
            let rows = start..(start + chunk).min(n);
            let part = |t: &Tensor<2>| t.clone().slice_dim(0, rows.clone());
            draw(round, part(&s), part(&w), part(&u))
        })
        .collect();
    let drawn = Tensor::cat(parts, 0);
    let mut columns = vec![Tensor::zeros([n, 1], &device)];
    if round.count > 1 {
        columns.push(drawn.slice_dim(1, 1..round.count));
    }
    columns.push(Tensor::ones([n, 1], &device));
    Tensor::cat(columns, 1)
}

/// One chunk of [`resample_on_device`]: dilation, annealing and the
/// inverse-CDF sampling at the quantiles `u`, before the pinning.
fn draw(round: &Round, s: Tensor<2>, w: Tensor<2>, u: Tensor<2>) -> Tensor<2> {
    let [_, posts] = s.dims();
    let (ends, weights) = match round.dilation {
        Some(d) => {
            let (ends, weights) = max_dilate_weights(s, w, d, (0.0, 1.0), true);
            let m = 3 * (posts - 1);
            // The outermost dilated intervals are clamped to zero width.
            (ends.slice_dim(1, 1..m), weights.slice_dim(1, 1..m - 1))
        }
        None => (s, w),
    };
    let weights = anneal_weights(ends.clone(), weights, round.exponent, round.padding);
    sample_pdf_at(ends, weights, u)
}
