//! Wall time and peak resident memory of the stages of a pipeline (scene
//! build, sampler, training, novel views, renders, evaluation), measured by
//! the OS and appended to `stages.json` in the run directory, so that one
//! run's records, from `train` and then `eval`, show where time and memory
//! go as the scene grows.
//!
//! The peak is Linux's `VmHWM` (the high-water mark of the resident set),
//! reset at each stage boundary by writing `5` to `/proc/self/clear_refs`,
//! after returning the allocator's freed pages to the OS so that the peak
//! counts what the stage holds rather than what earlier stages freed. Where
//! `/proc` is unavailable the peak is recorded as `null`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::OpsError;
use crate::json::write_json;

/// Name of the stage records in a run directory.
pub const STAGES_FILE: &str = "stages.json";

/// One finished stage.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageRecord {
    /// What ran (`scene`, `sampler`, `training`, `novel views`, ...).
    pub stage: String,
    /// Wall time, seconds, without the stages nested in it.
    pub seconds: f64,
    /// Peak resident memory during the stage (outside nested stages), MiB;
    /// `None` where the OS does not report it.
    pub peak_mb: Option<f64>,
}

/// A stage begun and not yet ended.
#[derive(Debug)]
struct Open {
    name: String,
    start: Instant,
    /// Wall time spent in stages nested in this one.
    nested_seconds: f64,
    /// Highest `VmHWM` seen in this stage's own stretches, KiB; `None` once
    /// a reading or a reset failed.
    peak_kib: Option<u64>,
}

/// Times stages and appends their records to a `stages.json`. Stages may
/// nest (novel views inside training): the outer stage's time and peak
/// leave out the nested ones'. Records made before the file is known (the
/// scene is built before its run directory exists) are kept until
/// [`StageLog::attach`].
#[derive(Debug, Default)]
pub struct StageLog {
    path: Option<PathBuf>,
    open: Vec<Open>,
    pending: Vec<StageRecord>,
}

impl StageLog {
    /// A log whose file is not known yet.
    pub fn pending() -> Self {
        Self::default()
    }

    /// A log appending to `stages.json` in the run directory `dir`.
    pub fn for_run(dir: &Path) -> Self {
        Self {
            path: Some(dir.join(STAGES_FILE)),
            ..Self::default()
        }
    }

    /// Appends to `path` from now on, writing the records kept so far.
    pub fn attach(&mut self, path: PathBuf) -> Result<(), OpsError> {
        for record in &self.pending {
            append_record(&path, record)?;
        }
        self.pending.clear();
        self.path = Some(path);
        Ok(())
    }

    /// Starts stage `name`: the peak counter is reset, after the stage it
    /// interrupts (if any) is credited with its peak so far.
    pub fn begin(&mut self, name: &str) {
        let now = read_peak_kib();
        if let Some(outer) = self.open.last_mut() {
            outer.peak_kib = fold_peak(outer.peak_kib, now);
        }
        let reset = reset_peak();
        self.open.push(Open {
            name: name.to_string(),
            start: Instant::now(),
            nested_seconds: 0.0,
            peak_kib: if reset { Some(0) } else { None },
        });
    }

    /// Ends the innermost stage and appends its record (kept in memory
    /// until a file is attached). A stage interrupted by it resumes with a
    /// fresh peak counter. `None` when no stage is open.
    pub fn end(&mut self) -> Result<Option<StageRecord>, OpsError> {
        let Some(stage) = self.open.pop() else {
            return Ok(None);
        };
        let elapsed = stage.start.elapsed().as_secs_f64();
        let peak = fold_peak(stage.peak_kib, read_peak_kib());
        if let Some(outer) = self.open.last_mut() {
            outer.nested_seconds += elapsed;
            if !reset_peak() {
                outer.peak_kib = None;
            }
        }
        let record = StageRecord {
            stage: stage.name,
            seconds: (elapsed - stage.nested_seconds).max(0.0),
            peak_mb: peak.map(|kib| (kib as f64 / 1024.0 * 10.0).round() / 10.0),
        };
        match &self.path {
            Some(path) => append_record(path, &record)?,
            None => self.pending.push(record.clone()),
        }
        Ok(Some(record))
    }

