//! The supervisor: runs each target in worker processes, restarts a worker
//! after the execution that ended it, saves every failing input and
//! counts the defects.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

use crate::mutate::input_for;
use crate::targets::{Seeds, Target};
use crate::worker::tokens;

/// Restarts after which a target is given up (each restart is a defect).
const MAX_RESTARTS: usize = 25;
/// Inputs saved per defect signature.
const SAVED_PER_SIGNATURE: usize = 3;

/// How long each target runs.
#[derive(Debug, Clone, Copy)]
pub struct Budget {
    /// Executions per target.
    pub execs: u64,
    /// Seconds per target.
    pub seconds: f64,
}

/// Settings shared by every target's run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// This program (started as the worker).
    pub exe: PathBuf,
    /// The budget of each target.
    pub budget: Budget,
    /// Time limit of one execution.
    pub timeout: Duration,
    /// Where the seeds are.
    pub seeds: Seeds,
    /// Where failing inputs are saved.
    pub defects_dir: PathBuf,
}

/// One kind of failure of a target: the kind and, for a panic, where.
#[derive(Debug, Clone, Default)]
pub struct Defect {
    /// Failing executions with this signature.
    pub count: u64,
    /// The first failing execution.
    pub first_index: u64,
    /// The detail of the first (message, bytes, milliseconds).
    pub detail: String,
    /// The saved inputs.
    pub saved: Vec<PathBuf>,
}

/// The outcome of one target.
#[derive(Debug, Clone)]
pub struct TargetRun {
    /// Target name.
    pub name: String,
    /// Seeds it started from.
    pub seeds: usize,
    /// Executions done.
    pub execs: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Defects by signature.
    pub defects: BTreeMap<String, Defect>,
    /// Why it stopped before its budget, if it did.
    pub stopped: Option<String>,
}

/// What one worker run reported.
#[derive(Default)]
struct WorkerReport {
    done: Option<u64>,
    progress: u64,
    fatal: Option<(u64, String, String)>,
    last_at: Option<u64>,
}

/// Records a failing execution: counts it under `signature` and saves its
/// input (rebuilt from the index).
fn record(
    run: &mut TargetRun,
    target: &Target,
    seeds: &[Vec<u8>],
    opts: &RunOptions,
    (index, signature, detail): (u64, String, String),
) {
    let entry = run.defects.entry(signature.clone()).or_default();
    if entry.count == 0 {
        entry.first_index = index;
        entry.detail = detail;
    }
    entry.count += 1;
    if entry.saved.len() < SAVED_PER_SIGNATURE {
        let input = input_for(target.name, seeds, &tokens(target), index);
        let dir = opts.defects_dir.join(target.name);
        let kind = signature.split(' ').next().unwrap_or("defect");
        let path = dir.join(format!("{kind}-{index}.bin"));
        if std::fs::create_dir_all(&dir)
            .and_then(|_| std::fs::write(&path, input))
            .is_ok()
        {
            entry.saved.push(path);
        }
    }
}

/// The signature and detail of a defect line (`panic I WHERE: MSG`,
/// `alloc I BYTES HOW`, `hang I MS`), with its index.
fn parse_defect(line: &str) -> Option<(u64, String, String)> {
    let mut parts = line.splitn(3, ' ');
    let kind = parts.next()?;
    let index: u64 = parts.next()?.parse().ok()?;
    let rest = parts.next().unwrap_or("").to_string();
    let signature = match kind {
        // A panic is told apart by where it happened.
        "panic" => format!("panic {}", rest.split(": ").next().unwrap_or("?")),
        "alloc" | "hang" => kind.to_string(),
        _ => return None,
    };
    Some((index, signature, rest))
}

