//! CLIP's two transformers. The text tower: token and position
//! embeddings, pre-LN residual attention blocks with a causal mask, a final
//! layer norm, pooling at the end-of-text token and a linear projection
//! into the joint image-text space. The vision tower: patch embedding,
//! class token, position embeddings stretched to any patch grid, the same
//! blocks without the mask, and either CLIP's pooled image embedding or
//! pixel-aligned features from a training-free last block (NACLIP,
//! ClearCLIP, MaskCLIP) over sliding windows. The same networks as OpenAI's
//! CLIP, Hugging Face's `CLIPModel` and OpenCLIP; loading their weights
//! (file I/O) is the `clip` crate's job.

mod attention;
mod block;
mod config;
mod dense;
mod encoder;
pub mod resample;
pub mod sliding;
mod vision;
mod vision_config;

pub use attention::CausalSelfAttention;
pub use block::{BlockSizes, ClipMlp, ResidualAttentionBlock};
pub use config::{ClipActivation, ClipTextConfig, EotPooling};
pub use dense::{dense_last_block, gaussian_window_bias};
pub use encoder::{ClipTextEncoder, l2_normalize};
pub use vision::ClipVisionEncoder;
pub use vision_config::{ClipVisionConfig, DenseVariant, NACLIP_STD};
