//! Reading and writing the run directory's JSON files (`config.json`,
//! `scene.json`, `split.json`, `summary.json`, ...): every such file of this
//! crate goes through these two functions.

use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::error::TrainError;

/// Writes `value` as pretty JSON to `path` (atomically).
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), TrainError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| TrainError::json(path, e))?;
    crate::checkpoint::write_atomic(path, text.as_bytes())
}

/// Reads a JSON file into `T`, naming the file in errors.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T, TrainError> {
    let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| TrainError::json(path, e))
}