/// Runs one worker of `target` from `from`; calls `on_progress` with the
/// executions it has done so far.
fn run_worker(
    target: &Target,
    opts: &RunOptions,
    (from, execs, seconds, trace): (u64, u64, f64, bool),
    mut on_line: impl FnMut(&str),
) -> Result<(WorkerReport, bool)> {
    let mut cmd = Command::new(&opts.exe);
    cmd.args(["--worker", target.name, "--from", &from.to_string()])
        .args([
            "--execs",
            &execs.to_string(),
            "--seconds",
            &seconds.to_string(),
        ])
        .args(["--timeout-ms", &opts.timeout.as_millis().to_string()])
        .arg("--data")
        .arg(&opts.seeds.data)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    if trace {
        cmd.arg("--trace");
    }
    let mut child = cmd
        .spawn()
        .with_context(|| format!("starting {}", opts.exe.display()))?;
    let mut report = WorkerReport::default();
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines() {
            let line = line.context("reading the worker's output")?;
            let (word, rest) = line.split_once(' ').unwrap_or((&line, ""));
            match word {
                "progress" => report.progress = rest.parse().unwrap_or(report.progress),
                "done" => report.done = rest.parse().ok(),
                "at" => report.last_at = rest.parse().ok(),
                "alloc" | "hang" => report.fatal = parse_defect(&line),
                _ => {}
            }
            on_line(&line);
        }
    }
    let status = child.wait().context("waiting for the worker")?;
    // A worker ended by its watchdog leaves its scratch directory behind.
    let _ = std::fs::remove_dir_all(
        crate::worker::scratch_root().join(format!("opennerf-fuzz-{}", child.id())),
    );
    Ok((report, status.success()))
}

fn progress_bar(name: &str, budget: Budget) -> ProgressBar {
    let bar = if budget.execs == u64::MAX {
        ProgressBar::new_spinner()
    } else {
        ProgressBar::new(budget.execs)
    };
    let style = ProgressStyle::with_template(
        "{prefix:>22} [{elapsed_precise}] {wide_bar} {human_pos}/{human_len} ({per_sec}) {msg}",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_prefix(name.to_string());
    bar
}

/// Runs `target` for the budget; the worker is restarted after each
/// execution that ended it (allocation over the cap, hang, crash).
pub fn run_target(target: &Target, opts: &RunOptions) -> Result<TargetRun> {
    let seeds = (target.seeds)(&opts.seeds);
    let mut run = TargetRun {
        name: target.name.to_string(),
        seeds: seeds.len(),
        execs: 0,
        seconds: 0.0,
        defects: BTreeMap::new(),
        stopped: None,
    };
    let bar = progress_bar(target.name, opts.budget);
    let start = Instant::now();
    let (mut next, mut trace, mut restarts) = (0u64, false, 0usize);
    loop {
        let left_s = opts.budget.seconds - start.elapsed().as_secs_f64();
        let left_n = opts.budget.execs.saturating_sub(run.execs);
        if left_s <= 0.0 || left_n == 0 {
            break;
        }
        let n = if trace { left_n.min(20_000) } else { left_n };
        let base = run.execs;
        let mut panics = Vec::new();
        let (report, ok) = run_worker(target, opts, (next, n, left_s, trace), |line| {
            if let Some(p) = line
                .strip_prefix("progress ")
                .and_then(|p| p.parse::<u64>().ok())
            {
                bar.set_position(base + p);
            }
            if line.starts_with("panic ") {
                panics.extend(parse_defect(line));
            }
        })?;
        for p in panics {
            record(&mut run, target, &seeds, opts, p);
        }
        bar.set_message(format!("{} defects", run.defects.len()));
        if let (Some(done), true) = (report.done, ok) {
            run.execs += done;
            next += done;
            if trace && done == n {
                trace = false;
                continue;
            }
            break;
        }
        restarts += 1;
        if let Some(fatal) = report.fatal {
            run.execs += fatal.0 + 1 - next;
            next = fatal.0 + 1;
            record(&mut run, target, &seeds, opts, fatal);
        } else if trace {
            // The worker died in an execution it had announced.
            let index = report.last_at.unwrap_or(next);
            run.execs += index + 1 - next;
            next = index + 1;
            let detail = "the worker process died (signal or abort)".to_string();
            record(
                &mut run,
                target,
                &seeds,
                opts,
                (index, "crash".into(), detail),
            );
            trace = false;
        } else {
            // Died without saying where: replay from the last progress line
            // announcing every execution.
            run.execs += report.progress;
            next += report.progress;
            trace = true;
        }
        if restarts >= MAX_RESTARTS {
            run.stopped = Some(format!("stopped after {restarts} worker restarts"));
            break;
        }
    }
    run.seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    Ok(run)
}

/// A short path for messages: relative to `base` when inside it.
pub fn short(path: &Path, base: &Path) -> String {
    path.strip_prefix(base)
        .unwrap_or(path)
        .display()
        .to_string()
}
