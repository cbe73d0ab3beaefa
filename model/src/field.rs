//! The Mip-NeRF MLP (trunk, density, colour) and the open-set feature head.
//!
//! Two layers that act on a concatenation (the skip connection and the view
//! branch) are stored as two linear maps whose outputs are added. That is the
//! same function as one linear layer on the concatenated input, without
//! materialising the concatenation per sample; the view part is evaluated
//! once per ray and broadcast over the samples.

use burn::config::Config;
use burn::module::Module;
use burn::nn::{Initializer, Linear, LinearConfig};
use burn::tensor::Device;
use burn::tensor::Tensor;
use burn::tensor::activation::{relu, sigmoid, softplus};

use crate::mip::{ipe_dim, pe_dim};

/// Configuration of [`MipMlp`].
#[derive(Config, Debug)]
pub struct MipMlpConfig {
    /// Number of trunk layers.
    #[config(default = 8)]
    pub depth: usize,
    /// Trunk width.
    #[config(default = 256)]
    pub width: usize,
    /// The encoded input is re-injected after this many trunk layers.
    #[config(default = 4)]
    pub skip_layer: usize,
    /// Lowest IPE degree.
    #[config(default = 0)]
    pub min_deg: usize,
    /// One past the highest IPE degree.
    #[config(default = 16)]
    pub max_deg: usize,
    /// View-direction encoding degrees `0..viewdir_deg`, plus identity.
    #[config(default = 4)]
    pub viewdir_deg: usize,
}

/// A linear layer whose weights are drawn as if it had `fan_in` inputs (the
/// default uniform `+-1/sqrt(fan_in)`), for the halves of a split layer.
pub(crate) fn split_linear(
    d_in: usize,
    d_out: usize,
    fan_in: usize,
    bias: bool,
    device: &Device,
) -> Linear {
    let bound = 1.0 / (fan_in.max(1) as f64).sqrt();
    LinearConfig::new(d_in, d_out)
        .with_bias(bias)
        .with_initializer(Initializer::Uniform {
            min: -bound,
            max: bound,
        })
        .init(device)
}

impl MipMlpConfig {
    /// Width of the IPE input.
    pub fn input_dim(&self) -> usize {
        ipe_dim(self.min_deg, self.max_deg)
    }

    /// Width of the view-direction encoding.
    pub fn view_dim(&self) -> usize {
        pe_dim(0, self.viewdir_deg, true)
    }

    /// Builds the MLP. A `depth` of 0 is treated as 1, `width` 0 as 1.
    pub fn init(&self, device: &Device) -> MipMlp {
        self.init_with_appearance(0, device)
    }

    /// [`Self::init`] with the view branch also taking a per-photograph
    /// appearance code of `appearance_dim` numbers after the view encoding
    /// (see [`crate::appearance`]; 0: none).
    pub fn init_with_appearance(&self, appearance_dim: usize, device: &Device) -> MipMlp {
        self.init_with_inputs(appearance_dim, 0, device)
    }

    /// [`Self::init_with_appearance`] with `extra_input` more numbers per
    /// sample after the IPE (a hash encoding's features; 0: none).
    pub fn init_with_inputs(
        &self,
        appearance_dim: usize,
        extra_input: usize,
        device: &Device,
    ) -> MipMlp {
        let depth = self.depth.max(1);
        let width = self.width.max(1);
        let input = self.input_dim() + extra_input;
        let mut trunk = Vec::with_capacity(depth);
        let mut skip = None;
        for i in 0..depth {
            if i > 0 && i == self.skip_layer {
                let fan = width + input;
                trunk.push(split_linear(width, width, fan, true, device));
                skip = Some(split_linear(input, width, fan, false, device));
            } else {
                let d_in = if i == 0 { input } else { width };
                trunk.push(LinearConfig::new(d_in, width).init(device));
            }
        }
        let half = (width / 2).max(1);
        let view_in = self.view_dim() + appearance_dim;
        let view_fan = width + view_in;
        MipMlp {
            trunk,
            skip,
            skip_layer: self.skip_layer,
            density: LinearConfig::new(width, 1).init(device),
            bottleneck: LinearConfig::new(width, width).init(device),
            view_bottleneck: split_linear(width, half, view_fan, true, device),
            view_dir: split_linear(view_in, half, view_fan, false, device),
            rgb: LinearConfig::new(half, 3).init(device),
            min_deg: self.min_deg,
            max_deg: self.max_deg,
            viewdir_deg: self.viewdir_deg,
            appearance_dim,
        }
    }
}

/// Mip-NeRF MLP: 8 x 256 ReLU trunk with a skip connection, density
/// `softplus(raw - 1)`, colour `sigmoid * 1.002 - 0.001` through a bottleneck
/// and a view-dependent layer of half width.
#[derive(Module, Debug)]
pub struct MipMlp {
    /// Trunk layers; at `skip_layer` this is the part acting on the hidden state.
    pub trunk: Vec<Linear>,
    /// Part of the skip layer acting on the re-injected encoding (no bias).
    pub skip: Option<Linear>,
    /// Index of the skip layer.
    pub skip_layer: usize,
    /// Raw density output.
    pub density: Linear,
    /// Bottleneck before the view branch.
    pub bottleneck: Linear,
    /// View-branch part acting on the bottleneck.
    pub view_bottleneck: Linear,
    /// View-branch part acting on the view encoding (no bias).
    pub view_dir: Linear,
    /// Colour output.
    pub rgb: Linear,
    /// Lowest IPE degree.
    pub min_deg: usize,
    /// One past the highest IPE degree.
    pub max_deg: usize,
    /// View encoding degrees.
    pub viewdir_deg: usize,
    /// Length of the appearance code the view branch takes after the view
    /// encoding (0: none).
    pub appearance_dim: usize,
}

