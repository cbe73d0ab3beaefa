//! Step functions along rays: interval ends `t: [rays, n + 1]`, sorted,
//! and one weight per interval `w: [rays, n]`. What the samplers of both
//! extents do with them: sampling a step function read as a density
//! ([`mod@pdf`]: Mip-NeRF's blur-resample, inverse-CDF sampling), the
//! proposal sampler's max-dilation ([`mod@dilate`]) and annealing
//! ([`mod@anneal`]), and the measures the proposal and distortion losses
//! take ([`measure`]).
//!
//! Where a step function is processed ray by ray (the fine level's
//! resampling, the proposal rounds), its host form (`*_host`, linear-time
//! loops) sits beside the tensor form; [`pdf::resample_t_vals`] and
//! [`crate::proposal::rounds`] choose between them per backend.

pub mod anneal;
pub mod dilate;
pub mod measure;
pub mod pdf;

use burn::tensor::{Device, Tensor, TensorData};

pub use anneal::{anneal_exponent, anneal_weights, anneal_weights_host};
pub use dilate::{max_dilate_weights, max_dilate_weights_host};
pub use measure::{INTERLEVEL_EPS, distortion_loss, interlevel_loss, outer_measure};
pub use pdf::{
    blur_weights, blur_weights_host, pdf_quantiles, resample_t_vals, resample_t_vals_on_device,
    resample_t_vals_on_host, sample_pdf, sample_pdf_at, sample_pdf_host,
};

/// Interval starts and ends of `[rays, n + 1]` posts, `[rays, n]` each.
pub(crate) fn lo_hi(t: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
    let [_, posts] = t.dims();
    (
        t.clone().slice_dim(1, 0..posts - 1),
        t.slice_dim(1, 1..posts),
    )
}

/// `n` evenly spaced values from `0` to `hi` as a `[1, n]` row.
pub(crate) fn linspace_row(n: usize, hi: f32, device: &Device) -> Tensor<2> {
    let denom = (n.max(2) - 1) as f32;
    let v: Vec<f32> = (0..n).map(|i| hi * i as f32 / denom).collect();
    Tensor::from_data(TensorData::new(v, [1, n]), device)
}
