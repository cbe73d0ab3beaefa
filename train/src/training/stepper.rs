//! Taking the loop's steps: the batch drawn (the next one drawn and
//! uploaded on a second thread while the current step runs), the grid's
//! update when due, and the step itself, checked as it is taken or left on
//! the device for the next check (see [`super::guard`]).

use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::tensor::Device;
use datasets::Scene;
use model::{FeatureSpace, GridUse, OpenNerf};

use super::guard::{Checked, Kept, LoopMark, Pending, Unchecked, Verdict, checked_until};
use crate::batch::{BatchTensors, TrainSampler, iteration_seed, to_tensors};
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::step::{
    StepRates, StepRender, UnseenPatches, train_step_deferred, train_step_regularised,
};

/// What one step did: checked as it was taken, or left on the device for
/// the next check.
pub(super) enum Step {
    Checked(Checked),
    Deferred(Box<Pending>),
}

impl Step {
    /// What the occupancy grid clipped of the step's batch.
    pub(super) fn clip(&self) -> Option<model::ClipStats> {
        match self {
            Step::Checked(c) => c.report.clip,
            Step::Deferred(p) => p.values.clip,
        }
    }
}

/// What a step reads of the session, borrowed for the step.
pub(super) struct StepInputs<'s> {
    pub scene: &'s Scene,
    /// The training frames (indices into `scene.frames`).
    pub train: &'s [usize],
    pub config: &'s TrainConfig,
    pub device: &'s Device,
    /// The run's seed.
    pub seed: u64,
    /// The iteration the session stops at (no batch is drawn ahead of it).
    pub end: usize,
}

/// A batch drawn and on the device, with the unseen patches of its
/// iteration.
struct Drawn {
    batch: BatchTensors,
    /// Rays drawn.
    rays: u64,
    unseen: Option<UnseenPatches>,
}

/// The optimiser, the sampler and the steps not yet checked.
pub(super) struct Stepper {
    pub optim: ModuleOptimizer,
    sampler: TrainSampler,
    space: FeatureSpace,
    /// The batch drawn ahead, for the iteration it names.
    ahead: Option<(usize, Result<Drawn, TrainError>)>,
    unchecked: Option<Unchecked>,
    /// Steps before this iteration are checked as they are taken (after a
    /// non-finite one, to the end of its log window).
    checked_until: usize,
    /// Steps before this iteration are taken again whatever the time
    /// budget says (those after going back from a non-finite one).
    replay_to: usize,
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

/// The batch of iteration `it`, uploaded to the device.
fn draw(
    sampler: &TrainSampler,
    space: &FeatureSpace,
    inputs: &StepInputs<'_>,
    it: usize,
) -> Result<Drawn, TrainError> {
    let drawn = sampler.batch(inputs.scene, it)?;
    let batch = to_tensors(&drawn, space, inputs.device);
    let unseen = super::unseen::patches(inputs.scene, inputs.train, inputs.config, inputs.seed, it);
    Ok(Drawn {
        batch,
        rays: drawn.len() as u64,
        unseen,
    })
}

impl Stepper {
    pub(super) fn new(optim: ModuleOptimizer, sampler: TrainSampler, space: FeatureSpace) -> Self {
        Self {
            optim,
            sampler,
            space,
            ahead: None,
            unchecked: None,
            checked_until: 0,
            replay_to: 0,
        }
    }

