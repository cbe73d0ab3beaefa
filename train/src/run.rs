//! The training loop: a new run or a resumed one, periodic logging,
//! evaluation and checkpoints, the time budget, and the final renders and
//! `summary.json`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamConfig, ModuleOptimizer};
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use datasets::{Scene, SceneMeta};
use eval::run::{RunDir, Split};
use indicatif::{ProgressBar, ProgressStyle};
use model::OpenNerf;
use serde_json::json;

use crate::backend::{BackendKind, peak_memory_bytes, training_device};
use crate::batch::{iteration_seed, sample_batch, to_tensors};
use crate::checkpoint::{
    Checkpoint, CheckpointState, checkpoint_path, list_checkpoints, prune_checkpoints,
};
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::evaluate::{EvalPixels, eval_pixels, evaluate_pixels, evaluate_views};
use crate::metrics::{EvalMetrics, MetricsLog, Summary, read_json, split_frames, write_json};
use crate::step::{StepRates, train_step};

/// How a session runs (as opposed to what is trained, which is the config).
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Backend.
    pub backend: BackendKind,
    /// wgpu adapter index.
    pub device_index: Option<usize>,
    /// Stop after this many seconds of this session (then evaluate and save).
    pub time_budget: Option<f64>,
    /// Stop after this iteration even if the schedule is longer.
    pub stop_at: Option<usize>,
    /// Show a progress bar (otherwise plain log lines).
    pub progress: bool,
    /// Render the held-out views to PNG and measure them in full at the end.
    pub final_render: bool,
}

impl Default for SessionOptions {
    fn default() -> Self {
        Self {
            backend: BackendKind::Flex,
            device_index: None,
            time_budget: None,
            stop_at: None,
            progress: false,
            final_render: true,
        }
    }
}

/// What a finished session returns.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// The run directory.
    pub dir: PathBuf,
    /// The summary written to `summary.json`.
    pub summary: Summary,
}

/// Starts a new run on `scene` in `out`: writes `config.json`, `scene.json`
/// and `split.json`, then trains.
pub fn train_new(
    scene: &Scene,
    mut config: TrainConfig,
    holdout_every: usize,
    out: &Path,
    session: &SessionOptions,
) -> Result<RunOutcome, TrainError> {
    config.set_feature_dim(scene.features.as_ref().map_or(0, |f| f.dim()));
    config.validate()?;
    if scene.frames.is_empty() {
        return Err(TrainError::Config(format!(
            "scene {} has no frames",
            scene.name
        )));
    }
    let run = RunDir::new(out);
    std::fs::create_dir_all(&run.dir).map_err(|e| TrainError::io(&run.dir, e))?;
    if !list_checkpoints(&run.checkpoints())?.is_empty() {
        return Err(TrainError::Config(format!(
            "{} already holds a run with checkpoints; use --resume {} or another --out",
            run.dir.display(),
            run.dir.display()
        )));
    }
    let split = split_frames(scene.frames.len(), holdout_every);
    write_json(&run.config(), &config)?;
    write_json(&run.scene(), &crate::data::meta(scene))?;
    write_json(&run.split(), &split)?;
    let _ = std::fs::remove_file(run.metrics());
    let device = training_device(session.backend, session.device_index);
    device.seed(config.seed);
    let model = config.model.init(&device);
    let optim = adam(&config);
    let state = CheckpointState {
        iteration: 0,
        seed: config.seed,
        skipped_steps: 0,
        wall_seconds: 0.0,
        train_seconds: 0.0,
        rays_processed: 0,
    };
    train_loop(
        scene, &config, &split, &run, model, optim, state, &device, session,
    )
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
    let (_, path) =
        list_checkpoints(&run.checkpoints())?
            .pop()
            .ok_or_else(|| TrainError::NoCheckpoint {
                path: dir.to_path_buf(),
            })?;
    let ckpt = Checkpoint::read(&path)?;
    if let Some(n) = iterations {
        config.schedule.iterations = n;
        write_json(&run.config(), &config)?;
    }
    config.validate()?;
    let scene = crate::data::load(&meta.source)?;
    let n = scene.frames.len();
    if split.train.iter().chain(&split.heldout).any(|&i| i >= n) {
        return Err(TrainError::json(
            run.split(),
            format!("frame index out of range for a scene of {n} frames"),
        ));
    }
    let device = training_device(session.backend, session.device_index);
    let (model, optim) = restore(&config, &ckpt, &path, &device)?;
    train_loop(
        &scene, &config, &split, &run, model, optim, ckpt.state, &device, session,
    )
}

