//! A step and its accounting: the step taken, then counted once it is
//! known to be finite (steps are checked in batches, one read-back each);
//! a non-finite one is skipped and logged, and a check that finds one goes
//! back to before it; the training log line of a step when due.

use std::time::Instant;

use model::{ClipStats, OpenNerf};

use super::TrainLoop;
use crate::error::TrainError;
use crate::metrics_log::{MetricsEvent, NonfiniteLine, TrainLine};
use crate::progress::say;
use crate::training::console::{grid_line, show_step};
use crate::training::guard::{Checked, Kept, LoopMark, Verdict, check_due, going_back};
use crate::training::stepper::{Step, StepInputs};

impl TrainLoop<'_> {
    /// The step of iteration `it` ([`Stepper::take`]), its time and what
    /// the grid clipped of its batch.
    pub(super) fn step(
        &mut self,
        model: OpenNerf,
        it: usize,
    ) -> Result<(OpenNerf, Step), TrainError> {
        let step_start = Instant::now();
        let inputs = StepInputs {
            scene: &self.scene,
            train: &self.split.train,
            config: &self.config,
            device: self.device,
            seed: self.state.seed,
            end: self.end,
        };
        let check_after = check_due(&self.config, self.end, it + 1);
        let mark = || LoopMark {
            state: self.state.clone(),
            skipping: self.skipping,
            consecutive_bad: self.consecutive_bad,
        };
        let (next, step) = self.stepper.take(&inputs, model, it, check_after, mark)?;
        if let Some(clip) = step.clip() {
            self.skipping.add(clip);
        }
        self.state.train_seconds += step_start.elapsed().as_secs_f64();
        self.state.iteration += 1;
        Ok((next, step))
    }

    /// Counts and logs a checked step; keeps a deferred one for the next
    /// check, which is made when a log line, an evaluation or a checkpoint
    /// is due. Returns whether a check went back to an earlier iteration.
    pub(super) fn record(
        &mut self,
        model: &mut OpenNerf,
        it: usize,
        step: Step,
    ) -> Result<bool, TrainError> {
        match step {
            Step::Checked(checked) => {
                self.account(it, &checked)?;
                self.log_step(model, &checked)?;
                Ok(false)
            }
            Step::Deferred(pending) => {
                self.stepper.defer(*pending);
                let back = check_due(&self.config, self.end, self.state.iteration)
                    && self.settle(model)?;
                self.bar.set_position(self.state.iteration as u64);
                Ok(back)
            }
        }
    }

    /// Checks the steps taken since the last check (one read-back): finite
    /// ones are counted and the last logged when due; from a non-finite
    /// one, the model, optimiser and state go back to before the first of
    /// them (returns true), and the steps are taken again, checked.
    pub(super) fn settle(&mut self, model: &mut OpenNerf) -> Result<bool, TrainError> {
        match self.stepper.check() {
            None => Ok(false),
            Some(Verdict::Finite(steps)) => {
                for checked in &steps {
                    self.account(checked.done - 1, checked)?;
                }
                if let Some(last) = steps.last() {
                    self.log_step(model, last)?;
                }
                Ok(false)
            }
            Some(Verdict::Back { kept, done }) => {
                let Kept {
                    model: m,
                    optim,
                    mark,
                } = *kept;
                let seconds = self.state.train_seconds;
                *model = m;
                self.stepper
                    .went_back(optim, done, self.config.logging.log_every);
                (self.state, self.skipping) = (mark.state, mark.skipping);
                self.consecutive_bad = mark.consecutive_bad;
                self.state.train_seconds = seconds;
                self.bar.set_position(self.state.iteration as u64);
                say(&self.bar, going_back(done, self.state.iteration));
                Ok(true)
            }
        }
    }

    /// Counts the step of iteration `it`; a skipped one is logged, and too
    /// many in a row end the run.
    fn account(&mut self, it: usize, step: &Checked) -> Result<(), TrainError> {
        let report = &step.report;
        if report.applied {
            self.consecutive_bad = 0;
            self.state.rays_processed += step.rays;
            self.rate.add(step.rays);
            return Ok(());
        }
        self.consecutive_bad += 1;
        self.state.skipped_steps += 1;
        self.log.write(&MetricsEvent::Nonfinite(NonfiniteLine {
            iteration: it,
            loss: report.loss,
            grad_l1: report.grad_l1,
            consecutive: self.consecutive_bad,
        }))?;
        say(
            &self.bar,
            format!(
                "iteration {it}: non-finite loss or gradient (loss {}, |grad| {}), step skipped",
                report.loss, report.grad_l1
            ),
        );
        if self.consecutive_bad >= self.config.logging.max_nonfinite_steps.max(1) {
            self.bar.abandon();
            return Err(TrainError::Diverged {
                count: self.consecutive_bad,
                iteration: it,
                last_checkpoint: self.last_checkpoint.clone(),
            });
        }
        Ok(())
    }

    /// The training line of the step, when one is due, and the bar.
    fn log_step(&mut self, model: &OpenNerf, step: &Checked) -> Result<(), TrainError> {
        let i = step.done;
        let report = &step.report;
        let every = self.config.logging.log_every.max(1);
        if report.applied && (i.is_multiple_of(every) || i == self.end) {
            let rays_per_second = self.rate.take();
            let wall_seconds = self.clock.wall();
            let grid = model.occupancy().map(|grid| {
                let line = grid_line(grid, &self.skipping);
                self.skipping = ClipStats::default();
                line
            });
            self.log.write(&MetricsEvent::Train(TrainLine {
                iteration: i,
                loss: report.loss,
                rgb_mse: report.rgb_mse,
                psnr: report.psnr(),
                depth: report.depth,
                open: report.open,
                lr: step.lr,
                rays_per_second,
                wall_seconds,
                grid,
            }))?;
            show_step(&self.bar, i, self.end, report, rays_per_second);
        }
        self.bar.set_position(i as u64);
        Ok(())
    }
}
