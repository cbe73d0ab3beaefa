//! The pre-LN residual attention block of CLIP's text transformer.

use burn::module::Module;
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::activation::{gelu, sigmoid};
use burn::tensor::{Device, Tensor};

use super::attention::CausalSelfAttention;
use super::config::{ClipActivation, ClipTextConfig};

/// The two-layer MLP of a block: `fc2(act(fc1(x)))`.
#[derive(Module, Debug)]
pub struct ClipMlp {
    /// `width -> mlp_width` (Hugging Face `fc1`, OpenCLIP `c_fc`).
    pub fc1: Linear,
    /// `mlp_width -> width` (Hugging Face `fc2`, OpenCLIP `c_proj`).
    pub fc2: Linear,
    /// The activation between them.
    #[module(skip)]
    pub activation: ClipActivation,
}

impl ClipMlp {
    /// # Shapes
    /// - `x`: `[batch, seq, width]`; output: `[batch, seq, width]`.
    pub fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        let h = self.fc1.forward(x);
        let h = match self.activation {
            ClipActivation::QuickGelu => h.clone() * sigmoid(h.mul_scalar(1.702)),
            ClipActivation::Gelu => gelu(h),
        };
        self.fc2.forward(h)
    }
}

/// `x + attn(ln1(x))`, then `x + mlp(ln2(x))`.
#[derive(Module, Debug)]
pub struct ResidualAttentionBlock {
    /// Layer norm before attention (Hugging Face `layer_norm1`, OpenCLIP `ln_1`).
    pub ln1: LayerNorm,
    /// Causal self-attention.
    pub attn: CausalSelfAttention,
    /// Layer norm before the MLP (Hugging Face `layer_norm2`, OpenCLIP `ln_2`).
    pub ln2: LayerNorm,
    /// The MLP.
    pub mlp: ClipMlp,
}

impl ResidualAttentionBlock {
    /// A block of `config`'s sizes, randomly initialised.
    pub fn new(config: &ClipTextConfig, device: &Device) -> Self {
        let ln = || {
            LayerNormConfig::new(config.width)
                .with_epsilon(config.layer_norm_eps)
                .init(device)
        };
        Self {
            ln1: ln(),
            attn: CausalSelfAttention::new(config.width, config.heads, device),
            ln2: ln(),
            mlp: ClipMlp {
                fc1: LinearConfig::new(config.width, config.mlp_width).init(device),
                fc2: LinearConfig::new(config.mlp_width, config.width).init(device),
                activation: config.activation,
            },
        }
    }

    /// # Shapes
    /// - `x`: `[batch, seq, width]`; output: `[batch, seq, width]`.
    pub fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        let x = x.clone() + self.attn.forward(self.ln1.forward(x));
        x.clone() + self.mlp.forward(self.ln2.forward(x))
    }
}
