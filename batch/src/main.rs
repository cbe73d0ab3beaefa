//! `batch`: trains and evaluates the scenes of a scene list, here or on a
//! Slurm cluster.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use batch::{TaskOutcome, run_task};
use clap::Parser;
use train::interrupt::{EXIT_INTERRUPTED, StopFlag};

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Where the batch runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Emit {
    /// Slurm job arrays (`sbatch` scripts).
    Slurm,
}

/// Train and evaluate every scene of a scene list, each into its own run
/// directory under --out.
///
/// Without --emit the runs go one after the other on this machine; finished
/// ones are skipped and stopped ones resumed, so the same command continues
/// a batch. `--emit slurm` writes job-array scripts instead (one task per
/// run; a preempted or requeued task writes a checkpoint and resumes from
/// it), and --submit submits them. `eval gather DIR` then writes the table.
/// The scene list's format: docs/guide/batch.md.
#[derive(Debug, Parser)]
#[command(name = "batch", version)]
struct Cli {
    /// The scene list (TOML: `[[scene]]` entries with `name`, `data` or
    /// `synthetic`, `train` flags, `eval` commands, `seeds`, `slurm`
    /// requests; `[defaults]` for all).
    #[arg(long, required_unless_present = "task")]
    scenes: Option<PathBuf>,
    /// The batch directory: `batch.json`, one run directory per run.
    #[arg(long)]
    out: PathBuf,
    /// Write the batch for a scheduler instead of running it here.
    #[arg(long, value_enum, conflicts_with = "task")]
    emit: Option<Emit>,
    /// Submit the written scripts with `sbatch` (implies --emit slurm).
    #[arg(long, conflicts_with = "task")]
    submit: bool,
    /// At most this many tasks of an array at once (`--array=...%K`).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    max_parallel: Option<u64>,
    /// Run only task I of the batch already written to --out (what each
    /// array task runs). Exits with 75 when a signal stopped it after its
    /// checkpoint.
    #[arg(long, value_name = "I", conflicts_with = "scenes")]
    task: Option<usize>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Subnormals flushed to zero: docs/measurements/cpu-step.md.
    field_ops::subnormals::flush_to_zero();
    let stop = StopFlag::on_signals().unwrap_or_else(|e| {
        eprintln!("warning: signals will stop the batch without a checkpoint: {e}");
        StopFlag::new()
    });
    match run(&cli, &stop) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: &Cli, stop: &StopFlag) -> anyhow::Result<ExitCode> {
    if let Some(index) = cli.task {
        let task = batch::task(&cli.out, index)?;
        return Ok(exit_code(&run_task(&cli.out, &task, stop)?));
    }
    let scenes = cli.scenes.as_ref().context("--scenes is required")?;
    let list = batch::scenes::read(scenes)?;
    if cli.submit || cli.emit.is_some() {
        return emit(cli, &list);
    }
    let dir = batch::prepare_dir(&cli.out, &list)?;
    let tasks = &list.manifest.tasks;
    let mut failed = Vec::new();
    for task in tasks {
        eprintln!("== {} ({} of {})", task.run, task.index + 1, tasks.len());
        match run_task(&dir, task, stop)? {
            TaskOutcome::Interrupted => {
                eprintln!("batch stopped by a signal; the same command continues it");
                return Ok(ExitCode::from(EXIT_INTERRUPTED));
            }
            TaskOutcome::Failed(e) => {
                eprintln!("{}: failed: {e}", task.run);
                failed.push(task.run.clone());
            }
            TaskOutcome::Done | TaskOutcome::AlreadyDone => {}
        }
    }
    println!(
        "{} of {} runs done in {}; the table: eval gather {}",
        tasks.len() - failed.len(),
        tasks.len(),
        dir.display(),
        dir.display()
    );
    if failed.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "failed: {} (their batch_task.json says why; the same command retries them)",
            failed.join(", ")
        );
        Ok(ExitCode::FAILURE)
    }
}

fn exit_code(outcome: &TaskOutcome) -> ExitCode {
    match outcome {
        TaskOutcome::Done | TaskOutcome::AlreadyDone => ExitCode::SUCCESS,
        TaskOutcome::Interrupted => ExitCode::from(EXIT_INTERRUPTED),
        TaskOutcome::Failed(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Writes the array scripts, and submits them with --submit.
fn emit(cli: &Cli, list: &batch::Batch) -> anyhow::Result<ExitCode> {
    // Before anything is written: a submission that cannot happen leaves
    // no half-made batch behind.
    let sbatch = if cli.submit {
        Some(batch::slurm::find_sbatch()?)
    } else {
        None
    };
    let exe = std::env::current_exe().context("finding this program's path for the scripts")?;
    let dir = batch::prepare_dir(&cli.out, list)?;
    let slurm_out = dir.join("slurm");
    std::fs::create_dir_all(&slurm_out)
        .with_context(|| format!("creating {}", slurm_out.display()))?;
    let runs: Vec<String> = list.manifest.tasks.iter().map(|t| t.run.clone()).collect();
    let scripts = batch::slurm::scripts(
        &dir,
        &exe,
        &runs,
        &list.requests,
        cli.max_parallel.map(|k| k as usize),
    );
    for s in &scripts {
        field_ops::files::write_atomic(&s.path, s.text.as_bytes())?;
        println!("wrote {} ({} tasks)", s.path.display(), s.tasks.len());
    }
    match sbatch {
        None => {
            for s in &scripts {
                println!("submit: sbatch {}", s.path.display());
            }
        }
        Some(sbatch) => {
            for s in &scripts {
                let id = batch::slurm::submit(&sbatch, &s.path)?;
                println!(
                    "submitted job {id} ({} tasks): squeue -j {id}",
                    s.tasks.len()
                );
            }
        }
    }
    println!("when they are done: eval gather {}", dir.display());
    Ok(ExitCode::SUCCESS)
}
