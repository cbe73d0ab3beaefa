//! `--perf-control FIFO`: brackets the timed training steps with `enable`
//! and `disable` written to perf's control FIFO (`perf record -D -1
//! --control fifo:FIFO`), so that a profile holds the steps alone, not the
//! ball fit, the warm-up step or the inference timing
//! (`scripts/profile-step.sh`).

use std::io::Write;
use std::path::Path;
use std::sync::Mutex;

static FIFO: Mutex<Option<std::fs::File>> = Mutex::new(None);

/// Opens the FIFO (perf must already be reading it).
pub fn open(path: &Path) -> std::io::Result<()> {
    let file = std::fs::OpenOptions::new().write(true).open(path)?;
    *FIFO.lock().unwrap_or_else(|e| e.into_inner()) = Some(file);
    Ok(())
}

fn send(command: &str) {
    if let Some(f) = FIFO.lock().unwrap_or_else(|e| e.into_inner()).as_mut() {
        // A profile that misses a bracket is visibly empty; the benchmark's
        // own figures do not depend on it.
        if let Err(e) = writeln!(f, "{command}").and_then(|_| f.flush()) {
            eprintln!("warning: perf control FIFO: {e}");
        }
    }
}

/// Starts sampling.
pub fn enable() {
    send("enable");
}

/// Stops sampling.
pub fn disable() {
    send("disable");
}
