//! Per-photograph appearance codes (NeRF in the Wild's appearance
//! embedding, as nerfacto uses it): a learned vector for each training
//! photograph, given to the colour branch beside the view direction.
//!
//! Where [`crate::exposure`] absorbs a global colour change (six numbers
//! that know no position), a code lets the colour of each place depend on
//! the photograph: a window bright in one and dark in another, a shadow
//! that moves. The colour branch sees the code of the ray's photograph in
//! training; every other view (held-out photographs, novel views, every
//! render) sees the zero code, which a penalty on the codes' squares keeps
//! at the photographs' common appearance, and which is where every code
//! starts.

use burn::config::Config;
use burn::module::{Module, Param};
use burn::tensor::{Device, Tensor};

use crate::exposure::frame_rows;

/// Configuration of [`AppearanceCodes`].
#[derive(Config, Debug)]
pub struct AppearanceCodesConfig {
    /// Photographs with a code each: frames `0..images` of the scene (a
    /// frame index at or past it, such as a novel view's, gets the zero
    /// code).
    pub images: usize,
    /// Length of each code (nerfacto: 32).
    #[config(default = 16)]
    pub dim: usize,
}

impl AppearanceCodesConfig {
    /// Builds the codes, all zero (the common appearance) to start.
    pub fn init(&self, device: &Device) -> AppearanceCodes {
        AppearanceCodes {
            codes: Param::from_tensor(Tensor::zeros([self.images.max(1), self.dim.max(1)], device)),
            images: self.images,
        }
    }
}

/// The learned appearance code of each training photograph (see the module
/// docs).
#[derive(Module, Debug)]
pub struct AppearanceCodes {
    /// `[images, dim]`: one code per photograph.
    pub codes: Param<Tensor<2>>,
    /// Photographs with a code.
    #[module(skip)]
    pub images: usize,
}

impl AppearanceCodes {
    /// The code of each ray, from the frame it was drawn from; zero rows
    /// for frames without one.
    ///
    /// # Shapes
    /// - output: `[frames.len(), dim]`.
    pub fn per_ray(&self, frames: &[usize]) -> Tensor<2> {
        frame_rows(self.codes.val(), frames, self.images)
    }

    /// Length of each code.
    pub fn dim(&self) -> usize {
        self.codes.val().dims()[1]
    }

    /// The mean over photographs of each code's squared norm, `[1]`.
    pub fn penalty(&self) -> Tensor<1> {
        let c = self.codes.val();
        let [images, _] = c.dims();
        c.square().sum().div_scalar(images.max(1) as f32)
    }
}