fn adam(config: &TrainConfig) -> ModuleOptimizer {
    AdamConfig::new()
        .with_beta_1(config.optimiser.beta_1)
        .with_beta_2(config.optimiser.beta_2)
        .with_epsilon(config.optimiser.epsilon)
        .init()
}

/// Model and optimiser from a checkpoint; any mismatch is reported against
/// the checkpoint file.
pub fn restore(
    config: &TrainConfig,
    ckpt: &Checkpoint,
    path: &Path,
    device: &Device,
) -> Result<(OpenNerf, ModuleOptimizer), TrainError> {
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(ckpt.model.clone()))
        .map_err(|e| TrainError::checkpoint(path, format!("model record: {e}")))?;
    let model = config
        .model
        .init(device)
        .try_load_record(record)
        .map_err(|e| {
            TrainError::checkpoint(path, format!("model does not match config.json: {e}"))
        })?;
    let optim = adam(config)
        .from_bytes(Bytes::from_bytes_vec(ckpt.optimizer.clone()))
        .map_err(|e| TrainError::checkpoint(path, format!("optimiser record: {e}")))?;
    Ok((model, optim))
}

/// Serialised model weights (burnpack).
pub fn model_bytes(model: &OpenNerf) -> Result<Vec<u8>, TrainError> {
    let bytes = model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| TrainError::Device(format!("cannot serialise the model: {e}")))?;
    Ok(bytes.to_vec())
}

fn save_checkpoint(
    run: &RunDir,
    model: &OpenNerf,
    optim: &ModuleOptimizer,
    state: &CheckpointState,
    keep: usize,
) -> Result<PathBuf, TrainError> {
    let optimizer = optim
        .into_bytes()
        .map_err(|e| TrainError::Device(format!("cannot serialise the optimiser: {e}")))?
        .to_vec();
    let ckpt = Checkpoint {
        state: state.clone(),
        model: model_bytes(model)?,
        optimizer,
    };
    let path = checkpoint_path(&run.checkpoints(), state.iteration);
    ckpt.write(&path)?;
    prune_checkpoints(&run.checkpoints(), keep)?;
    Ok(path)
}

fn eval_line(kind: &str, iteration: usize, m: &EvalMetrics, wall: f64) -> serde_json::Value {
    json!({
        "event": kind,
        "iteration": iteration,
        "psnr": m.psnr,
        "depth_mae": m.depth_mae,
        "feature_cosine": m.feature_cosine,
        "pixels": m.pixels,
        "wall_seconds": wall,
    })
}

/// The initial evaluation recorded in `metrics.jsonl` (iteration 0).
fn initial_eval(path: &Path) -> Option<EvalMetrics> {
    let text = std::fs::read_to_string(path).ok()?;
    text.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["event"] == "eval" && v["iteration"] == 0)
        .map(|v| EvalMetrics {
            psnr: v["psnr"].as_f64().unwrap_or(f64::NAN),
            depth_mae: v["depth_mae"].as_f64(),
            feature_cosine: v["feature_cosine"].as_f64(),
            pixels: v["pixels"].as_u64().unwrap_or(0),
        })
}

