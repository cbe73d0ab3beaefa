//! The end of a session: the last checkpoint and the weights, the final
//! evaluation, `summary.json` and the training-curve picture.

use burn::optim::ModuleOptimizer;
use datasets::Scene;
use field_ops::run_dir::RunDir;
use model::OpenNerf;

use super::console::{Clock, describe};
use super::heldout::HeldOut;
use super::session::{RunOutcome, SessionOptions};
use super::snapshot::{model_bytes, save_checkpoint};
use crate::backend::peak_memory_bytes;
use crate::checkpoint::CheckpointState;
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::metrics_log::{EvalLine, MetricsEvent, MetricsLog, initial_eval};
use crate::summary::Summary;
use field_ops::json::write_json;
use field_ops::stages::StageLog;

/// A session whose last step is done.
pub(super) struct Trained<'a> {
    pub run: &'a RunDir,
    pub session: &'a SessionOptions,
    pub config: &'a TrainConfig,
    pub scene: &'a Scene,
    pub model: &'a OpenNerf,
    pub optim: &'a ModuleOptimizer,
    pub state: &'a CheckpointState,
    pub heldout: &'a HeldOut,
}

/// Saves, measures and summarises the session `t`.
pub(super) fn finish(
    t: &Trained<'_>,
    log: &mut MetricsLog,
    clock: &Clock,
    stages: &mut StageLog,
) -> Result<RunOutcome, TrainError> {
    let (run, state) = (t.run, t.state);
    save_checkpoint(
        run,
        t.model,
        t.optim,
        state,
        t.config.logging.keep_checkpoints,
    )?;
    field_ops::files::write_atomic(&run.weights(), &model_bytes(t.model)?)?;
    let last = if t.session.final_render {
        stages.run("final render", || {
            t.heldout.last(t.model, t.scene, true, &run.renders())
        })?
    } else {
        t.heldout.last(t.model, t.scene, false, &run.renders())?
    };
    let (interior, whole) = (last.interior, last.whole);
    let wall_seconds = clock.wall();
    log.write(&MetricsEvent::Final(EvalLine {
        iteration: state.iteration,
        wall_seconds,
        interior,
        whole,
    }))?;
    eprintln!(
        "{}",
        describe("held-out views, interior pixels:", &interior)
    );
    if let Some(w) = &whole {
        eprintln!("{}", describe("held-out views, every pixel:", w));
    }
    let summary = Summary {
        iterations: state.iteration,
        heldout_interior: interior,
        heldout_whole: whole,
        heldout_views: last.views,
        wall_seconds,
        rays_per_second: state.rays_processed as f64 / state.train_seconds.max(1e-9),
        render_rays_per_second: Some(last.rays_per_second),
        peak_memory_bytes: peak_memory_bytes(),
        initial_interior: initial_eval(&run.metrics()),
        skipped_steps: state.skipped_steps,
        backend: t.session.backend.name().into(),
        heldout_frames: t.heldout.frames.clone(),
    };
    write_json(&run.summary(), &summary)?;
    // The numbers are in metrics.jsonl: a missing font costs the picture only.
    let curve = run.dir.join("training_curve.png");
    let events = crate::metrics_log::read(&run.metrics())?;
    if let Err(e) = crate::curve::draw(&crate::curve::from_events(&events), &curve) {
        eprintln!("warning: {e}");
    }
    Ok(RunOutcome {
        dir: run.dir.clone(),
        summary,
    })
}
