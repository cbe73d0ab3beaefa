//! Checkpoint files: model weights, optimiser state and the training
//! position in one self-checking file, written atomically.
//!
//! Layout (all integers little-endian):
//!
//! ```text
//! magic "ONERFCK1" | u64 state_len | u64 model_len | u64 optim_len | u64 checksum
//! state (JSON) | model (burnpack bytes) | optimiser (burnpack bytes)
//! ```
//!
//! The checksum is FNV-1a (64 bit) over everything after the header, so a
//! truncated file or one overwritten with garbage is reported as corrupt
//! before any of it is decoded.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::TrainError;
use field_ops::files::write_atomic;

const MAGIC: &[u8; 8] = b"ONERFCK1";
const HEADER_LEN: usize = 8 + 4 * 8;
/// File extension of checkpoint files.
pub const EXTENSION: &str = "onck";

/// Where the training loop stood when the checkpoint was taken.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckpointState {
    /// Iterations completed (the next step to run has this index).
    pub iteration: usize,
    /// Base seed of the run; the ray sampler and the stratified jitter of
    /// iteration `i` are seeded from `(seed, i)`, so this plus `iteration`
    /// is the whole sampler position.
    pub seed: u64,
    /// Steps skipped so far because of a non-finite loss or gradient.
    pub skipped_steps: usize,
    /// Wall-clock seconds of the run before this checkpoint (training,
    /// periodic evaluations and checkpoints).
    pub wall_seconds: f64,
    /// Of those, seconds spent in training steps.
    pub train_seconds: f64,
    /// Rays processed before this checkpoint.
    pub rays_processed: u64,
    /// The occupancy grid (hex of its bytes), when empty-space skipping is on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occupancy: Option<String>,
}

/// A decoded checkpoint: position plus the two serialised records.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// Training position.
    pub state: CheckpointState,
    /// Model record (burnpack bytes from `Module::into_record().into_bytes()`).
    pub model: Vec<u8>,
    /// Optimiser record (burnpack bytes from `ModuleOptimizer::into_bytes()`).
    pub optimizer: Vec<u8>,
}

/// FNV-1a, 64 bit: cheap and good enough to catch truncation and garbage.
fn fnv1a(parts: &[&[u8]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for part in parts {
        for &b in *part {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

impl Checkpoint {
    /// Serialises the checkpoint to its on-disk form.
    pub fn to_bytes(&self) -> Vec<u8> {
        // Serialising a plain struct of numbers cannot fail.
        let state = serde_json::to_vec(&self.state).unwrap_or_default();
        let mut out =
            Vec::with_capacity(HEADER_LEN + state.len() + self.model.len() + self.optimizer.len());
        out.extend_from_slice(MAGIC);
        for len in [state.len(), self.model.len(), self.optimizer.len()] {
            out.extend_from_slice(&(len as u64).to_le_bytes());
        }
        let sum = fnv1a(&[&state, &self.model, &self.optimizer]);
        out.extend_from_slice(&sum.to_le_bytes());
        out.extend_from_slice(&state);
        out.extend_from_slice(&self.model);
        out.extend_from_slice(&self.optimizer);
        out
    }

    /// Parses and verifies the on-disk form; `path` is only used in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, TrainError> {
        let bad = |m: String| TrainError::checkpoint(path, m);
        if bytes.len() < HEADER_LEN {
            return Err(bad(format!(
                "file is {} bytes, shorter than the {HEADER_LEN}-byte header (truncated?)",
                bytes.len()
            )));
        }
        if &bytes[..8] != MAGIC {
            return Err(bad("not a checkpoint file (bad magic bytes)".into()));
        }
        let word = |i: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[8 + 8 * i..16 + 8 * i]);
            u64::from_le_bytes(b)
        };
        let (state_len, model_len, optim_len, sum) = (word(0), word(1), word(2), word(3));
        let body = (bytes.len() - HEADER_LEN) as u64;
        let expected = state_len
            .checked_add(model_len)
            .and_then(|v| v.checked_add(optim_len));
        if expected != Some(body) {
            return Err(bad(format!(
                "header announces {state_len} + {model_len} + {optim_len} bytes but the file holds {body} (truncated or overwritten)"
            )));
        }
        let (s, m) = (state_len as usize, model_len as usize);
        let rest = &bytes[HEADER_LEN..];
        let (state, rest) = rest.split_at(s);
        let (model, optimizer) = rest.split_at(m);
        if fnv1a(&[state, model, optimizer]) != sum {
            return Err(bad("checksum mismatch (file damaged)".into()));
        }
        let state: CheckpointState = serde_json::from_slice(state)
            .map_err(|e| bad(format!("training state is not valid JSON: {e}")))?;
        Ok(Self {
            state,
            model: model.to_vec(),
            optimizer: optimizer.to_vec(),
        })
    }

    /// Writes the checkpoint to `path` atomically: a temporary file in the
    /// same directory is written, flushed to disk and renamed over `path`,
    /// so a crash never leaves a half-written checkpoint under the real name.
    pub fn write(&self, path: &Path) -> Result<(), TrainError> {
        Ok(write_atomic(path, &self.to_bytes())?)
    }

    /// Reads and verifies the checkpoint at `path`.
    pub fn read(path: &Path) -> Result<Self, TrainError> {
        let bytes = std::fs::read(path).map_err(|e| TrainError::io(path, e))?;
        Self::from_bytes(&bytes, path)
    }
}

/// The checkpoint file name for `iteration` inside `dir`
/// (`ckpt-00001200.onck`; zero-padded so names sort by iteration).
pub fn checkpoint_path(dir: &Path, iteration: usize) -> PathBuf {
    dir.join(format!("ckpt-{iteration:08}.{EXTENSION}"))
}

/// All checkpoints in `dir` with their iteration, oldest first.
pub fn list_checkpoints(dir: &Path) -> Result<Vec<(usize, PathBuf)>, TrainError> {
    if !dir.exists() {
        return Ok(Vec::new());
    }
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| TrainError::io(dir, e))? {
        let path = entry.map_err(|e| TrainError::io(dir, e))?.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        let iteration = name
            .strip_prefix("ckpt-")
            .and_then(|n| n.strip_suffix(&format!(".{EXTENSION}")))
            .and_then(|n| n.parse::<usize>().ok());
        if let Some(i) = iteration {
            found.push((i, path));
        }
    }
    found.sort();
    Ok(found)
}

