//! Running one task of a batch: train (new, resumed from its newest
//! checkpoint, or skipped when trained), then its `eval` commands, with
//! the progress in the run's `batch_task.json`, so that a task run again
//! (requeued, or the batch restarted) continues where it stopped.

use std::path::Path;

use field_ops::batch_dir::{BatchTask, TaskRecord, TaskState};
use field_ops::run_dir::RunDir;
use train::TrainError;
use train::interrupt::StopFlag;

use crate::error::BatchError;
use crate::scenes::{eval_cli, train_cli};

/// How a task ended.
#[derive(Debug, Clone, PartialEq)]
pub enum TaskOutcome {
    /// Trained and evaluated, in this call.
    Done,
    /// Already done before this call.
    AlreadyDone,
    /// A signal stopped it; its checkpoint is written (or it stopped
    /// between steps) and running it again continues.
    Interrupted,
    /// An error stopped it (recorded in its `batch_task.json`).
    Failed(String),
}

/// Runs `task` of the batch in `dir`.
pub fn run_task(dir: &Path, task: &BatchTask, stop: &StopFlag) -> Result<TaskOutcome, BatchError> {
    let run = dir.join(&task.run);
    let mut record = TaskRecord::read(&run)?.unwrap_or(TaskRecord {
        state: TaskState::Running,
        attempts: 0,
        eval_done: Vec::new(),
        error: None,
    });
    if record.state == TaskState::Done {
        eprintln!("{}: done before, skipped", task.run);
        return Ok(TaskOutcome::AlreadyDone);
    }
    std::fs::create_dir_all(&run).map_err(|e| BatchError::dir(&run, e))?;
    record.attempts += 1;
    record.state = TaskState::Running;
    record.error = None;
    record.write(&run)?;
    let outcome = train_and_evaluate(&run, task, &mut record, stop)?;
    match &outcome {
        TaskOutcome::Done => record.state = TaskState::Done,
        TaskOutcome::Failed(e) => {
            record.state = TaskState::Failed;
            record.error = Some(e.clone());
        }
        TaskOutcome::Interrupted | TaskOutcome::AlreadyDone => {}
    }
    record.write(&run)?;
    Ok(outcome)
}

fn train_and_evaluate(
    run: &Path,
    task: &BatchTask,
    record: &mut TaskRecord,
    stop: &StopFlag,
) -> Result<TaskOutcome, BatchError> {
    let dir = RunDir::new(run);
    if dir.summary().exists() {
        eprintln!("{}: trained before", task.run);
    } else {
        if stop.requested() {
            return Ok(TaskOutcome::Interrupted);
        }
        let cli = match train_command(run, task) {
            Ok(cli) => cli,
            Err(e) => return Ok(TaskOutcome::Failed(e)),
        };
        match train::run_cli(&cli, stop) {
            Ok(outcome) => eprintln!(
                "{}: trained, {} iterations, held-out PSNR {:.2} dB",
                task.run, outcome.summary.iterations, outcome.summary.heldout_interior.psnr
            ),
            Err(e @ TrainError::Interrupted { .. }) => {
                eprintln!("{}: {e}", task.run);
                return Ok(TaskOutcome::Interrupted);
            }
            Err(e) => return Ok(TaskOutcome::Failed(format!("train: {e}"))),
        }
    }
    for (i, step) in task.eval.iter().enumerate() {
        if record.eval_done.contains(&i) {
            continue;
        }
        if stop.requested() {
            return Ok(TaskOutcome::Interrupted);
        }
        eprintln!("{}: eval {}", task.run, step.join(" "));
        let result = eval_cli(step, run)
            .map_err(anyhow::Error::msg)
            .and_then(eval::cli::run);
        if let Err(e) = result {
            return Ok(TaskOutcome::Failed(format!(
                "eval {}: {e:#}",
                step.join(" ")
            )));
        }
        record.eval_done.push(i);
        record.write(run)?;
    }
    Ok(TaskOutcome::Done)
}

/// `train`'s command line for the task: a new run, or `--resume` where
/// the run has a checkpoint. A run stopped before its first checkpoint is
/// started over (its first files are removed first).
fn train_command(run: &Path, task: &BatchTask) -> Result<train::cli::Cli, String> {
    let cli = train_cli(&task.train, run)?;
    let dir = RunDir::new(run);
    let checkpoints =
        train::checkpoint::list_checkpoints(&dir.checkpoints()).map_err(|e| e.to_string())?;
    let Some(&(iteration, _)) = checkpoints.last() else {
        let partial: Vec<_> = [dir.config(), dir.metrics()]
            .into_iter()
            .filter(|p| p.exists())
            .collect();
        if !partial.is_empty() {
            eprintln!(
                "{}: stopped before its first checkpoint: starting it over",
                task.run
            );
        }
        for p in partial {
            std::fs::remove_file(&p).map_err(|e| format!("{}: {e}", p.display()))?;
        }
        return Ok(cli);
    };
    eprintln!(
        "{}: resuming from its checkpoint at iteration {iteration}",
        task.run
    );
    // A resumed run keeps its scene and configuration; only the session's
    // options apply. A time budget is what the run has not spent (a spent
    // one, a millisecond: `train` then saves and evaluates at once), read
    // from the checkpoint `train` resumes from.
    let time_budget = match cli.time_budget {
        None => None,
        Some(budget) => {
            let (ckpt, _, _) =
                train::checkpoint::newest_intact(&dir.checkpoints()).map_err(|e| e.to_string())?;
            Some((budget - ckpt.state.wall_seconds).max(1e-3))
        }
    };
    let mut resumed = train_cli(&[], run)?;
    resumed.out = None;
    resumed.resume = Some(run.to_path_buf());
    resumed.compute = cli.compute;
    resumed.stop_at = cli.stop_at;
    resumed.quiet = cli.quiet;
    resumed.no_final_render = cli.no_final_render;
    resumed.time_budget = time_budget;
    Ok(resumed)
}
