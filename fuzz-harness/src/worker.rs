//! The worker process: runs executions `from..` of one target and reports
//! on stdout, one line each:
//!
//! ```text
//! seeds N              the target's seed count
//! at I                 (trace mode) execution I starts
//! panic I WHERE: MSG   execution I panicked (the worker goes on)
//! alloc I BYTES HOW    execution I broke the allocation cap (the worker ends)
//! hang I MS            execution I ran past the time limit (the worker ends)
//! progress N           N executions done
//! done N               finished after N executions
//! ```

use std::io::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use crate::guard;
use crate::mutate::{COMMON_TOKENS, input_for};
use crate::targets::{Seeds, Target, by_name};

/// What one worker runs.
#[derive(Debug, Clone)]
pub struct WorkerArgs {
    /// Target name.
    pub target: String,
    /// First execution index.
    pub from: u64,
    /// At most this many executions.
    pub execs: u64,
    /// At most this long.
    pub seconds: f64,
    /// Time limit of one execution.
    pub timeout: Duration,
    /// Announce every execution before it runs (to find a crash).
    pub trace: bool,
    /// Where the seeds are.
    pub seeds: Seeds,
}

/// The message of the last panic, set by the hook.
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "(no message)".into());
        let place = info
            .location()
            .map_or("?".into(), |l| format!("{}:{}", l.file(), l.line()));
        let line = format!("{place}: {}", msg.replace(['\n', '\r'], " "));
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = Some(line);
        }
    }));
}

/// The tokens of `target`: the common ones and its own.
pub fn tokens(target: &Target) -> Vec<&'static str> {
    COMMON_TOKENS.iter().chain(target.tokens).copied().collect()
}

/// Where scratch directories go: memory (`/dev/shm`) where there is one.
/// Rewriting a file in place on ext4 flushes it to disk on close, which
/// held every execution to about 2 ms and loaded the disk.
pub fn scratch_root() -> PathBuf {
    let shm = PathBuf::from("/dev/shm");
    if shm.is_dir() {
        shm
    } else {
        std::env::temp_dir()
    }
}

/// A scratch directory for `target` in this process (reused by every
/// execution).
fn scratch(target: &str) -> Result<PathBuf> {
    let dir = scratch_root()
        .join(format!("opennerf-fuzz-{}", std::process::id()))
        .join(target);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

/// Runs the worker; returns when the budget is spent.
pub fn run(args: &WorkerArgs) -> Result<()> {
    let Some(target) = by_name(&args.target) else {
        bail!("no fuzz target called {:?}", args.target);
    };
    let seeds = (target.seeds)(&args.seeds);
    let tokens = tokens(&target);
    let dir = scratch(target.name)?;
    (target.setup)(&dir, &args.seeds)
        .with_context(|| format!("writing the companion files of {}", target.name))?;
    let file = dir.join(target.file);
    install_panic_hook();
    guard::start_watchdog(args.timeout);
    println!("seeds {}", seeds.len());
    let start = Instant::now();
    let mut last_report = start;
    let mut done = 0u64;
    while done < args.execs && start.elapsed().as_secs_f64() < args.seconds {
        let index = args.from + done;
        let input = input_for(target.name, &seeds, &tokens, index);
        std::fs::write(&file, &input).with_context(|| format!("writing {}", file.display()))?;
        if args.trace {
            println!("at {index}");
            std::io::stdout().flush()?;
        }
        guard::arm(index, guard::cap_for(input.len()));
        let outcome = catch_unwind(AssertUnwindSafe(|| (target.run)(&file)));
        guard::disarm();
        if outcome.is_err() {
            let msg = LAST_PANIC.lock().ok().and_then(|mut m| m.take());
            println!("panic {index} {}", msg.unwrap_or_else(|| "?".into()));
        }
        done += 1;
        if last_report.elapsed() > Duration::from_millis(200) {
            println!("progress {done}");
            last_report = Instant::now();
        }
    }
    println!("done {done}");
    std::io::stdout().flush()?;
    let _ = std::fs::remove_dir_all(dir.parent().unwrap_or(&dir));
    Ok(())
}