/// Deletes all but the newest `keep` checkpoints in `dir` (keeping at least
/// one earlier good checkpoint next to the newest one guards against a
/// damaged newest file), and the temporary files of writes that a killed
/// process left behind.
pub fn prune_checkpoints(dir: &Path, keep: usize) -> Result<(), TrainError> {
    let all = list_checkpoints(dir)?;
    let n = all.len().saturating_sub(keep.max(1));
    for (_, path) in &all[..n] {
        std::fs::remove_file(path).map_err(|e| TrainError::io(path, e))?;
    }
    remove_stale_temp_files(dir)?;
    Ok(())
}

/// The process id in a temporary name written by [`write_atomic`](field_ops::files::write_atomic)
/// (`.NAME.tmp-PID`).
fn temp_file_pid(name: &str) -> Option<u32> {
    let (_, pid) = name.strip_prefix('.')?.rsplit_once(".tmp-")?;
    pid.parse().ok()
}

/// Whether process `pid` is running. Where `/proc` does not exist, only this
/// process counts as running (two trainings writing one run directory at the
/// same time are not supported anyway).
fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc = Path::new("/proc");
    proc.is_dir() && proc.join(pid.to_string()).exists()
}

/// Deletes the temporary files in `dir` that [`field_ops::files::write_atomic`] calls of
/// processes no longer running left behind (a kill during a write leaves
/// one; the real file it was to replace is intact). Returns what was deleted.
pub fn remove_stale_temp_files(dir: &Path) -> Result<Vec<PathBuf>, TrainError> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    let mut removed = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| TrainError::io(dir, e))? {
        let path = entry.map_err(|e| TrainError::io(dir, e))?.path();
        let stale = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(temp_file_pid)
            .is_some_and(|pid| !process_alive(pid));
        if stale && path.is_file() {
            std::fs::remove_file(&path).map_err(|e| TrainError::io(&path, e))?;
            removed.push(path);
        }
    }
    Ok(removed)
}

