//! The training loop: one step per iteration, with, around it, the time
//! budget, the schedule's fit, the novel views, the log lines, the
//! periodic evaluations and the checkpoints.

use std::borrow::Cow;
use std::path::PathBuf;
use std::time::Instant;

use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::tensor::Device;
use datasets::Scene;
use field_ops::run_dir::{RunDir, Split};
use field_ops::stages::StageLog;
use indicatif::ProgressBar;
use model::{ClipStats, FeatureSpace, GridUse, OpenNerf};

use super::budget::ScheduleFit;
use super::console::{Clock, RayRate, describe, grid_line, show_step};
use super::finish::{Trained, finish};
use super::guard::{Checked, Kept, Pending, Unchecked, Verdict, checked_until};
use super::heldout::HeldOut;
use super::live_viewer::LiveViewer;
use super::novel::SessionViews;
use super::session::{RunOutcome, SessionOptions};
use super::snapshot::save_checkpoint;
use crate::batch::{TrainSampler, feature_space, iteration_seed, to_tensors};
use crate::checkpoint::{CheckpointState, list_checkpoints};
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::metrics_log::{EvalLine, MetricsEvent, MetricsLog, NonfiniteLine, TrainLine};
use crate::progress::say;
use crate::step::{StepRates, StepRender, train_step_deferred, train_step_regularised};
use field_ops::json::write_json;
use field_ops::novel::record::RecordedViews;

/// Everything a session starts from.
pub(super) struct SessionStart<'a> {
    /// Owned when the caller hands the scene over (adding novel views then
    /// extends it in place instead of copying it first).
    pub scene: Cow<'a, Scene>,
    /// Novel views already made (read back on resume).
    pub added: Option<RecordedViews>,
    pub config: &'a TrainConfig,
    pub split: &'a Split,
    pub run: &'a RunDir,
    pub model: OpenNerf,
    pub optim: ModuleOptimizer,
    pub state: CheckpointState,
    pub device: &'a Device,
    pub session: &'a SessionOptions,
    /// Where the stages' time and peak memory are recorded.
    pub stages: StageLog,
}

/// A session in progress. The model is not held here but passed from step
/// to step, since each step consumes it and returns the next.
pub(super) struct TrainLoop<'a> {
    /// The configuration, whose schedule a time budget may refit.
    config: TrainConfig,
    split: &'a Split,
    run: &'a RunDir,
    session: &'a SessionOptions,
    device: &'a Device,
    inference: Device,
    heldout: HeldOut,
    space: FeatureSpace,
    /// Novel views are appended to a copy of the scene when they are made.
    scene: Cow<'a, Scene>,
    views: SessionViews,
    sampler: TrainSampler,
    optim: ModuleOptimizer,
    state: CheckpointState,
    /// The iteration the session stops at.
    end: usize,
    fit: Option<ScheduleFit>,
    log: MetricsLog,
    bar: ProgressBar,
    clock: Clock,
    rate: RayRate,
    /// What the occupancy grid clipped since the last log line.
    skipping: ClipStats,
    consecutive_bad: usize,
    /// The steps taken since the last check, on the device.
    unchecked: Option<Unchecked>,
    /// Steps before this iteration are checked as they are taken (after a
    /// non-finite one, to the end of its log window).
    checked_until: usize,
    /// Steps before this iteration are taken again whatever the time
    /// budget says (those after going back from a non-finite one).
    replay_to: usize,
    last_checkpoint: Option<PathBuf>,
    /// The web viewer served while training (`--viewer`).
    viewer: Option<LiveViewer>,
    /// The `training` stage is open from the start of the session to its
    /// end; the sampler builds, novel views and final render nest in it.
    stages: StageLog,
}

/// What one step did: checked as it was taken, or left on the device for
/// the next check ([`Unchecked`]).
enum Step {
    Checked(Checked),
    Deferred(Box<Pending>),
}

/// The seed of the device generator (the stratified jitter) at iteration
/// `it`: seeding it per iteration makes a resumed run draw what the
/// uninterrupted one would.
fn jitter_seed(seed: u64, it: usize) -> u64 {
    iteration_seed(seed ^ 0x6a09_e667_f3bc_c909, it)
}

/// The seed of the occupancy grid's update at iteration `it`.
fn grid_update_seed(seed: u64, it: usize) -> u64 {
    iteration_seed(seed ^ 0x0cc0_9a1d, it)
}

