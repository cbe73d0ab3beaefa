//! The steps the training loop has applied without reading anything back,
//! and their check: the values of a run of steps are read together (one
//! read-back), and where one was not finite the loop goes back to the
//! model, optimiser and state kept from before the run and takes the steps
//! again, each checked as it is taken (the guarded step), so that the
//! non-finite one is skipped exactly as a checked step would skip it.
//! Every input of a step (the batch, the jitter, the grid's update) is drawn
//! from a seed of its iteration, so the steps taken again are the same.

use burn::optim::ModuleOptimizer;
use model::{ClipStats, OpenNerf};

use crate::checkpoint::CheckpointState;
use crate::config::TrainConfig;
use crate::step::{StepReport, StepValues};

/// What the loop goes back to when a step of the run was not finite.
pub(super) struct Kept {
    pub model: OpenNerf,
    pub optim: ModuleOptimizer,
    pub mark: LoopMark,
}

/// The loop's own counts at the start of a run of unchecked steps.
pub(super) struct LoopMark {
    pub state: CheckpointState,
    /// What the grid clipped since the last log line.
    pub skipping: ClipStats,
    pub consecutive_bad: usize,
}

/// One step applied before its values were read.
pub(super) struct Pending {
    /// The iterations done after it (`state.iteration` once it ran).
    pub done: usize,
    pub values: StepValues,
    pub lr: f64,
    /// Rays drawn for it.
    pub rays: u64,
}

/// A run of unchecked steps and what was before them.
pub(super) struct Unchecked {
    pub kept: Kept,
    pub steps: Vec<Pending>,
}

/// A checked step: what it measured, at which learning rate, on how many
/// rays, and the iterations done after it.
pub(super) struct Checked {
    pub done: usize,
    pub report: StepReport,
    pub lr: f64,
    pub rays: u64,
}

/// What reading a run of steps found.
pub(super) enum Verdict {
    /// Every step was finite: they stand.
    Finite(Vec<Checked>),
    /// The step ending at iteration `done` was the first that was not:
    /// go back to `kept`.
    Back { kept: Box<Kept>, done: usize },
}

impl Unchecked {
    /// Starts a run from `kept`.
    pub(super) fn new(kept: Kept) -> Self {
        Self {
            kept,
            steps: Vec::new(),
        }
    }

    /// Reads the run's values (one read-back) and judges them.
    pub(super) fn check(self) -> Verdict {
        let (meta, values): (Vec<_>, Vec<_>) = self
            .steps
            .into_iter()
            .map(|p| ((p.done, p.lr, p.rays), p.values))
            .unzip();
        let reports = StepValues::read_all(values);
        if let Some(bad) = reports.iter().position(|r| !r.finite()) {
            return Verdict::Back {
                kept: Box::new(self.kept),
                done: meta[bad].0,
            };
        }
        let checked = meta
            .into_iter()
            .zip(reports)
            .map(|((done, lr, rays), mut report)| {
                report.applied = true;
                Checked {
                    done,
                    report,
                    lr,
                    rays,
                }
            })
            .collect();
        Verdict::Finite(checked)
    }
}

/// The first iteration after `done` whose steps run unchecked again: the
/// end of the log window the non-finite step fell in (the next multiple of
/// `every` after it), so that a run of bad steps is counted as it happens.
pub(super) fn checked_until(done: usize, every: usize) -> usize {
    let every = every.max(1);
    done.div_ceil(every) * every
}

/// Whether the steps are checked once `done` iterations of a session
/// ending at `end` are: a log line, an evaluation or a checkpoint is due.
pub(super) fn check_due(config: &TrainConfig, end: usize, done: usize) -> bool {
    let logging = config.logging;
    let due = |every: usize| every > 0 && done.is_multiple_of(every);
    done == end
        || due(logging.log_every.max(1))
        || due(logging.eval_every)
        || due(logging.checkpoint_every)
}

/// The console line when the step ending at iteration `done` was the
/// first non-finite one since iteration `from`.
pub(super) fn going_back(done: usize, from: usize) -> String {
    format!(
        "iteration {}: a non-finite loss or gradient since iteration {from}; \
         taking those steps again, each checked",
        done - 1
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_checked_to_the_end_of_the_bad_steps_log_window() {
        assert_eq!(checked_until(7, 25), 25);
        assert_eq!(checked_until(25, 25), 25);
        assert_eq!(checked_until(26, 25), 50);
        assert_eq!(checked_until(3, 1), 3);
        assert_eq!(checked_until(3, 0), 3);
    }
}
