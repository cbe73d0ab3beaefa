//! CLIP's vision tower from files and pixel-aligned features from it:
//! weight naming ([`layout`]), configuration and image normalisation
//! ([`config`]), the loaded model and its sliding-window dense maps
//! ([`model`]), the model directory with both towers ([`vlm`]), writing
//! both towers as a Hugging Face `CLIPModel` directory ([`export`]) and the
//! scene pipeline's feature extractor on top of it ([`extractor`]).

pub mod config;
pub mod export;
pub mod extractor;
pub mod layout;
pub mod model;
pub mod vlm;

pub use extractor::ClipExtractor;
pub use model::{DEFAULT_SHORT_SIDE, DenseMap, DenseOptions, VisionModel};
pub use vlm::Vlm;