impl<'a> TrainLoop<'a> {
    /// Trains from `start` to the end of the schedule (or of the session),
    /// then saves, measures and summarises.
    pub(super) fn train(start: SessionStart<'a>) -> Result<RunOutcome, TrainError> {
        let (mut session, mut model) = Self::new(start)?;
        loop {
            let it = session.state.iteration;
            let stop = session.session.stop.requested();
            // Steps being taken again after a non-finite one are taken
            // whatever the clock says.
            let over = it >= session.end || (it >= session.replay_to && session.budget_spent());
            let views = session.views.due(&session.config, it) || session.views.joins_at(it);
            // Nothing is saved, made or stopped on before the steps since
            // the last check are known to be finite.
            if (stop || over || views) && session.settle(&mut model)? {
                continue;
            }
            if stop {
                return Err(session.interrupt(&model));
            }
            if over {
                break;
            }
            session.refit_schedule(it)?;
            session.add_novel_views_if_due(&model, it)?;
            session.join_novel_views(it)?;
            let (next, step) = session.step(model, it)?;
            model = next;
            if session.record(&mut model, it, step)? {
                continue;
            }
            session.evaluate_and_save(&model)?;
            if let Some(v) = session.viewer.as_mut() {
                v.refresh(&model, session.state.iteration);
            }
        }
        session.finish(&model)
    }

    /// Sets the session up; a new run's untrained field is evaluated first.
    fn new(s: SessionStart<'a>) -> Result<(Self, OpenNerf), TrainError> {
        let mut stages = s.stages;
        stages.begin("training");
        let config = s.config.clone();
        let end = s.session.end(config.schedule.iterations);
        let fit = ScheduleFit::for_session(s.session, s.state.iteration);
        let inference = s.device.clone().without_autodiff();
        let heldout = HeldOut::new(&s.scene, s.split, &config)?;
        let mut log = MetricsLog::open(&s.run.metrics())?;
        let clock = Clock::start(s.state.wall_seconds);
        if s.state.iteration == 0 {
            let m = heldout.sample(&s.model, &s.scene);
            log.write(&MetricsEvent::Eval(EvalLine {
                iteration: 0,
                wall_seconds: 0.0,
                interior: m,
                whole: None,
            }))?;
        }
        let space = feature_space(&s.scene, s.device);
        let views = SessionViews::new(s.added, s.state.iteration);
        let sampler = stages.run("sampler", || {
            TrainSampler::with_novel(
                &s.scene,
                &s.split.train,
                views.novel_frames(s.state.iteration),
                &config.sampler,
                s.state.seed,
            )
        })?;
        let bar = crate::progress::bar(s.session.progress, s.state.iteration, end);
        let last_checkpoint = list_checkpoints(&s.run.checkpoints())?.pop().map(|c| c.1);
        let viewer = match &s.session.viewer {
            Some(settings) => Some(LiveViewer::start(
                settings,
                &s.scene,
                s.split,
                s.run,
                &s.model,
                s.state.iteration,
                &inference,
            )?),
            None => None,
        };
        let session = Self {
            config,
            split: s.split,
            run: s.run,
            session: s.session,
            device: s.device,
            inference,
            heldout,
            space,
            scene: s.scene,
            views,
            sampler,
            optim: s.optim,
            state: s.state,
            end,
            fit,
            log,
            bar,
            clock,
            rate: RayRate::start(),
            skipping: ClipStats::default(),
            consecutive_bad: 0,
            unchecked: None,
            checked_until: 0,
            replay_to: 0,
            last_checkpoint,
            viewer,
            stages,
        };
        Ok((session, s.model))
    }

    /// Whether the session's time budget is spent (and says so).
    fn budget_spent(&self) -> bool {
        match self.session.time_budget {
            Some(budget) if self.clock.elapsed() >= budget => {
                say(
                    &self.bar,
                    format!(
                        "time budget of {budget} s spent at iteration {}",
                        self.state.iteration
                    ),
                );
                true
            }
            _ => false,
        }
    }

    /// Refits the schedule to the time budget when a fit is due, writing
    /// the new length to `config.json`.
    fn refit_schedule(&mut self, it: usize) -> Result<(), TrainError> {
        let elapsed = self.clock.elapsed();
        let Some(refit) = self
            .fit
            .as_mut()
            .and_then(|f| f.observe(it, elapsed, self.config.schedule.iterations))
        else {
            return Ok(());
        };
        self.config.schedule.iterations = refit.iterations;
        self.end = self.session.end(refit.iterations);
        write_json(&self.run.config(), &self.config)?;
        self.bar.set_length(self.end as u64);
        if let Some(message) = refit.announce {
            say(&self.bar, message);
        }
        Ok(())
    }

