//! Files of a run directory written so that a killed process never leaves a
//! half-written one behind.

use std::io::Write;
use std::path::Path;

use crate::error::OpsError;

/// Writes `bytes` to `path` through a temporary file (`.NAME.tmp-PID`
/// beside it) and a rename: `path` holds either its old or its new content.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OpsError> {
    let dir = path.parent().unwrap_or_else(|| Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| OpsError::io(dir, e))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "file".into());
    let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(OpsError::io(&tmp, e));
    }
    std::fs::rename(&tmp, path).map_err(|e| OpsError::io(path, e))
}
