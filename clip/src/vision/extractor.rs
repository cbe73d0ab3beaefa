//! The scene pipeline's [`FeatureExtractor`] backed by a CLIP vision tower:
//! in-process, so training frames and rendered novel views are extracted
//! without a subprocess.

use std::sync::Arc;

use datasets::DatasetError;
use datasets::extractor::FeatureExtractor;
use datasets::features::FeatureMap;
use datasets::scene::RgbImage;
use half::f16;

use super::model::{DenseOptions, VisionModel};

/// Dense CLIP features of colour images, one map per image at the patch
/// grid of its resized copy.
#[derive(Debug, Clone)]
pub struct ClipExtractor {
    model: Arc<VisionModel>,
    options: DenseOptions,
}

impl ClipExtractor {
    /// An extractor running `model` as `options` say.
    pub fn new(model: Arc<VisionModel>, options: DenseOptions) -> Self {
        Self { model, options }
    }

    /// The model.
    pub fn model(&self) -> &VisionModel {
        &self.model
    }

    /// The options.
    pub fn options(&self) -> &DenseOptions {
        &self.options
    }
}

impl FeatureExtractor for ClipExtractor {
    fn dim(&self) -> usize {
        self.model.dim()
    }

    fn extract(&self, image: &RgbImage) -> Result<FeatureMap, DatasetError> {
        let map = self
            .model
            .dense_map(
                &image.to_f32(),
                (image.height as usize, image.width as usize),
                &self.options,
            )
            .map_err(|e| DatasetError::invalid(&self.model.dir, e.to_string()))?;
        Ok(FeatureMap {
            width: map.cols as u32,
            height: map.rows as u32,
            dim: map.dim,
            data: map.data.into_iter().map(f16::from_f32).collect(),
        })
    }
}
