//! A vision-language model directory: CLIP's two towers from one checkpoint,
//! checked to share their embedding space.

use std::path::Path;

use burn::tensor::Device;

use super::model::VisionModel;
use crate::error::ClipError;
use crate::model_dir::TextModel;

/// Both towers of one CLIP model.
#[derive(Debug)]
pub struct Vlm {
    /// The image side.
    pub vision: VisionModel,
    /// The text side.
    pub text: TextModel,
}

impl Vlm {
    /// Loads both towers of `dir`, refusing a directory without a vision
    /// tower, without a text tower, or whose towers' projections differ in
    /// dimension.
    pub fn load(dir: &Path, device: &Device) -> Result<Self, ClipError> {
        let vision = VisionModel::load(dir, device)?;
        let text = TextModel::load(dir, device)?;
        if vision.dim() != text.dim() {
            return Err(ClipError::invalid(
                &vision.weights,
                format!(
                    "the vision tower projects to {} dimensions but the text tower to {}: \
                     they are not one CLIP model",
                    vision.dim(),
                    text.dim()
                ),
            ));
        }
        Ok(Self { vision, text })
    }

    /// The joint space's dimension.
    pub fn dim(&self) -> usize {
        self.text.dim()
    }

    /// Everything assumed where the files were silent.
    pub fn notes(&self) -> Vec<String> {
        self.vision
            .notes
            .iter()
            .chain(&self.text.notes)
            .cloned()
            .collect()
    }
}
