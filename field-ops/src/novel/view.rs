//! A novel view as rendered and read, before compression.

use datasets::{DepthImage, FeatureMap, RgbImage};

/// A novel view's colour, depth (0 = no target) and full-dimension
/// features, before compression into the scene's feature space.
#[derive(Debug, Clone)]
pub struct ExtractedView {
    /// Colour image.
    pub rgb: RgbImage,
    /// Z-depth, metres.
    pub depth: DepthImage,
    /// The feature map read from the colour.
    pub features: FeatureMap,
}
