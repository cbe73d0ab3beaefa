//! The proposal sampler of Mip-NeRF 360 (section 3): a small density-only
//! MLP (on the IPE, or on a small hash encoding as nerfacto's proposal
//! networks are), queried in rounds along each ray, whose weights decide where the
//! NeRF MLP samples. It is trained only by the interlevel loss
//! ([`crate::stepfun::interlevel_loss`]), which makes each round's
//! histogram an upper envelope of the NeRF weights; the NeRF MLP is then
//! evaluated once per ray (no coarse pass of the full-size MLP).
//!
//! Sampling happens in `s`, the ray's normalised coordinate: normalised
//! disparity for an unbounded field, normalised distance in the box (see
//! [`crate::extent::Extent::spacing`]).

use burn::config::Config;
use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::{relu, softplus};
use burn::tensor::{Device, Tensor};

use crate::fast_field::exp_density;
use crate::hashgrid::{HashGrid, HashGridConfig};
use crate::mip::{integrated_pos_enc, ipe_dim};

pub mod rounds;

/// Configuration of the proposal sampler: its MLP and its sampling rounds.
#[derive(Config, Debug)]
pub struct ProposalConfig {
    /// Samples of each proposal round, in order (Mip-NeRF 360: two rounds
    /// of 64). The NeRF level then takes the model's `num_samples`.
    #[config(default = "vec![64, 64]")]
    pub samples: Vec<usize>,
    /// Hidden layers of the proposal MLP.
    #[config(default = 2)]
    pub depth: usize,
    /// Width of the proposal MLP.
    #[config(default = 64)]
    pub width: usize,
    /// Lowest IPE degree of the proposal MLP's input.
    #[config(default = 0)]
    pub min_deg: usize,
    /// One past its highest IPE degree (a smoother input than the NeRF
    /// MLP's: it only has to bound where density is).
    #[config(default = 10)]
    pub max_deg: usize,
    /// Dilation of a round's histogram before it is resampled, in `s`: this
    /// plus `dilation_multiplier` over the product of the samples of the
    /// rounds before (Mip-NeRF 360: 0.0025 and 0.5).
    #[config(default = 0.0025)]
    pub dilation_bias: f32,
    /// See `dilation_bias`.
    #[config(default = 0.5)]
    pub dilation_multiplier: f32,
    /// Slope of the annealing of the resampling weights over training
    /// (Schlick's bias, Mip-NeRF 360: 10; 0 is off).
    #[config(default = 10.0)]
    pub anneal_slope: f32,
    /// Added to the weights before resampling.
    #[config(default = 0.0)]
    pub resample_padding: f32,
    /// A hash encoding of the sample's position as the MLP's input in place
    /// of the IPE (nerfacto's proposal networks: 5 levels of 2^17 rows, up
    /// to 128-256 cells across), with an exponential density; `None`: the
    /// IPE and a softplus density.
    pub hash: Option<HashGridConfig>,
    /// Added to the raw density of the hash form before its exponential
    /// (see the fast field's `density_shift`; `None`: 0).
    pub density_shift: Option<f32>,
}

impl ProposalConfig {
    /// Builds the proposal MLP (a `depth` of 0 is taken as 1, `width` 0 as 1).
    pub fn init(&self, device: &Device) -> ProposalMlp {
        let width = self.width.max(1);
        let input = match &self.hash {
            Some(h) => h.output_dim(),
            None => ipe_dim(self.min_deg, self.max_deg),
        };
        let layers = (0..self.depth.max(1))
            .map(|i| LinearConfig::new(if i == 0 { input } else { width }, width).init(device))
            .collect();
        ProposalMlp {
            layers,
            density: LinearConfig::new(width, 1).init(device),
            min_deg: self.min_deg,
            max_deg: self.max_deg,
            hash: self.hash.as_ref().map(|h| h.init(device)),
            density_shift: self.density_shift.unwrap_or(0.0),
        }
    }

    /// Samples a ray takes over all rounds (a round of 0 takes 1).
    pub fn round_samples(&self) -> usize {
        self.samples.iter().map(|&k| k.max(1)).sum()
    }

    /// The dilation of the histogram resampled in round `round` (0-based;
    /// round 0 starts from one interval and is not dilated).
    pub fn dilation(&self, round: usize) -> f32 {
        let before: f32 = self.samples.iter().take(round).map(|&n| n as f32).product();
        self.dilation_bias + self.dilation_multiplier / before.max(1.0)
    }
}

/// The proposal MLP: ReLU layers and a density output, `softplus(raw - 1)`
/// on the IPE (as the NeRF MLP's), `exp(raw)` on a hash encoding (as the
/// fast field's).
#[derive(Module, Debug)]
pub struct ProposalMlp {
    /// Hidden layers.
    pub layers: Vec<Linear>,
    /// Raw density output.
    pub density: Linear,
    /// Lowest IPE degree.
    pub min_deg: usize,
    /// One past the highest IPE degree.
    pub max_deg: usize,
    /// The hash encoding it takes in place of the IPE.
    pub hash: Option<HashGrid>,
    /// Added to the hash form's raw density before its exponential.
    pub density_shift: f32,
}

impl ProposalMlp {
    /// Density of the Gaussians of samples, from their IPE or their means'
    /// hash encoding.
    ///
    /// # Shapes
    /// - `mean`, `cov_diag`: `[n, 3]`; output: `[n, 1]`.
    pub fn density_at(&self, mean: Tensor<2>, cov_diag: Tensor<2>) -> Tensor<2> {
        match &self.hash {
            Some(grid) => self.hash_density(grid, mean),
            None => self.density(integrated_pos_enc(
                mean,
                cov_diag,
                self.min_deg,
                self.max_deg,
            )),
        }
    }

    /// The hash form's density of Gaussians of means `mean` (the hash
    /// form reads no covariance): what [`ProposalMlp::density_at`] gives
    /// them when `grid` is the MLP's own.
    ///
    /// # Shapes
    /// - `mean`: `[n, 3]`; output: `[n, 1]`.
    pub fn hash_density(&self, grid: &HashGrid, mean: Tensor<2>) -> Tensor<2> {
        let mut h = grid.forward(mean.detach());
        for layer in &self.layers {
            h = relu(layer.forward(h));
        }
        exp_density(self.density.forward(h).add_scalar(self.density_shift))
    }

    /// Density from the integrated positional encoding.
    ///
    /// # Shapes
    /// - `ipe`: `[n, 6 (max_deg - min_deg)]`; output: `[n, 1]`.
    pub fn density(&self, ipe: Tensor<2>) -> Tensor<2> {
        let mut h = ipe;
        for layer in &self.layers {
            h = relu(layer.forward(h));
        }
        softplus(self.density.forward(h).sub_scalar(1.0), 1.0)
    }
}