/// The newest checkpoint in `dir` that reads back intact, its path, and the
/// errors of the newer ones that did not (each renamed to `*.damaged`, so it
/// is kept for inspection but never listed or pruned as a checkpoint again).
/// Keeping an older checkpoint next to the newest is for exactly this case.
pub fn newest_intact(dir: &Path) -> Result<(Checkpoint, PathBuf, Vec<TrainError>), TrainError> {
    let all = list_checkpoints(dir)?;
    let mut damaged = Vec::new();
    for (_, path) in all.iter().rev() {
        match Checkpoint::read(path) {
            Ok(ckpt) => {
                for (_, bad) in all.iter().rev().take(damaged.len()) {
                    let mut aside = bad.clone().into_os_string();
                    aside.push(".damaged");
                    std::fs::rename(bad, &aside).map_err(|e| TrainError::io(bad, e))?;
                }
                return Ok((ckpt, path.clone(), damaged));
            }
            Err(e @ TrainError::Checkpoint { .. }) => damaged.push(e),
            Err(e) => return Err(e),
        }
    }
    match damaged.len() {
        0 => Err(TrainError::NoCheckpoint {
            path: dir.parent().unwrap_or(dir).to_path_buf(),
        }),
        1 => Err(damaged.remove(0)),
        n => {
            let first = damaged.remove(0);
            Err(TrainError::checkpoint(
                dir,
                format!(
                    "all {n} checkpoints are damaged; the newest: {first}; {}",
                    damaged
                        .iter()
                        .map(|e| e.to_string())
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Checkpoint {
        Checkpoint {
            state: CheckpointState {
                iteration: 40,
                seed: 7,
                skipped_steps: 1,
                wall_seconds: 2.5,
                train_seconds: 2.0,
                rays_processed: 1 << 20,
                occupancy: Some("00ff".into()),
            },
            model: (0..=255u8).cycle().take(1000).collect(),
            optimizer: vec![9; 77],
        }
    }

    fn tmpdir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("train-ckpt-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn roundtrip_through_a_file() {
        let d = tmpdir("rt");
        let p = checkpoint_path(&d, 40);
        sample().write(&p).unwrap();
        assert_eq!(Checkpoint::read(&p).unwrap(), sample());
        // No temporary file is left behind.
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn every_truncation_and_a_flipped_byte_are_rejected() {
        let bytes = sample().to_bytes();
        let p = Path::new("/x/ckpt.onck");
        for cut in [
            0,
            7,
            HEADER_LEN - 1,
            HEADER_LEN,
            bytes.len() / 2,
            bytes.len() - 1,
        ] {
            let err = Checkpoint::from_bytes(&bytes[..cut], p).unwrap_err();
            assert!(err.to_string().contains("/x/ckpt.onck"), "{err}");
        }
        for pos in [3, HEADER_LEN + 2, bytes.len() - 5] {
            let mut b = bytes.clone();
            b[pos] ^= 0x5a;
            assert!(matches!(
                Checkpoint::from_bytes(&b, p),
                Err(TrainError::Checkpoint { .. })
            ));
        }
        let garbage: Vec<u8> = (0..500u32).map(|i| (i * 31 % 251) as u8).collect();
        assert!(Checkpoint::from_bytes(&garbage, p).is_err());
    }

    #[test]
    fn stale_temporary_files_are_removed_and_live_ones_kept() {
        let d = tmpdir("stale");
        // A pid far above any pid_max: no such process.
        let stale = d.join(".ckpt-00000020.onck.tmp-4000000000");
        let live = d.join(format!(".ckpt-00000040.onck.tmp-{}", std::process::id()));
        std::fs::write(&stale, b"half a checkpoint").unwrap();
        std::fs::write(&live, b"being written").unwrap();
        sample().write(&checkpoint_path(&d, 20)).unwrap();
        prune_checkpoints(&d, 2).unwrap();
        assert!(!stale.exists(), "a dead process's temporary file is left");
        assert!(
            live.exists(),
            "this process's own temporary file was removed"
        );
        assert!(checkpoint_path(&d, 20).exists());
        assert_eq!(temp_file_pid(".model.bpk.tmp-12"), Some(12));
        assert_eq!(temp_file_pid("model.bpk"), None);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_damaged_newest_checkpoint_falls_back_to_the_older_one() {
        let d = tmpdir("fallback");
        let mut older = sample();
        older.state.iteration = 20;
        older.write(&checkpoint_path(&d, 20)).unwrap();
        sample().write(&checkpoint_path(&d, 40)).unwrap();
        let newest = checkpoint_path(&d, 40);
        let bytes = std::fs::read(&newest).unwrap();
        std::fs::write(&newest, &bytes[..bytes.len() / 2]).unwrap();
        let (ckpt, path, damaged) = newest_intact(&d).unwrap();
        assert_eq!(ckpt.state.iteration, 20);
        assert_eq!(path, checkpoint_path(&d, 20));
        assert_eq!(damaged.len(), 1);
        assert!(damaged[0].to_string().contains("ckpt-00000040"));
        // The damaged file is kept aside, no longer listed as a checkpoint.
        let its: Vec<usize> = list_checkpoints(&d).unwrap().iter().map(|c| c.0).collect();
        assert_eq!(its, vec![20]);
        assert!(d.join("ckpt-00000040.onck.damaged").exists());
        // With every checkpoint damaged the error names the newest.
        std::fs::write(checkpoint_path(&d, 20), b"garbage").unwrap();
        let err = newest_intact(&d).unwrap_err().to_string();
        assert!(err.contains("ckpt-00000020"), "{err}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn listing_sorts_by_iteration_and_pruning_keeps_the_newest() {
        let d = tmpdir("list");
        for i in [300, 20, 1000] {
            sample().write(&checkpoint_path(&d, i)).unwrap();
        }
        std::fs::write(d.join("notes.txt"), "x").unwrap();
        let its: Vec<usize> = list_checkpoints(&d).unwrap().iter().map(|c| c.0).collect();
        assert_eq!(its, vec![20, 300, 1000]);
        prune_checkpoints(&d, 2).unwrap();
        let its: Vec<usize> = list_checkpoints(&d).unwrap().iter().map(|c| c.0).collect();
        assert_eq!(its, vec![300, 1000]);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
