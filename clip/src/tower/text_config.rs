//! Sizes and options of the CLIP text transformer.

use burn::config::Config;
use serde::{Deserialize, Serialize};

/// The MLP activation of the residual blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClipActivation {
    /// `x * sigmoid(1.702 x)`, OpenAI's original (`hidden_act = "quick_gelu"`).
    QuickGelu,
    /// The exact (erf) GELU (`hidden_act = "gelu"`, most OpenCLIP models).
    Gelu,
}

impl ClipActivation {
    /// The activation named by a Hugging Face `hidden_act` string
    /// (`quick_gelu`, `gelu`); `None` for one CLIP does not use.
    pub fn from_hf_name(name: &str) -> Option<Self> {
        match name {
            "quick_gelu" => Some(Self::QuickGelu),
            "gelu" => Some(Self::Gelu),
            _ => None,
        }
    }
}

/// Which token's output is the sentence embedding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EotPooling {
    /// The position of the highest token id in each sequence: the
    /// end-of-text token of the original vocabulary, whose id is the largest
    /// (OpenAI, OpenCLIP, and Hugging Face configs with `eos_token_id = 2`).
    HighestId,
    /// The first position holding this token id (Hugging Face's
    /// `eos_token_id`); a sequence without it pools its last position.
    EosId(u32),
}

/// Configuration of [`ClipTextEncoder`](super::ClipTextEncoder).
#[derive(Config, Debug)]
pub struct ClipTextConfig {
    /// Vocabulary size (49408 for the original BPE vocabulary).
    #[config(default = 49408)]
    pub vocab_size: usize,
    /// Maximum sequence length, the number of position embeddings.
    #[config(default = 77)]
    pub context_length: usize,
    /// Transformer width (hidden size).
    #[config(default = 512)]
    pub width: usize,
    /// Number of residual attention blocks.
    #[config(default = 12)]
    pub layers: usize,
    /// Number of attention heads; must divide `width`.
    #[config(default = 8)]
    pub heads: usize,
    /// Hidden width of the MLPs (usually `4 * width`).
    #[config(default = 2048)]
    pub mlp_width: usize,
    /// Output dimension of the text projection (the joint embedding space).
    #[config(default = 512)]
    pub embed_dim: usize,
    /// MLP activation.
    #[config(default = "ClipActivation::QuickGelu")]
    pub activation: ClipActivation,
    /// Epsilon of every layer norm.
    #[config(default = 1e-5)]
    pub layer_norm_eps: f64,
    /// Which token is pooled.
    #[config(default = "EotPooling::HighestId")]
    pub pooling: EotPooling,
}

impl ClipTextConfig {
    /// The text tower of CLIP ViT-B/32 (and B/16): width 512, 12 layers,
    /// 8 heads, 512-d embeddings, quick-GELU.
    pub fn vit_b_32() -> Self {
        Self::new()
    }

    /// The text tower of CLIP ViT-L/14 (the query side of OpenNeRF's
    /// OpenSeg-free setups): width 768, 12 layers, 12 heads, 768-d
    /// embeddings, quick-GELU.
    pub fn vit_l_14() -> Self {
        Self::new()
            .with_width(768)
            .with_heads(12)
            .with_mlp_width(3072)
            .with_embed_dim(768)
    }

    /// Width of one attention head, `width / heads`.
    pub fn head_dim(&self) -> usize {
        self.width / self.heads.max(1)
    }

    /// Why this configuration cannot be built, if it cannot (a zero size,
    /// or `heads` not dividing `width`).
    pub fn problem(&self) -> Option<String> {
        let sizes = [
            ("vocab_size", self.vocab_size),
            ("context_length", self.context_length),
            ("width", self.width),
            ("layers", self.layers),
            ("heads", self.heads),
            ("mlp_width", self.mlp_width),
            ("embed_dim", self.embed_dim),
        ];
        transformer_problem(&sizes, self.width, self.heads, self.layer_norm_eps)
    }
}

/// Why a transformer of these sizes cannot be built, if it cannot: a zero
/// in `sizes` (name, value), `heads` not dividing `width`, or a layer-norm
/// epsilon that is not positive. Shared by the text and vision towers.
pub(crate) fn transformer_problem(
    sizes: &[(&str, usize)],
    width: usize,
    heads: usize,
    layer_norm_eps: f64,
) -> Option<String> {
    if let Some((name, _)) = sizes.iter().find(|(_, v)| *v == 0) {
        return Some(format!("{name} must be at least 1"));
    }
    if !width.is_multiple_of(heads) {
        return Some(format!("{heads} heads do not divide the width {width}"));
    }
    if !(layer_norm_eps.is_finite() && layer_norm_eps > 0.0) {
        return Some(format!("layer_norm_eps {layer_norm_eps} must be positive"));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_and_problems() {
        let b = ClipTextConfig::vit_b_32();
        assert_eq!(
            (b.width, b.heads, b.embed_dim, b.head_dim()),
            (512, 8, 512, 64)
        );
        let l = ClipTextConfig::vit_l_14();
        assert_eq!(
            (l.width, l.heads, l.embed_dim, l.head_dim()),
            (768, 12, 768, 64)
        );
        assert!(b.problem().is_none() && l.problem().is_none());
        assert!(
            b.clone()
                .with_heads(7)
                .problem()
                .unwrap()
                .contains("7 heads")
        );
        assert!(b.with_layers(0).problem().unwrap().contains("layers"));
        assert_eq!(
            ClipActivation::from_hf_name("gelu"),
            Some(ClipActivation::Gelu)
        );
        assert_eq!(ClipActivation::from_hf_name("relu"), None);
    }

    #[test]
    fn config_round_trips_through_json() {
        let c = ClipTextConfig::vit_l_14().with_pooling(EotPooling::EosId(7));
        let json = serde_json::to_string(&c).unwrap();
        let back: ClipTextConfig = serde_json::from_str(&json).unwrap();
        assert_eq!(back.pooling, EotPooling::EosId(7));
        assert_eq!(back.width, 768);
    }
}