    /// Makes the novel views when they are due before iteration `it`.
    fn add_novel_views_if_due(&mut self, model: &OpenNerf, it: usize) -> Result<(), TrainError> {
        if !self.views.due(&self.config, it) {
            return Ok(());
        }
        say(&self.bar, super::novel::adding_message(&self.config, it));
        let bar = &self.bar;
        let (scene, stages) = (&mut self.scene, &mut self.stages);
        let report = stages.run("novel views", || {
            super::novel::add_views(
                &model.valid(),
                scene.to_mut(),
                &self.split.train,
                &self.config,
                self.run,
                it,
                &self.inference,
                |done, total| bar.set_message(format!("novel view {done}/{total} rendered")),
            )
        })?;
        let line = super::novel::log_line(&report, it, self.clock.wall());
        self.log.write(&MetricsEvent::NovelViews(line))?;
        say(
            &self.bar,
            super::novel::added_message(&report, self.run, it),
        );
        self.views.added = Some(report.added);
        Ok(())
    }

    /// From the iteration recorded with the novel views on, the sampler
    /// draws from them too.
    fn join_novel_views(&mut self, it: usize) -> Result<(), TrainError> {
        if self.views.join(it) {
            let novel = self.views.novel_frames(it);
            let (scene, config, train) = (&self.scene, &self.config, &self.split.train);
            self.sampler = self.stages.run("sampler", || {
                TrainSampler::with_novel(scene, train, novel, &config.sampler, self.state.seed)
            })?;
        }
        Ok(())
    }

    /// The step of iteration `it`: the grid's update when due, the batch
    /// (rendered behind the grid), the loss and the update.
    fn step(&mut self, model: OpenNerf, it: usize) -> Result<(OpenNerf, Step), TrainError> {
        let mut model = model;
        let lr = self.config.schedule.lr(it);
        let rates = StepRates {
            base: lr,
            head: lr * self.config.optimiser.head_lr_scale,
            pose: lr * self.config.optimiser.pose_lr_scale,
        };
        let step_start = Instant::now();
        self.device.seed(jitter_seed(self.state.seed, it));
        if self.config.occupancy.update_due(it)
            && let Some(grid) = model.occupancy()
        {
            let mut grid = grid.clone();
            let seed = grid_update_seed(self.state.seed, it);
            grid.update_from_field(&model.valid(), seed);
            model = model.with_occupancy(Some(grid));
        }
        let drawn = self.sampler.batch(&self.scene, it)?;
        let rays = drawn.len() as u64;
        let batch = to_tensors(&drawn, &self.space, self.device);
        let grid = GridUse::for_training(&self.config.occupancy, model.occupancy());
        let unseen = super::unseen::patches(
            &self.scene,
            &self.split.train,
            &self.config,
            self.state.seed,
            it,
        );
        let render = StepRender {
            background: self.scene.background,
            grid,
            progress: self.config.schedule.progress(it),
            jitter: true,
        };
        let (losses, unseen) = (&self.config.losses, unseen.as_ref());
        // A step checked as it is taken costs the one read its check would,
        // and nothing to go back to.
        let checked =
            it < self.checked_until || (self.unchecked.is_none() && self.check_due(it + 1));
        let (next, clip, step) = if checked {
            let (next, report) = train_step_regularised(
                model,
                &mut self.optim,
                &batch,
                unseen,
                render,
                losses,
                rates,
            );
            let done = it + 1;
            let step = Step::Checked(Checked {
                done,
                report,
                lr,
                rays,
            });
            (next, report.clip, step)
        } else {
            if self.unchecked.is_none() {
                self.unchecked = Some(Unchecked::new(Kept {
                    model: model.clone(),
                    optim: self.optim.clone(),
                    state: self.state.clone(),
                    skipping: self.skipping,
                    consecutive_bad: self.consecutive_bad,
                }));
            }
            let (next, values) = train_step_deferred(
                model,
                &mut self.optim,
                &batch,
                unseen,
                render,
                losses,
                rates,
            );
            let clip = values.clip;
            let step = Step::Deferred(Box::new(Pending {
                done: it + 1,
                values,
                lr,
                rays,
            }));
            (next, clip, step)
        };
        if let Some(clip) = clip {
            self.skipping.add(clip);
        }
        self.state.train_seconds += step_start.elapsed().as_secs_f64();
        self.state.iteration += 1;
        Ok((next, step))
    }

    /// Counts and logs a checked step; keeps a deferred one for the next
    /// check, which is made when a log line, an evaluation or a checkpoint
    /// is due. Returns whether a check went back to an earlier iteration.
    fn record(&mut self, model: &mut OpenNerf, it: usize, step: Step) -> Result<bool, TrainError> {
        match step {
            Step::Checked(checked) => {
                self.account(it, &checked)?;
                self.log_step(model, &checked)?;
                Ok(false)
            }
            Step::Deferred(pending) => {
                if let Some(u) = self.unchecked.as_mut() {
                    u.steps.push(*pending);
                }
                let back = self.check_due(self.state.iteration) && self.settle(model)?;
                self.bar.set_position(self.state.iteration as u64);
                Ok(back)
            }
        }
    }

