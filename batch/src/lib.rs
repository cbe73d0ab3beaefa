//! Many scenes, each trained and evaluated as its own run directory: one
//! after the other on this machine, or as Slurm job arrays that survive
//! preemption (a signalled task writes a checkpoint and is requeued; the
//! requeued task resumes from it, bit-identically). `eval gather` then
//! writes the benchmark table of the batch directory.
//!
//! A batch directory holds `batch.json` (the runs, fixed when the batch is
//! written: [`field_ops::batch_dir`]), one run directory per run (with its
//! `batch_task.json` and `batch.log`) and, for Slurm, the array scripts and
//! Slurm's own output in `slurm/`.
#![warn(missing_docs)]

pub mod error;
pub mod runner;
pub mod scenes;
pub mod slurm;

use std::path::{Path, PathBuf};

use field_ops::batch_dir::{BatchManifest, MANIFEST_FILE};

pub use error::BatchError;
pub use runner::{TaskOutcome, run_task};
pub use scenes::Batch;

/// Writes `dir/batch.json` for `batch`; a directory that already holds
/// another batch's list is refused (its array tasks would run other
/// scenes). Returns the directory made absolute.
pub fn prepare_dir(dir: &Path, batch: &Batch) -> Result<PathBuf, BatchError> {
    std::fs::create_dir_all(dir).map_err(|e| BatchError::dir(dir, e))?;
    let dir = std::path::absolute(dir).map_err(|e| BatchError::dir(dir, e))?;
    let path = dir.join(MANIFEST_FILE);
    if path.exists() {
        let old = BatchManifest::read(&dir)?;
        if old.tasks != batch.manifest.tasks {
            return Err(BatchError::dir(
                &path,
                format!(
                    "this directory holds a batch written from {} with other runs or flags; \
                     give another --out (or remove {} to replace that batch)",
                    old.scenes_file.display(),
                    path.display()
                ),
            ));
        }
    }
    batch.manifest.write(&dir)?;
    Ok(dir)
}

/// The task `index` of the batch in `dir`.
pub fn task(dir: &Path, index: usize) -> Result<field_ops::batch_dir::BatchTask, BatchError> {
    let manifest = BatchManifest::read(dir)?;
    let n = manifest.tasks.len();
    manifest.tasks.into_iter().nth(index).ok_or_else(|| {
        BatchError::dir(
            &dir.join(MANIFEST_FILE),
            format!(
                "no task {index}: the batch has {n} (0 to {})",
                n.saturating_sub(1)
            ),
        )
    })
}
