//! Everything that turns files on disk (or a seed) into scenes and ray
//! batches: Nice-SLAM Replica, Blender/nerfstudio and LLFF loaders, lazy
//! feature maps with PCA compression, text embeddings, point clouds, the
//! synthetic benchmark scene with its simulated 2D feature extractor, and the
//! ray sampler.
#![warn(missing_docs)]

pub mod blender;
pub mod error;
pub mod extractor;
pub mod features;
pub mod llff;
pub mod npy;
pub mod points;
pub mod replica;
pub mod sampler;
pub mod scene;
pub mod synthetic;
pub mod text;
pub mod writer;

pub use error::DatasetError;
pub use scene::{DepthImage, FeatureMap, Frame, RgbImage, Scene, SceneMeta, SceneSource};
