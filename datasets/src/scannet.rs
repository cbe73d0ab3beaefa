//! ScanNet scene exports.

use std::path::Path;

use crate::error::DatasetError;
pub use crate::options::ScannetOptions;
use crate::scene::Scene;

/// Loads a ScanNet scene export.
pub fn load_scannet(dir: &Path, _options: &ScannetOptions) -> Result<Scene, DatasetError> {
    Err(DatasetError::invalid(
        dir,
        "the ScanNet loader is not built yet",
    ))
}
