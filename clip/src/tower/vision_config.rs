//! Sizes and options of the CLIP vision transformer, and the width of
//! NACLIP's window.

use burn::config::Config;

use super::text_config::{ClipActivation, transformer_problem};

/// NACLIP's Gaussian window width, in patches.
pub const NACLIP_STD: f64 = 5.0;

/// Configuration of [`ClipVisionEncoder`](super::ClipVisionEncoder).
#[derive(Config, Debug)]
pub struct ClipVisionConfig {
    /// Side of the square input the position embeddings were trained for.
    #[config(default = 224)]
    pub image_size: usize,
    /// Side of a patch, in pixels.
    #[config(default = 16)]
    pub patch_size: usize,
    /// Transformer width.
    #[config(default = 768)]
    pub width: usize,
    /// Number of residual attention blocks.
    #[config(default = 12)]
    pub layers: usize,
    /// Number of attention heads; must divide `width`.
    #[config(default = 12)]
    pub heads: usize,
    /// Hidden width of the MLPs.
    #[config(default = 3072)]
    pub mlp_width: usize,
    /// Output dimension of the projection (the joint embedding space).
    #[config(default = 512)]
    pub embed_dim: usize,
    /// MLP activation.
    #[config(default = "ClipActivation::QuickGelu")]
    pub activation: ClipActivation,
    /// Epsilon of every layer norm.
    #[config(default = 1e-5)]
    pub layer_norm_eps: f64,
}

impl ClipVisionConfig {
    /// CLIP ViT-B/32: 224 px, 32-px patches, width 768, 12 layers, 512-d.
    pub fn vit_b_32() -> Self {
        Self::new().with_patch_size(32)
    }

    /// CLIP ViT-B/16: 224 px, 16-px patches, width 768, 12 layers, 512-d.
    pub fn vit_b_16() -> Self {
        Self::new()
    }

    /// CLIP ViT-L/14: 224 px, 14-px patches, width 1024, 24 layers, 16
    /// heads, 768-d.
    pub fn vit_l_14() -> Self {
        Self::new()
            .with_patch_size(14)
            .with_width(1024)
            .with_layers(24)
            .with_heads(16)
            .with_mlp_width(4096)
            .with_embed_dim(768)
    }

    /// CLIP ViT-L/14 at 336 px.
    pub fn vit_l_14_336() -> Self {
        Self::vit_l_14().with_image_size(336)
    }

    /// Patches along each side of the native input.
    pub fn grid(&self) -> usize {
        self.image_size / self.patch_size.max(1)
    }

    /// Why this configuration cannot be built, if it cannot.
    pub fn problem(&self) -> Option<String> {
        let sizes = [
            ("image_size", self.image_size),
            ("patch_size", self.patch_size),
            ("width", self.width),
            ("layers", self.layers),
            ("heads", self.heads),
            ("mlp_width", self.mlp_width),
            ("embed_dim", self.embed_dim),
        ];
        if let Some(p) = transformer_problem(&sizes, self.width, self.heads, self.layer_norm_eps) {
            return Some(p);
        }
        if !self.image_size.is_multiple_of(self.patch_size) {
            return Some(format!(
                "the image size {} is not a whole number of {}-px patches",
                self.image_size, self.patch_size
            ));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tower::DenseVariant;

    #[test]
    fn presets_names_and_problems() {
        let b = ClipVisionConfig::vit_b_16();
        assert_eq!((b.grid(), b.embed_dim), (14, 512));
        assert_eq!(ClipVisionConfig::vit_b_32().grid(), 7);
        assert_eq!(ClipVisionConfig::vit_l_14_336().grid(), 24);
        assert!(ClipVisionConfig::vit_l_14().problem().is_none());
        assert!(
            b.clone()
                .with_image_size(225)
                .problem()
                .unwrap()
                .contains("225")
        );
        assert!(
            b.clone()
                .with_heads(7)
                .problem()
                .unwrap()
                .contains("7 heads")
        );
        for v in DenseVariant::ALL {
            assert_eq!(v.name().parse::<DenseVariant>(), Ok(v));
            let json = serde_json::to_string(&v).unwrap();
            assert_eq!(json, format!("\"{v}\""));
        }
        let e = "sclip".parse::<DenseVariant>().unwrap_err();
        assert!(e.contains("sclip") && e.contains("naclip"), "{e}");
    }
}
