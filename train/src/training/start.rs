//! The start of a session: a new run (its directory, configuration, split
//! and untrained field) or a resumed one (its newest intact checkpoint).

use std::borrow::Cow;
use std::path::Path;

use datasets::{Scene, SceneMeta};
use field_ops::run_dir::{RunDir, Split};
use field_ops::stages::{STAGES_FILE, StageLog};

use super::session::{RunOutcome, SessionOptions, SessionStart};
use super::snapshot::{adam, restore};
use super::train_loop::TrainLoop;
use crate::backend::training_device;
use crate::checkpoint::{CheckpointState, list_checkpoints};
use crate::config::TrainConfig;
use crate::error::TrainError;
use field_ops::json::{read_json, write_json};

/// Starts a new run on `scene` in `out`: writes `config.json`, `scene.json`
/// and `split.json`, then trains.
pub fn train_new(
    scene: &Scene,
    config: TrainConfig,
    holdout_every: usize,
    out: &Path,
    session: &SessionOptions,
) -> Result<RunOutcome, TrainError> {
    let stages = StageLog::pending();
    train_new_with_stages(
        Cow::Borrowed(scene),
        config,
        holdout_every,
        out,
        session,
        stages,
    )
}

/// [`train_new`] with the stages timed so far (the scene's build, made
/// before the run directory exists): they and the session's stages go to
/// the run's `stages.json`. A scene handed over (`Cow::Owned`) is extended
/// in place when novel views are added; a borrowed one is copied first.
pub fn train_new_with_stages(
    scene: Cow<'_, Scene>,
    mut config: TrainConfig,
    holdout_every: usize,
    out: &Path,
    session: &SessionOptions,
    mut stages: StageLog,
) -> Result<RunOutcome, TrainError> {
    config.set_feature_dim(scene.features.as_ref().map_or(0, |f| f.dim()));
    config.validate()?;
    if scene.frames.is_empty() {
        return Err(TrainError::Config(format!(
            "scene {} has no frames",
            scene.name
        )));
    }
    if let Some(due) = super::novel::due_at(&config) {
        if !session.fit_schedule_to_budget && due >= config.schedule.iterations {
            return Err(TrainError::Config(format!(
                "novel views are due at iteration {due}, but the schedule ends at {}: give --novel-after below it",
                config.schedule.iterations
            )));
        }
        field_ops::novel::check_extractor(&scene, &config.novel)?;
    }
    let split = crate::validate::holdout_split(scene.frames.len(), holdout_every)?;
    let run = RunDir::new(out);
    crate::validate::fresh_out_dir(&run.dir)?;
    std::fs::create_dir_all(&run.dir).map_err(|e| TrainError::io(&run.dir, e))?;
    write_json(&run.config(), &config)?;
    write_json(&run.scene(), &crate::data::meta(&scene))?;
    if let Some(w) = &scene.world {
        print_world_frame(w, &run.scene());
    }
    write_json(&run.split(), &split)?;
    stages.attach(run.dir.join(STAGES_FILE))?;
    let _ = std::fs::remove_file(run.metrics());
    let device = session_device(session);
    device.seed(config.seed);
    let model = config
        .model
        .init(&device)
        .with_occupancy(config.occupancy.initial_grid());
    let optim = adam(&config);
    let state = CheckpointState {
        iteration: 0,
        seed: config.seed,
        skipped_steps: 0,
        wall_seconds: 0.0,
        train_seconds: 0.0,
        rays_processed: 0,
        occupancy: None,
    };
    TrainLoop::train(SessionStart {
        scene,
        added: None,
        config: &config,
        split: &split,
        run: &run,
        model,
        optim,
        state,
        device: &device,
        session,
        stages,
    })
}

/// Tells the user how the scene was moved out of the capture's own frame
/// and where that transform is kept.
fn print_world_frame(w: &datasets::WorldFrame, scene_json: &Path) {
    let m = w.to_scene.to_matrix();
    let row = |r: &[f64; 4]| format!("[{:>9.5} {:>9.5} {:>9.5} {:>9.5}]", r[0], r[1], r[2], r[3]);
    if !w.fitted_to.is_empty() {
        eprintln!("scene frame: {}", w.fitted_to);
    }
    eprintln!(
        "scene frame = {} frame mapped by scale {:.6} (p_scene = s R p_{} + t):\n  {}\n  {}\n  {}\n\
         (stored in {} under \"world\"; eval writes outputs in the {} frame with --frame {})",
        w.name,
        w.to_scene.scale,
        w.name,
        row(&m[0]),
        row(&m[1]),
        row(&m[2]),
        scene_json.display(),
        w.name,
        w.name
    );
}

/// Continues the run in `dir` from its newest checkpoint. `iterations`
/// replaces the schedule's length (the default keeps it, so the run ends
/// exactly where an uninterrupted one would).
pub fn resume(
    dir: &Path,
    iterations: Option<usize>,
    session: &SessionOptions,
) -> Result<RunOutcome, TrainError> {
    let run = RunDir::new(dir);
    let mut config: TrainConfig = read_json(&run.config())?;
    let meta: SceneMeta = read_json(&run.scene())?;
    let split: Split = read_json(&run.split())?;
    if list_checkpoints(&run.checkpoints())?.is_empty() {
        return Err(TrainError::NoCheckpoint {
            path: dir.to_path_buf(),
        });
    }
    let (ckpt, path, damaged) = crate::checkpoint::newest_intact(&run.checkpoints())?;
    for e in &damaged {
        eprintln!(
            "warning: {e}; resuming from the older {} (iteration {}), the damaged file is kept as *.damaged",
            path.display(),
            ckpt.state.iteration
        );
    }
    crate::checkpoint::remove_stale_temp_files(&run.dir)?;
    crate::checkpoint::remove_stale_temp_files(&run.checkpoints())?;
    if let Some(n) = iterations {
        crate::validate::resume_iterations(n, ckpt.state.iteration, dir)?;
        config.schedule.iterations = n;
    }
    // config.json is rewritten only once everything it describes checks out.
    config.validate()?;
    let mut stages = StageLog::for_run(&run.dir);
    let field_ops::run_dir::RunScene {
        scene,
        novel: added,
    } = stages.run("scene", || field_ops::run_dir::rebuild_scene(&run, &meta))?;
    let n = scene.frames.len();
    if split.train.iter().chain(&split.heldout).any(|&i| i >= n) {
        return Err(TrainError::json(
            run.split(),
            format!("frame index out of range for a scene of {n} frames"),
        ));
    }
    let device = session_device(session);
    let (model, optim) = restore(&config, &ckpt, &path, &device)?;
    if iterations.is_some() {
        write_json(&run.config(), &config)?;
    }
    TrainLoop::train(SessionStart {
        scene: Cow::Owned(scene),
        added,
        config: &config,
        split: &split,
        run: &run,
        model,
        optim,
        state: ckpt.state,
        device: &device,
        session,
        stages,
    })
}

/// The session's training device; on wgpu, says how the backend runs
/// (fusion, where compiled kernels are kept).
fn session_device(session: &SessionOptions) -> burn::tensor::Device {
    let device = training_device(session.backend, session.device_index);
    if session.backend == crate::backend::BackendKind::Wgpu {
        eprintln!("{}", field_ops::backend::wgpu_settings());
    }
    device
}
