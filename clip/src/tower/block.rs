//! The pre-LN residual attention block of CLIP's transformers (text and
//! vision).

use burn::module::Module;
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::activation::gelu;
use burn::tensor::{Device, Tensor};

use super::attention::CausalSelfAttention;
use super::text_config::{ClipActivation, ClipTextConfig};

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
            // `x * sigmoid(1.702 x)` written as one exp and one division:
            // the same values, fewer passes over the widest activation.
            ClipActivation::QuickGelu => h.clone() / h.mul_scalar(-1.702).exp().add_scalar(1.0),
            ClipActivation::Gelu => gelu(h),
        };
        self.fc2.forward(h)
    }
}

/// The sizes and options of one block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockSizes {
    /// Channels.
    pub width: usize,
    /// Attention heads (dividing `width`).
    pub heads: usize,
    /// Hidden width of the MLP.
    pub mlp_width: usize,
    /// MLP activation.
    pub activation: ClipActivation,
    /// Epsilon of both layer norms.
    pub layer_norm_eps: f64,
    /// Causal attention (text) or not (vision).
    pub causal: bool,
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
    /// A causal block of `config`'s sizes, randomly initialised.
    pub fn new(config: &ClipTextConfig, device: &Device) -> Self {
        Self::with_sizes(
            &BlockSizes {
                width: config.width,
                heads: config.heads,
                mlp_width: config.mlp_width,
                activation: config.activation,
                layer_norm_eps: config.layer_norm_eps,
                causal: true,
            },
            device,
        )
    }

    /// A block of these sizes, randomly initialised.
    pub fn with_sizes(sizes: &BlockSizes, device: &Device) -> Self {
        let ln = || {
            LayerNormConfig::new(sizes.width)
                .with_epsilon(sizes.layer_norm_eps)
                .init(device)
        };
        Self {
            ln1: ln(),
            attn: CausalSelfAttention::with_mask(sizes.width, sizes.heads, sizes.causal, device),
            ln2: ln(),
            mlp: ClipMlp {
                fc1: LinearConfig::new(sizes.width, sizes.mlp_width).init(device),
                fc2: LinearConfig::new(sizes.mlp_width, sizes.width).init(device),
                activation: sizes.activation,
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