    /// Whether the steps are checked once `done` iterations are: a log
    /// line, an evaluation or a checkpoint is due.
    fn check_due(&self, done: usize) -> bool {
        let logging = self.config.logging;
        let due = |every: usize| every > 0 && done.is_multiple_of(every);
        done == self.end
            || due(logging.log_every.max(1))
            || due(logging.eval_every)
            || due(logging.checkpoint_every)
    }

    /// Checks the steps taken since the last check (one read-back): finite
    /// ones are counted and the last logged when due; from a non-finite
    /// one, the model, optimiser and state go back to before the first of
    /// them (returns true), and the steps are taken again, checked.
    fn settle(&mut self, model: &mut OpenNerf) -> Result<bool, TrainError> {
        let Some(unchecked) = self.unchecked.take() else {
            return Ok(false);
        };
        match unchecked.check() {
            Verdict::Finite(steps) => {
                let last = steps.len().saturating_sub(1);
                for (k, checked) in steps.iter().enumerate() {
                    self.account(checked.done - 1, checked)?;
                    if k == last {
                        self.log_step(model, checked)?;
                    }
                }
                Ok(false)
            }
            Verdict::Back { kept, done } => {
                let kept = *kept;
                let seconds = self.state.train_seconds;
                *model = kept.model;
                self.optim = kept.optim;
                self.state = kept.state;
                self.state.train_seconds = seconds;
                self.skipping = kept.skipping;
                self.consecutive_bad = kept.consecutive_bad;
                self.checked_until = checked_until(done, self.config.logging.log_every);
                self.replay_to = done;
                self.bar.set_position(self.state.iteration as u64);
                say(
                    &self.bar,
                    format!(
                        "iteration {}: a non-finite loss or gradient since iteration {}; \
                         taking those steps again, each checked",
                        done - 1,
                        self.state.iteration
                    ),
                );
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

    /// The periodic evaluation on the pixel sample and the periodic
    /// checkpoint, when due (the last iteration has its own).
    fn evaluate_and_save(&mut self, model: &OpenNerf) -> Result<(), TrainError> {
        let i = self.state.iteration;
        let logging = self.config.logging;
        if logging.eval_every > 0 && i.is_multiple_of(logging.eval_every) && i < self.end {
            let m = self.heldout.sample(model, &self.scene);
            self.log.write(&MetricsEvent::Eval(EvalLine {
                iteration: i,
                wall_seconds: self.clock.wall(),
                interior: m,
                whole: None,
            }))?;
            let figures = describe("held-out interior pixels (sample):", &m);
            say(&self.bar, format!("iteration {i}: {figures}"));
        }
        if logging.checkpoint_every > 0
            && i.is_multiple_of(logging.checkpoint_every)
            && i < self.end
        {
            self.state.wall_seconds = self.clock.wall();
            self.last_checkpoint = Some(save_checkpoint(
                self.run,
                model,
                &self.optim,
                &self.state,
                logging.keep_checkpoints,
            )?);
        }
        Ok(())
    }

    /// Stops the session on a signal: a checkpoint at the iteration reached
    /// (the error says where, or why it could not be written).
    fn interrupt(mut self, model: &OpenNerf) -> TrainError {
        self.bar.abandon();
        if let Some(v) = self.viewer.take() {
            v.stop();
        }
        self.state.wall_seconds = self.clock.wall();
        let saved = save_checkpoint(
            self.run,
            model,
            &self.optim,
            &self.state,
            self.config.logging.keep_checkpoints,
        );
        if let Err(e) = self.stages.end() {
            eprintln!("warning: {e}");
        }
        match saved {
            Ok(checkpoint) => TrainError::Interrupted {
                iteration: self.state.iteration,
                checkpoint,
                dir: self.run.dir.clone(),
            },
            Err(e) => e,
        }
    }

    /// Ends the session: the bar, then [`finish`].
    fn finish(mut self, model: &OpenNerf) -> Result<RunOutcome, TrainError> {
        self.bar.finish_and_clear();
        if let Some(v) = self.viewer.take() {
            v.stop();
        }
        self.state.wall_seconds = self.clock.wall();
        let trained = Trained {
            run: self.run,
            session: self.session,
            config: &self.config,
            scene: &self.scene,
            model,
            optim: &self.optim,
            state: &self.state,
            heldout: &self.heldout,
        };
        let outcome = finish(&trained, &mut self.log, &self.clock, &mut self.stages)?;
        self.stages.end()?;
        Ok(outcome)
    }
}
