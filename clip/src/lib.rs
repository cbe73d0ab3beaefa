//! CLIP: its text and vision transformers as Burn modules ([`tower`]) and
//! the models from files: pixel-aligned image features from the vision
//! tower ([`vision`]) and, for free-text queries, the byte-level BPE
//! tokenizer ([`tokenizer`], with CLIP's text clean-up in [`clean`]),
//! safetensors weights in Hugging Face or OpenCLIP naming ([`tensors`],
//! [`layout`]), their configuration ([`config`]), a model directory loader
//! that embeds text ([`model_dir`]) and a per-run cache of embeddings
//! ([`cache`]).
#![warn(missing_docs)]

pub mod cache;
pub mod clean;
pub mod config;
pub mod error;
pub mod export;
pub mod layout;
pub mod model_dir;
pub mod tensors;
pub mod tokenizer;
pub mod tower;
pub mod vision;

pub use cache::{Embedded, embed_texts};
pub use error::ClipError;
pub use model_dir::{TextModel, load_tokenizer};
pub use tokenizer::ClipTokenizer;
pub use tower::{
    ClipTextConfig, ClipTextEncoder, ClipVisionConfig, ClipVisionEncoder, DenseVariant,
};
pub use vision::{ClipExtractor, DenseOptions, VisionModel, Vlm};

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
