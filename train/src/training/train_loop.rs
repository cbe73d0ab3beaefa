//! The training loop: one step per iteration, with, around it, the time
//! budget, the schedule's fit, the novel views, the log lines, the
//! periodic evaluations and the checkpoints. Here: the session's setup,
//! the loop itself, the time budget and the schedule's fit, the periodic
//! evaluations and checkpoints, and the two ends (finished or
//! interrupted); [`novel_views`] makes and joins the novel views, and
//! [`steps`] takes each step and accounts for it.

mod novel_views;
mod steps;

use std::borrow::Cow;
use std::path::PathBuf;

use burn::tensor::Device;
use datasets::Scene;
use field_ops::run_dir::{RunDir, Split};
use field_ops::stages::StageLog;
use indicatif::ProgressBar;
use model::{ClipStats, OpenNerf};

use super::budget::ScheduleFit;
use super::console::{Clock, RayRate, describe};
use super::finish::{Trained, finish};
use super::heldout::HeldOut;
use super::live_viewer::LiveViewer;
use super::novel::SessionViews;
use super::session::{RunOutcome, SessionOptions, SessionStart};
use super::snapshot::save_checkpoint;
use super::stepper::Stepper;
use crate::batch::{TrainSampler, feature_space};
use crate::checkpoint::{CheckpointState, list_checkpoints};
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::metrics_log::{EvalLine, MetricsEvent, MetricsLog};
use crate::progress::say;
use field_ops::json::write_json;

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
    /// Novel views are appended to a copy of the scene when they are made.
    scene: Cow<'a, Scene>,
    views: SessionViews,
    /// The optimiser, the sampler and the steps not yet checked.
    stepper: Stepper,
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
    last_checkpoint: Option<PathBuf>,
    /// The web viewer served while training (`--viewer`).
    viewer: Option<LiveViewer>,
    /// The `training` stage is open from the start of the session to its
    /// end; the sampler builds, novel views and final render nest in it.
    stages: StageLog,
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
            let over =
                it >= session.end || (!session.stepper.replaying(it) && session.budget_spent());
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
            scene: s.scene,
            views,
            stepper: Stepper::new(s.optim, sampler, space),
            state: s.state,
            end,
            fit,
            log,
            bar,
            clock,
            rate: RayRate::start(),
            skipping: ClipStats::default(),
            consecutive_bad: 0,
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
                &self.stepper.optim,
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
            &self.stepper.optim,
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
            optim: &self.stepper.optim,
            state: &self.state,
            heldout: &self.heldout,
        };
        let outcome = finish(&trained, &mut self.log, &self.clock, &mut self.stages)?;
        self.stages.end()?;
        Ok(outcome)
    }
}
