//! CLIP's two transformers as Burn modules (no file I/O). The text tower
//! ([`ClipTextEncoder`]): token and position embeddings, pre-LN residual attention
//! blocks with a causal mask, a final layer norm, pooling at the
//! end-of-text token and a linear projection into the joint image-text
//! space. The vision tower ([`ClipVisionEncoder`]): patch embedding, class token,
//! position embeddings stretched to any patch grid, the same blocks
//! without the mask, and either CLIP's pooled image embedding or
//! pixel-aligned features from a training-free last block (NACLIP,
//! ClearCLIP, MaskCLIP: [`DenseVariant`]) over sliding windows ([`sliding`]). The
//! same networks as OpenAI's CLIP, Hugging Face's `CLIPModel` and OpenCLIP;
//! the rest of this crate loads their weights from files.

mod attention;
mod block;
mod dense;
pub mod resample;
pub mod sliding;
mod text;
mod text_config;
mod vision;
mod vision_config;

pub use attention::CausalSelfAttention;
pub use block::{BlockSizes, ClipMlp, ResidualAttentionBlock};
pub use dense::{dense_last_block, gaussian_window_bias};
pub use model::dense_variant::DenseVariant;
pub use text::{ClipTextEncoder, l2_normalize};
pub use text_config::{ClipActivation, ClipTextConfig, EotPooling};
pub use vision::ClipVisionEncoder;
pub use vision_config::{ClipVisionConfig, NACLIP_STD};
