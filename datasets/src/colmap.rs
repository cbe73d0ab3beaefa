//! COLMAP reconstructions (binary or text models).

use std::path::Path;

use crate::error::DatasetError;
pub use crate::options::ColmapOptions;
use crate::scene::Scene;

/// Loads a COLMAP reconstruction directory.
pub fn load_colmap(dir: &Path, _options: &ColmapOptions) -> Result<Scene, DatasetError> {
    Err(DatasetError::invalid(
        dir,
        "the COLMAP loader is not built yet",
    ))
}
