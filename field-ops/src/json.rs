//! JSON files of run directories, read and written with errors that name
//! the file: every JSON file of a run goes through these two functions.

use std::path::Path;

use crate::error::OpsError;
use crate::files::write_atomic;

/// Reads and parses a JSON file into `T`, naming the file in every error.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, OpsError> {
    let text = read_text(path)?;
    serde_json::from_str(&text).map_err(|e| OpsError::json(path, e))
}

/// Writes `value` as pretty JSON to `path`, atomically (see
/// [`write_atomic`]).
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), OpsError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| OpsError::json(path, e))?;
    write_atomic(path, text.as_bytes())
}

fn read_text(path: &Path) -> Result<String, OpsError> {
    std::fs::read_to_string(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            OpsError::Missing {
                path: path.to_path_buf(),
                what: "required file of a run directory".into(),
            }
        } else {
            OpsError::io(path, e)
        }
    })
}
