//! The fuzz targets: one per parser, each with its seeds, its dictionary
//! and the public entry point it drives.
//!
//! A target writes the input to a file of a scratch directory (one per
//! target and worker) under the name the loader expects, with any
//! companion files it needs written once, and calls the loader. Errors are
//! the expected outcome for most inputs and are ignored: only a panic, an
//! allocation over the cap or a hang is a defect.

mod clip_files;
mod colmap;
mod run_files;
mod scenes;
mod selftest;

use std::path::{Path, PathBuf};

/// One fuzz target.
pub struct Target {
    /// Name on the command line and in the table.
    pub name: &'static str,
    /// What it parses, with the entry point.
    pub about: &'static str,
    /// The file name the input is written under.
    pub file: &'static str,
    /// Tokens inserted by the dictionary mutation (besides the common ones).
    pub tokens: &'static [&'static str],
    /// The seed inputs.
    pub seeds: fn(&Seeds) -> Vec<Vec<u8>>,
    /// Writes the companion files into the scratch directory (once).
    pub setup: fn(&Path, &Seeds) -> std::io::Result<()>,
    /// Parses the input file (already written).
    pub run: fn(&Path),
}

/// A target without companion files.
fn no_setup(_: &Path, _: &Seeds) -> std::io::Result<()> {
    Ok(())
}

/// Where seed files come from: the shared data sets (never copied into
/// the repository) and the repository's test fixtures.
#[derive(Debug, Clone)]
pub struct Seeds {
    /// `../shared/data` of the repository root (or `--data`).
    pub data: PathBuf,
    /// The repository root.
    pub repo: PathBuf,
}

impl Seeds {
    /// The default locations, from this crate's source directory.
    pub fn default_paths() -> Self {
        let repo = Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .unwrap_or(Path::new("."))
            .to_path_buf();
        Self {
            data: repo.join("../shared/data"),
            repo,
        }
    }

    /// A shared data file, when present.
    pub fn data_file(&self, rel: &str) -> Option<Vec<u8>> {
        std::fs::read(self.data.join(rel)).ok()
    }

    /// A test fixture of the repository, when present.
    pub fn fixture(&self, rel: &str) -> Option<Vec<u8>> {
        std::fs::read(self.repo.join(rel)).ok()
    }
}

/// Every target, in the order of the table.
pub fn all() -> Vec<Target> {
    let mut v = scenes::targets();
    v.extend(colmap::targets());
    v.extend(clip_files::targets());
    v.extend(run_files::targets());
    v
}

/// The target called `name`, including the self-test targets that fail
/// on purpose.
pub fn by_name(name: &str) -> Option<Target> {
    all()
        .into_iter()
        .chain(selftest::targets())
        .find(|t| t.name == name)
}

/// The bytes a writer of the product puts in a file: `write` is given a
/// path in a scratch directory. Used to make seeds in formats no shared
/// file covers.
pub(crate) fn written(name: &str, write: impl FnOnce(&Path) -> Result<(), String>) -> Vec<u8> {
    let dir = std::env::temp_dir().join(format!("fuzz-seed-{}", std::process::id()));
    let path = dir.join(name);
    let bytes = std::fs::create_dir_all(&dir)
        .map_err(|e| e.to_string())
        .and_then(|_| write(&path))
        .and_then(|_| std::fs::read(&path).map_err(|e| e.to_string()));
    let _ = std::fs::remove_file(&path);
    match bytes {
        Ok(b) => b,
        Err(e) => {
            eprintln!("warning: cannot make the seed {name}: {e}");
            Vec::new()
        }
    }
}

/// The seeds that are present, in a stable order.
pub(crate) fn present(list: impl IntoIterator<Item = Option<Vec<u8>>>) -> Vec<Vec<u8>> {
    list.into_iter()
        .flatten()
        .filter(|s| !s.is_empty())
        .collect()
}