/// Per-sample outputs of the field.
#[derive(Debug, Clone)]
pub struct FieldOutputs {
    /// Trunk feature (input of the bottleneck and of the feature head), `[n, width]`.
    pub trunk: Tensor<2>,
    /// Density, `[n, 1]`, non-negative.
    pub density: Tensor<2>,
    /// Colour in `[-0.001, 1.001]`, `[n, 3]`.
    pub rgb: Tensor<2>,
}

impl MipMlp {
    /// Trunk feature and density from the integrated positional encoding.
    ///
    /// # Shapes
    /// - `ipe`: `[n, 6 (max_deg - min_deg)]`.
    /// - output: (`[n, width]`, `[n, 1]`).
    pub fn trunk_density(&self, ipe: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let mut h = ipe.clone();
        for (i, layer) in self.trunk.iter().enumerate() {
            h = match (&self.skip, i == self.skip_layer) {
                (Some(skip), true) => layer.forward(h).add(skip.forward(ipe.clone())),
                _ => layer.forward(h),
            };
            h = relu(h);
        }
        let density = softplus(self.density.forward(h.clone()).sub_scalar(1.0), 1.0);
        (h, density)
    }

    /// View-dependent colour.
    ///
    /// # Shapes
    /// - `trunk`: `[rays * samples, width]`, ray-major.
    /// - `view_enc`: `[rays, view_dim + appearance_dim]`.
    /// - output: `[rays * samples, 3]`.
    pub fn color(&self, trunk: Tensor<2>, view_enc: Tensor<2>, samples: usize) -> Tensor<2> {
        let [n, _] = trunk.dims();
        let rays = n / samples.max(1);
        let b = self.view_bottleneck.forward(self.bottleneck.forward(trunk));
        let [_, half] = b.dims();
        let v = self.view_dir.forward(view_enc).unsqueeze_dim::<3>(1); // [rays, 1, half]
        let h = relu(b.reshape([rays, samples, half]).add(v)).reshape([n, half]);
        sigmoid(self.rgb.forward(h))
            .mul_scalar(1.0 + 2.0 * 0.001)
            .sub_scalar(0.001)
    }

    /// Full field evaluation on `rays * samples` encoded samples.
    ///
    /// # Shapes
    /// - `ipe`: `[rays * samples, ipe_dim]`, ray-major; `view_enc`: `[rays, view_dim]`.
    pub fn forward(&self, ipe: Tensor<2>, view_enc: Tensor<2>, samples: usize) -> FieldOutputs {
        let (trunk, density) = self.trunk_density(ipe);
        let rgb = self.color(trunk.clone(), view_enc, samples);
        FieldOutputs {
            trunk,
            density,
            rgb,
        }
    }
}

/// Configuration of [`FeatureHead`].
#[derive(Config, Debug)]
pub struct FeatureHeadConfig {
    /// Output dimension: `D` (full feature) or `k` PCA coefficients.
    pub out_dim: usize,
    /// Number of hidden ReLU layers before the linear output layer.
    #[config(default = 2)]
    pub layers: usize,
    /// Hidden width.
    #[config(default = 256)]
    pub width: usize,
}

impl FeatureHeadConfig {
    /// Builds the head for trunk features of width `input_dim`.
    pub fn init(&self, input_dim: usize, device: &Device) -> FeatureHead {
        let width = self.width.max(1);
        let hidden = (0..self.layers)
            .map(|i| {
                let d_in = if i == 0 { input_dim } else { width };
                LinearConfig::new(d_in, width).init(device)
            })
            .collect();
        let last_in = if self.layers == 0 { input_dim } else { width };
        FeatureHead {
            hidden,
            output: LinearConfig::new(last_in, self.out_dim.max(1)).init(device),
        }
    }
}

/// Open-set feature head. Its input is the trunk feature *detached*, so the
/// feature loss never moves density or colour. The hidden activation and the
/// linear output layer are exposed separately: because the output layer is
/// linear, the weighted mean of `A h + b` is `A (mean h) + b`, so the
/// renderer averages hidden activations and applies the output layer once
/// per ray.
#[derive(Module, Debug)]
pub struct FeatureHead {
    /// Hidden ReLU layers.
    pub hidden: Vec<Linear>,
    /// Linear output layer.
    pub output: Linear,
}

impl FeatureHead {
    /// Hidden activation of `input` as it is: the caller has detached what
    /// the feature loss must not train ([`crate::nerf::Radiance::head_input`]).
    ///
    /// # Shapes
    /// - `input`: `[n, head_width]`; output: `[n, hidden_width]`.
    pub fn hidden_of(&self, input: Tensor<2>) -> Tensor<2> {
        let mut h = input;
        for layer in &self.hidden {
            h = relu(layer.forward(h));
        }
        h
    }

    /// Per-sample feature (hidden layers and output layer) of `input` as
    /// it is ([`FeatureHead::hidden_of`]).
    ///
    /// # Shapes
    /// - `input`: `[n, head_width]`; output: `[n, out_dim]`.
    pub fn forward(&self, input: Tensor<2>) -> Tensor<2> {
        self.output.forward(self.hidden_of(input))
    }
}
