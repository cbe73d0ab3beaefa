//! [`FeatureInput`]: the feature maps a loader attaches to the scene it
//! loaded, shared by every format that reads them (Replica, COLMAP and the
//! phone captures).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::null_as_default;
use crate::error::DatasetError;
use crate::features::{PcaBasis, PcaSetting, load_frame_features};
use crate::scene::Scene;

/// Where a scene's feature maps are and how they are compressed.
/// Serialised flattened into its format's options (the keys `features`,
/// `pca`, `seed`), as they were before the formats shared it.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct FeatureInput {
    /// Feature maps: a stacked `.npy` or a directory of per-frame `.npy`
    /// named after the frames (indexed over the frames kept); `None`: the
    /// scene has none.
    pub features: Option<PathBuf>,
    /// Compression of the feature maps (`null`, as older scene files
    /// write "none", reads as off).
    #[serde(deserialize_with = "null_as_default")]
    pub pca: PcaSetting,
    /// A basis to compress with instead of fitting one (a run's stored
    /// basis when its scene is rebuilt); not part of the saved options.
    #[serde(skip)]
    pub basis: Option<PcaBasis>,
    /// Seed of the PCA pixel sample.
    pub seed: u64,
}

impl FeatureInput {
    /// Attaches the feature maps to `scene`, loaded without them: the maps
    /// of its frames (by name, at their images' size), compressed with
    /// [`Self::basis`] when given, else as [`Self::pca`] asks. Without
    /// [`Self::features`] the scene is left as it is.
    pub fn attach(&self, scene: &mut Scene) -> Result<(), DatasetError> {
        if let Some(path) = &self.features {
            scene.features = Some(load_frame_features(
                path,
                &scene.frames,
                self.pca,
                self.basis.as_ref(),
                self.seed,
            )?);
        }
        Ok(())
    }
}