/// Prints above the progress bar, or to stderr when there is none.
fn say(bar: &ProgressBar, message: String) {
    if bar.is_hidden() {
        eprintln!("{message}");
    } else {
        bar.println(message);
    }
}

fn progress_bar(session: &SessionOptions, start: usize, end: usize) -> ProgressBar {
    if !session.progress {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(end as u64);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_position(start as u64);
    bar
}

#[allow(clippy::too_many_arguments)]
fn train_loop(
    scene: &Scene,
    config: &TrainConfig,
    split: &Split,
    run: &RunDir,
    mut model: OpenNerf,
    mut optim: ModuleOptimizer,
    mut state: CheckpointState,
    device: &Device,
    session: &SessionOptions,
) -> Result<RunOutcome, TrainError> {
    let log_cfg = config.logging;
    let end = session.stop_at.map_or(config.schedule.iterations, |s| {
        s.min(config.schedule.iterations)
    });
    let heldout: Vec<usize> = if split.heldout.is_empty() {
        split.train.clone()
    } else {
        split.heldout.clone()
    };
    let pixels: EvalPixels = eval_pixels(
        scene,
        &heldout,
        log_cfg.eval_pixels,
        config.sampler.border_margin,
        config.sampler.min_near,
        config.seed,
    )?;
    let inference = device.clone().without_autodiff();
    let mut log = MetricsLog::open(&run.metrics())?;
    let session_start = Instant::now();
    let wall_before = state.wall_seconds;
    let wall = |start: &Instant| wall_before + start.elapsed().as_secs_f64();
    let evaluate = |model: &OpenNerf| {
        evaluate_pixels(
            &model.valid(),
            scene,
            &pixels,
            log_cfg.render_chunk,
            &inference,
        )
    };
    if state.iteration == 0 {
        let m = evaluate(&model);
        log.write(&eval_line("eval", 0, &m, 0.0))?;
    }
    let bar = progress_bar(session, state.iteration, end);
    let mut consecutive_bad = 0usize;
    let mut last_checkpoint: Option<PathBuf> =
        list_checkpoints(&run.checkpoints())?.pop().map(|c| c.1);
    let mut window = (Instant::now(), 0u64);
    while state.iteration < end {
        if let Some(budget) = session.time_budget
            && session_start.elapsed().as_secs_f64() >= budget
        {
            say(
                &bar,
                format!(
                    "time budget of {budget} s spent at iteration {}",
                    state.iteration
                ),
            );
            break;
        }
        let it = state.iteration;
        let lr = config.schedule.lr(it);
        let rates = StepRates {
            base: lr,
            head: lr * config.optimiser.head_lr_scale,
        };
        let step_start = Instant::now();
        // The stratified jitter draws from the device generator: seeding it
        // per iteration makes a resumed run draw what the uninterrupted one would.
        device.seed(iteration_seed(state.seed ^ 0x6a09_e667_f3bc_c909, it));
        let batch = to_tensors(
            &sample_batch(scene, &split.train, &config.sampler, state.seed, it)?,
            device,
        );
        let (next, report) = train_step(
            model,
            &mut optim,
            &batch,
            scene.background,
            &config.losses,
            rates,
        );
        model = next;
        state.train_seconds += step_start.elapsed().as_secs_f64();
        state.iteration += 1;
        if report.applied {
            consecutive_bad = 0;
            state.rays_processed += batch.rays.len() as u64;
            window.1 += batch.rays.len() as u64;
        } else {
            consecutive_bad += 1;
            state.skipped_steps += 1;
            log.write(&json!({
                "event": "nonfinite",
                "iteration": it,
                "loss": format!("{}", report.loss),
                "grad_l1": format!("{}", report.grad_l1),
                "consecutive": consecutive_bad,
            }))?;
            say(
                &bar,
                format!(
                    "iteration {it}: non-finite loss or gradient (loss {}, |grad| {}), step skipped",
                    report.loss, report.grad_l1
                ),
            );
            if consecutive_bad >= log_cfg.max_nonfinite_steps.max(1) {
                bar.abandon();
                return Err(TrainError::Diverged {
                    count: consecutive_bad,
                    iteration: it,
                    last_checkpoint,
                });
            }
        }
        let i = state.iteration;
        if report.applied && (i.is_multiple_of(log_cfg.log_every.max(1)) || i == end) {
            let secs = window.0.elapsed().as_secs_f64().max(1e-9);
            let rays_per_second = window.1 as f64 / secs;
            window = (Instant::now(), 0);
            log.write(&json!({
                "event": "train",
                "iteration": i,
                "loss": report.loss,
                "rgb_mse": report.rgb_mse,
                "psnr": report.psnr(),
                "depth": report.depth,
                "open": report.open,
                "lr": lr,
                "rays_per_second": rays_per_second,
                "wall_seconds": wall(&session_start),
            }))?;
            bar.set_message(format!(
                "loss {:.4} rgb {:.5} open {:.4} depth {:.4} psnr {:.2} {:.0} rays/s",
                report.loss,
                report.rgb_mse,
                report.open,
                report.depth,
                report.psnr(),
                rays_per_second
            ));
        }
        bar.set_position(i as u64);
        if log_cfg.eval_every > 0 && i.is_multiple_of(log_cfg.eval_every) && i < end {
            let m = evaluate(&model);
            log.write(&eval_line("eval", i, &m, wall(&session_start)))?;
            say(
                &bar,
                format!(
                    "iteration {i}: held-out psnr {:.2} dB{}{}",
                    m.psnr,
                    m.depth_mae
                        .map(|d| format!(", depth mae {d:.3} m"))
                        .unwrap_or_default(),
                    m.feature_cosine
                        .map(|c| format!(", feature cosine {c:.3}"))
                        .unwrap_or_default()
                ),
            );
        }
        if log_cfg.checkpoint_every > 0 && i.is_multiple_of(log_cfg.checkpoint_every) && i < end {
            state.wall_seconds = wall(&session_start);
            last_checkpoint = Some(save_checkpoint(
                run,
                &model,
                &optim,
                &state,
                log_cfg.keep_checkpoints,
            )?);
        }
    }
    bar.finish_and_clear();
    state.wall_seconds = wall(&session_start);
    save_checkpoint(run, &model, &optim, &state, log_cfg.keep_checkpoints)?;
    crate::checkpoint::write_atomic(&run.weights(), &model_bytes(&model)?)?;
    let valid = model.valid();
    let final_metrics = if session.final_render {
        evaluate_views(
            &valid,
            scene,
            &heldout,
            log_cfg.render_chunk,
            &inference,
            &run.renders(),
        )?
    } else {
        evaluate_pixels(&valid, scene, &pixels, log_cfg.render_chunk, &inference)
    };
    let wall_seconds = wall(&session_start);
    log.write(&eval_line(
        "final",
        state.iteration,
        &final_metrics,
        wall_seconds,
    ))?;
    let initial = initial_eval(&run.metrics());
    let summary = Summary {
        iterations: state.iteration,
        heldout_psnr: final_metrics.psnr,
        heldout_depth_mae: final_metrics.depth_mae,
        heldout_feature_cosine: final_metrics.feature_cosine,
        wall_seconds,
        rays_per_second: state.rays_processed as f64 / state.train_seconds.max(1e-9),
        peak_memory_bytes: peak_memory_bytes(),
        initial_psnr: initial.map(|m| m.psnr),
        initial_feature_cosine: initial.and_then(|m| m.feature_cosine),
        skipped_steps: state.skipped_steps,
        backend: session.backend.name().into(),
        heldout_frames: heldout,
    };
    write_json(&run.summary(), &summary)?;
    Ok(RunOutcome {
        dir: run.dir.clone(),
        summary,
    })
}
