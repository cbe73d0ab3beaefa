//! Per-photograph exposure: a gain and an offset per colour channel for
//! each training photograph, learned with the field.
//!
//! Photographs of one capture are often taken with different exposure and
//! white balance (automatic camera settings, light through a window). A
//! field that must reproduce each photograph's colours exactly explains the
//! differences with geometry: colour placed along the rays of one
//! photograph that the others do not see, which held-out views then see
//! from elsewhere. Six numbers per photograph absorb a global colour change
//! and nothing else (they know no position or direction), as the learned
//! exposure of RawNeRF and Zip-NeRF does with a per-image scale, and as
//! NeRF in the Wild's appearance codes do with more freedom.
//!
//! The field itself renders the capture at its photographs' common
//! exposure: the correction is applied to a training ray's rendered colour
//! before the colour loss only, a penalty on its square holds the
//! corrections near none, and views that are not training photographs
//! (held-out photographs, novel views, every render) use none.

use burn::config::Config;
use burn::module::{Module, Param};
use burn::tensor::{Device, Int, Tensor, TensorData};

/// Configuration of [`Exposure`].
#[derive(Config, Debug)]
pub struct ExposureConfig {
    /// Photographs with a correction each: frames `0..images` of the scene
    /// (a frame index at or past it, such as a novel view's, gets none).
    pub images: usize,
}

impl ExposureConfig {
    /// Builds the corrections, all zero (no correction) to start.
    pub fn init(&self, device: &Device) -> Exposure {
        Exposure {
            params: Param::from_tensor(Tensor::zeros([self.images.max(1), 6], device)),
            images: self.images,
        }
    }
}

/// The learned exposure of each training photograph (see the module docs).
#[derive(Module, Debug)]
pub struct Exposure {
    /// `[images, 6]`: per photograph, the log-gain of red, green and blue,
    /// then the offset of each.
    pub params: Param<Tensor<2>>,
    /// Photographs with a correction.
    #[module(skip)]
    pub images: usize,
}

impl Exposure {
    /// The correction of each ray, from the frame it was drawn from; zero
    /// rows for frames without one.
    ///
    /// # Shapes
    /// - output: `[frames.len(), 6]`.
    pub fn per_ray(&self, frames: &[usize]) -> Tensor<2> {
        frame_rows(self.params.val(), frames, self.images)
    }
}

/// Row `f` of `table` for each frame `f` below `rows`, a zero row for the
/// others: a per-photograph table read out per ray.
///
/// # Shapes
/// - `table`: `[>= rows, c]`; output `[frames.len(), c]`.
pub(crate) fn frame_rows(table: Tensor<2>, frames: &[usize], rows: usize) -> Tensor<2> {
    let device = table.device();
    let [none, c] = table.dims();
    // The zero row appended below: no correction.
    let table = Tensor::cat(vec![table, Tensor::zeros([1, c], &device)], 0);
    let ids: Vec<i64> = frames
        .iter()
        .map(|&f| (if f < rows { f } else { none }) as i64)
        .collect();
    let ids = Tensor::<1, Int>::from_data(TensorData::new(ids, [frames.len()]), &device);
    table.select(0, ids)
}

/// `rgb * exp(log_gain) + offset`, per ray and channel, with
/// `correction = [log_gain | offset]` as [`Exposure::per_ray`] gives it.
///
/// # Shapes
/// - `rgb`: `[n, 3]`; `correction`: `[n, 6]`; output `[n, 3]`.
pub fn expose(rgb: Tensor<2>, correction: Tensor<2>) -> Tensor<2> {
    let [n, _] = correction.dims();
    let gain = correction.clone().slice([0..n, 0..3]).exp();
    let offset = correction.slice([0..n, 3..6]);
    rgb * gain + offset
}

/// The mean over rays of the summed squares of their corrections, `[1]`:
/// the penalty that holds the field at the photographs' common exposure.
///
/// # Shapes
/// - `correction`: `[n, 6]`.
pub fn exposure_penalty(correction: Tensor<2>) -> Tensor<1> {
    correction.square().sum_dim(1).mean()
}