    /// Runs `f` as stage `name`; the record is written only when `f`
    /// succeeds.
    pub fn run<T, E: From<OpsError>>(
        &mut self,
        name: &str,
        f: impl FnOnce() -> Result<T, E>,
    ) -> Result<T, E> {
        self.begin(name);
        match f() {
            Ok(value) => {
                self.end()?;
                Ok(value)
            }
            Err(e) => {
                self.open.pop();
                Err(e)
            }
        }
    }
}

/// The larger of a stage's peak so far and a new reading; unknown once
/// either is.
fn fold_peak(so_far: Option<u64>, now: Option<u64>) -> Option<u64> {
    Some(so_far?.max(now?))
}

/// The records of a `stages.json` (none when the file does not exist).
pub fn read_records(path: &Path) -> Result<Vec<StageRecord>, OpsError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    crate::json::read_json(path)
}

/// Appends `record` to the JSON array in `path`, rewriting it atomically.
pub fn append_record(path: &Path, record: &StageRecord) -> Result<(), OpsError> {
    let mut records = read_records(path)?;
    records.push(record.clone());
    write_json(path, &records)
}

/// Resets this process's peak resident size to its current resident size
/// (Linux), after the allocator returns its freed pages. Whether it did.
pub fn reset_peak() -> bool {
    crate::allocator::release_freed_pages();
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// This process's peak resident size (`VmHWM`) since start or the last
/// reset, KiB; `None` where `/proc/self/status` is unavailable.
pub fn read_peak_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_hwm_kib(&status)
}

/// The `VmHWM:   1234 kB` line of a `/proc/<pid>/status` text, in KiB.
fn parse_hwm_kib(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let mut parts = line["VmHWM:".len()..].split_whitespace();
    let value: u64 = parts.next()?.parse().ok()?;
    match parts.next().unwrap_or("kB") {
        "kB" => Some(value),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hwm_line_parses() {
        let s = "Name:\tx\nVmPeak:\t  999 kB\nVmHWM:\t    2048 kB\nVmRSS:\t 1 kB\n";
        assert_eq!(parse_hwm_kib(s), Some(2048));
        assert_eq!(parse_hwm_kib("VmRSS: 1 kB"), None);
        assert_eq!(fold_peak(Some(3), Some(5)), Some(5));
        assert_eq!(fold_peak(None, Some(5)), None);
    }

    #[test]
    fn pending_records_are_written_on_attach_and_appended() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join(STAGES_FILE);
        let mut log = StageLog::pending();
        log.begin("scene");
        log.end().expect("end");
        assert!(!path.exists(), "nothing written before attach");
        log.attach(path.clone()).expect("attach");
        let out: Result<u8, OpsError> = log.run("sampler", || Ok(3));
        assert_eq!(out.expect("run"), 3);
        let failed: Result<(), OpsError> = log.run("broken", || {
            Err(OpsError::io(&path, std::io::Error::other("x")))
        });
        assert!(failed.is_err());
        // A second process (eval after train) appends to the same file.
        let mut later = StageLog::for_run(dir.path());
        later.begin("eval segment");
        later.end().expect("end");
        let records = read_records(&path).expect("read");
        let names: Vec<&str> = records.iter().map(|r| r.stage.as_str()).collect();
        assert_eq!(names, ["scene", "sampler", "eval segment"]);
        let text = std::fs::read_to_string(&path).expect("text");
        let back: Vec<StageRecord> = serde_json::from_str(&text).expect("json array");
        assert_eq!(back, records);
        assert!(records.iter().all(|r| r.seconds >= 0.0));
    }
}