    /// The step of iteration `it`: the grid's update when due, the batch
    /// (rendered behind the grid), the loss and the update. It is checked
    /// as it is taken after a non-finite step (to the end of that log
    /// window) and where a check follows it anyway (`check_after`: the
    /// same one read, and nothing to go back to); otherwise it reads
    /// nothing back, and the first such step of a run keeps the model, the
    /// optimiser and `mark()` to go back to.
    pub(super) fn take(
        &mut self,
        inputs: &StepInputs<'_>,
        model: OpenNerf,
        it: usize,
        check_after: bool,
        mark: impl FnOnce() -> LoopMark,
    ) -> Result<(OpenNerf, Step), TrainError> {
        let mut model = model;
        let config = inputs.config;
        let lr = config.schedule.lr(it);
        let rates = StepRates {
            base: lr,
            head: lr * config.optimiser.head_lr_scale,
            pose: lr * config.optimiser.pose_lr_scale,
        };
        inputs.device.seed(jitter_seed(inputs.seed, it));
        if config.occupancy.update_due(it)
            && let Some(grid) = model.occupancy()
        {
            let mut grid = grid.clone();
            grid.update_from_field(&model.valid(), grid_update_seed(inputs.seed, it));
            model = model.with_occupancy(Some(grid));
        }
        let drawn = match self.ahead.take() {
            Some((at, drawn)) if at == it => drawn?,
            _ => draw(&self.sampler, &self.space, inputs, it)?,
        };
        let render = StepRender {
            background: inputs.scene.background,
            grid: GridUse::for_training(&config.occupancy, model.occupancy()),
            progress: config.schedule.progress(it),
            jitter: true,
        };
        let checked = it < self.checked_until || (self.unchecked.is_none() && check_after);
        if !checked && self.unchecked.is_none() {
            self.unchecked = Some(Unchecked::new(Kept {
                model: model.clone(),
                optim: self.optim.clone(),
                mark: mark(),
            }));
        }
        let Self {
            optim,
            sampler,
            space,
            ahead,
            ..
        } = self;
        let next = it + 1;
        let (losses, unseen) = (&config.losses, drawn.unseen.as_ref());
        let (model, step) = std::thread::scope(|s| {
            let worker =
                (next < inputs.end).then(|| s.spawn(|| draw(sampler, space, inputs, next)));
            let taken = if checked {
                let (model, report) = train_step_regularised(
                    model,
                    optim,
                    &drawn.batch,
                    unseen,
                    render,
                    losses,
                    rates,
                );
                let step = Checked {
                    done: next,
                    report,
                    lr,
                    rays: drawn.rays,
                };
                (model, Step::Checked(step))
            } else {
                let (model, values) =
                    train_step_deferred(model, optim, &drawn.batch, unseen, render, losses, rates);
                let step = Pending {
                    done: next,
                    values,
                    lr,
                    rays: drawn.rays,
                };
                (model, Step::Deferred(Box::new(step)))
            };
            if let Some(worker) = worker {
                let drawn = worker
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                *ahead = Some((next, drawn));
            }
            taken
        });
        Ok((model, step))
    }

    /// Keeps a deferred step for the next check.
    pub(super) fn defer(&mut self, pending: Pending) {
        if let Some(u) = self.unchecked.as_mut() {
            u.steps.push(pending);
        }
    }

    /// Reads the steps since the last check (one read-back), if any.
    pub(super) fn check(&mut self) -> Option<Verdict> {
        self.unchecked.take().map(Unchecked::check)
    }

    /// After [`Verdict::Back`]: takes `optim` back, and checks every step
    /// to the end of the log window of the non-finite step that ended at
    /// iteration `done`, taking them whatever the time budget says.
    pub(super) fn went_back(&mut self, optim: ModuleOptimizer, done: usize, log_every: usize) {
        self.optim = optim;
        self.checked_until = checked_until(done, log_every);
        self.replay_to = done;
        self.ahead = None;
    }

    /// Whether iteration `it` takes a step again after going back.
    pub(super) fn replaying(&self, it: usize) -> bool {
        it < self.replay_to
    }

    /// A new sampler (the novel views joined the training frames).
    pub(super) fn set_sampler(&mut self, sampler: TrainSampler) {
        self.sampler = sampler;
        self.ahead = None;
    }

    /// Forgets the batch drawn ahead (the scene changed).
    pub(super) fn forget_ahead(&mut self) {
        self.ahead = None;
    }
}
