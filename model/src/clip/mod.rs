//! The CLIP text transformer: token and position embeddings, pre-LN
//! residual attention blocks with a causal mask, a final layer norm, pooling
//! at the end-of-text token and a linear projection into the joint
//! image-text space. The same network as OpenAI's CLIP, Hugging Face's
//! `CLIPTextModelWithProjection` and OpenCLIP's text tower; loading their
//! weights (file I/O) is the `clip` crate's job.

mod attention;
mod block;
mod config;
mod encoder;

pub use attention::CausalSelfAttention;
pub use block::{ClipMlp, ResidualAttentionBlock};
pub use config::{ClipActivation, ClipTextConfig, EotPooling};
pub use encoder::ClipTextEncoder;
