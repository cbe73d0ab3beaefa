//! The training loop: a new run or a resumed one, periodic logging,
//! evaluation and checkpoints, the time budget, and the final renders and
//! `summary.json`.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamConfig, ModuleOptimizer};
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use datasets::{Scene, SceneMeta};
use field_ops::run_dir::{RunDir, Split};
use indicatif::{ProgressBar, ProgressStyle};
use model::OpenNerf;
use serde_json::json;

use crate::backend::{BackendKind, peak_memory_bytes, training_device};
use crate::batch::{TrainSampler, feature_space, iteration_seed, to_tensors};
use crate::checkpoint::{
    Checkpoint, CheckpointState, checkpoint_path, list_checkpoints, prune_checkpoints,
};
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::evaluate::{EvalPixels, eval_pixels, evaluate_pixels, evaluate_views};
use crate::metrics::{EvalMetrics, MetricsLog, Summary, read_json, write_json};
use crate::step::{StepRates, train_step};
use field_ops::novel::record::RecordedViews;

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
    /// With a time budget: time the first steps and set the schedule's
    /// length to the iterations that fit the budget (written back to
    /// `config.json`), so that the learning rate decays over the whole
    /// budget instead of the run ending early or being cut mid-schedule.
    pub fit_schedule_to_budget: bool,
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
            fit_schedule_to_budget: false,
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
    if let Some(due) = crate::novel::due_at(&config) {
        if !session.fit_schedule_to_budget && due >= config.schedule.iterations {
            return Err(TrainError::Config(format!(
                "novel views are due at iteration {due}, but the schedule ends at {}: give --novel-after below it",
                config.schedule.iterations
            )));
        }
        field_ops::novel::scene_extractor(scene, &config.novel)?;
    }
    let split = crate::validate::holdout_split(scene.frames.len(), holdout_every)?;
    let run = RunDir::new(out);
    crate::validate::fresh_out_dir(&run.dir)?;
    std::fs::create_dir_all(&run.dir).map_err(|e| TrainError::io(&run.dir, e))?;
    write_json(&run.config(), &config)?;
    write_json(&run.scene(), &crate::data::meta(scene))?;
    write_json(&run.split(), &split)?;
    let _ = std::fs::remove_file(run.metrics());
    let device = training_device(session.backend, session.device_index);
    device.seed(config.seed);
    let model = config
        .model
        .init(&device)
        .with_occupancy(crate::occupancy::initial_grid(&config.occupancy));
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
    train_loop(
        scene, None, &config, &split, &run, model, optim, state, &device, session,
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
    let field_ops::run_dir::RunScene {
        scene,
        novel: added,
    } = field_ops::run_dir::rebuild_scene(&run, &meta)?;
    let n = scene.frames.len();
    if split.train.iter().chain(&split.heldout).any(|&i| i >= n) {
        return Err(TrainError::json(
            run.split(),
            format!("frame index out of range for a scene of {n} frames"),
        ));
    }
    let device = training_device(session.backend, session.device_index);
    let (model, optim) = restore(&config, &ckpt, &path, &device)?;
    if iterations.is_some() {
        write_json(&run.config(), &config)?;
    }
    train_loop(
        &scene, added, &config, &split, &run, model, optim, ckpt.state, &device, session,
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
    let grid = match &ckpt.state.occupancy {
        Some(hex) => Some(crate::occupancy::decode(hex, path)?),
        None => crate::occupancy::initial_grid(&config.occupancy),
    };
    Ok((model.with_occupancy(grid), optim))
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
    let mut state = state.clone();
    state.occupancy = model.occupancy().map(crate::occupancy::encode);
    let ckpt = Checkpoint {
        state,
        model: model_bytes(model)?,
        optimizer,
    };
    let path = checkpoint_path(&run.checkpoints(), ckpt.state.iteration);
    ckpt.write(&path)?;
    if let Some(grid) = model.occupancy() {
        crate::checkpoint::write_atomic(&run.occupancy(), &grid.to_bytes())?;
    }
    prune_checkpoints(&run.checkpoints(), keep)?;
    Ok(path)
}

/// A `metrics.jsonl` evaluation line. Every figure is suffixed with the
/// pixels it was measured on: `_interior` (inside the border margin, what
/// training draws from) or `_whole` (every pixel of the held-out views).
fn eval_line(
    kind: &str,
    iteration: usize,
    interior: &EvalMetrics,
    whole: Option<&EvalMetrics>,
    wall: f64,
) -> serde_json::Value {
    let mut v = json!({
        "event": kind,
        "iteration": iteration,
        "wall_seconds": wall,
    });
    let mut put = |m: &EvalMetrics, suffix: &str| {
        v[format!("psnr_{suffix}")] = json!(m.psnr);
        v[format!("depth_mae_{suffix}")] = json!(m.depth_mae);
        v[format!("feature_cosine_{suffix}")] = json!(m.feature_cosine);
        v[format!("pixels_{suffix}")] = json!(m.pixels);
    };
    put(interior, "interior");
    if let Some(w) = whole {
        put(w, "whole");
    }
    v
}

/// One line of held-out figures for the log.
fn describe(label: &str, m: &EvalMetrics) -> String {
    format!(
        "{label} psnr {:.2} dB{}{}",
        m.psnr,
        m.depth_mae
            .map(|d| format!(", depth mae {d:.3} m"))
            .unwrap_or_default(),
        m.feature_cosine
            .map(|c| format!(", feature cosine {c:.3}"))
            .unwrap_or_default()
    )
}

/// Fits the schedule's length to a time budget from the measured time of
/// the steps (evaluations and checkpoints included, as they happen).
///
/// The first fit comes after a few timed steps; the fit is then repeated
/// every tenth of the planned run from the step time since the last fit, so that a run that slows down (a busier machine, a longer step
/// later in training) still reaches the end of its learning-rate decay
/// inside the budget instead of being cut off half-way.
#[derive(Debug, Clone, Copy)]
struct BudgetFit {
    budget: f64,
    /// `(iteration, elapsed seconds)` when timing started or last fitted.
    start: Option<(usize, f64)>,
    /// Iteration of the next fit.
    next: usize,
}

impl BudgetFit {
    /// Steps before timing starts (the first ones pay for allocation and
    /// warm-up) and steps timed.
    const SKIP: usize = 3;
    const TIMED: usize = 20;
    /// Fraction of the remaining budget planned for, leaving room for the
    /// periodic evaluations and checkpoints the timed steps did not include.
    const SAFETY: f64 = 0.95;
    /// Refits per planned run.
    const REFITS: usize = 10;

    fn new(budget: f64) -> Self {
        Self {
            budget,
            start: None,
            next: Self::SKIP + Self::TIMED,
        }
    }

    /// Called before iteration `it`; returns the (re)fitted number of
    /// iterations when a fit is due and changes the plan.
    fn observe(&mut self, it: usize, elapsed: f64) -> Option<usize> {
        match self.start {
            None if it >= Self::SKIP => {
                self.start = Some((it, elapsed));
                None
            }
            Some((i0, t0)) if it >= self.next && it > i0 => {
                // The pace since the last fit: what the next steps will cost.
                let per_step = (elapsed - t0) / (it - i0) as f64;
                let left = (self.budget - elapsed).max(0.0) * Self::SAFETY;
                let planned = it + (left / per_step.max(1e-9)).floor() as usize;
                self.start = Some((it, elapsed));
                self.next = it + (planned / Self::REFITS).max(Self::TIMED);
                Some(planned)
            }
            _ => None,
        }
    }
}

/// The initial evaluation recorded in `metrics.jsonl` (iteration 0).
fn initial_eval(path: &Path) -> Option<EvalMetrics> {
    let text = std::fs::read_to_string(path).ok()?;
    text.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["event"] == "eval" && v["iteration"] == 0)
        .map(|v| EvalMetrics {
            psnr: v["psnr_interior"].as_f64().unwrap_or(f64::NAN),
            depth_mae: v["depth_mae_interior"].as_f64(),
            feature_cosine: v["feature_cosine_interior"].as_f64(),
            pixels: v["pixels_interior"].as_u64().unwrap_or(0),
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
    use std::io::IsTerminal;
    // A bar only redraws one terminal line: where the output is captured
    // (a log file, CI), periodic plain lines are what is wanted instead.
    if !session.progress || !std::io::stderr().is_terminal() || !std::io::stdout().is_terminal() {
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
    mut added: Option<RecordedViews>,
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
    let mut config = config.clone();
    let stop_at = |iterations: usize| session.stop_at.map_or(iterations, |s| s.min(iterations));
    let mut end = stop_at(config.schedule.iterations);
    let (mut fitted_once, mut reported) = (false, 0usize);
    let mut fit = match session.time_budget {
        Some(budget) if session.fit_schedule_to_budget && state.iteration == 0 => {
            Some(BudgetFit::new(budget))
        }
        _ => None,
    };
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
    let evaluate = |model: &OpenNerf, scene: &Scene| {
        evaluate_pixels(
            &model.valid(),
            scene,
            &pixels,
            log_cfg.render_chunk,
            &inference,
        )
    };
    if state.iteration == 0 {
        let m = evaluate(&model, scene);
        log.write(&eval_line("eval", 0, &m, None, 0.0))?;
    }
    let space = feature_space(scene, device);
    // Novel views are appended to a copy of the scene when they are made.
    let mut scene: Cow<'_, Scene> = Cow::Borrowed(scene);
    let training_frames = |added: Option<&RecordedViews>, it: usize| -> Vec<usize> {
        let mut frames = split.train.clone();
        if let Some(a) = added.filter(|a| it >= a.at) {
            frames.extend(&a.frames);
        }
        frames
    };
    let mut sampler_has_novel = added.as_ref().is_some_and(|a| state.iteration >= a.at);
    let mut sampler = TrainSampler::new(
        &scene,
        &training_frames(added.as_ref(), state.iteration),
        &config.sampler,
        state.seed,
    )?;
    let bar = progress_bar(session, state.iteration, end);
    let mut consecutive_bad = 0usize;
    let mut last_checkpoint: Option<PathBuf> =
        list_checkpoints(&run.checkpoints())?.pop().map(|c| c.1);
    let mut window = (Instant::now(), 0u64);
    let mut skipping = crate::occupancy::ClipStats::default();
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
        if let Some(f) = fit.as_mut()
            && let Some(iterations) = f.observe(it, session_start.elapsed().as_secs_f64())
            && iterations != config.schedule.iterations
        {
            let first = !fitted_once;
            fitted_once = true;
            config.schedule.iterations = iterations;
            end = stop_at(iterations);
            write_json(&run.config(), &config)?;
            bar.set_length(end as u64);
            // The first fit is news; later ones only when the plan moves by
            // more than a few per cent.
            if first || iterations.abs_diff(reported) * 20 > reported {
                reported = iterations;
                say(
                    &bar,
                    format!(
                        "schedule {} to the time budget: {iterations} iterations",
                        if first { "fitted" } else { "refitted" }
                    ),
                );
            }
        }
        if added.is_none()
            && let Some(due) = crate::novel::due_at(&config)
            && it >= due
        {
            say(
                &bar,
                format!(
                    "iteration {it}: adding {} novel views ({})",
                    config.novel.views, config.novel.mode
                ),
            );
            let report = crate::novel::add_views(
                &model.valid(),
                scene.to_mut(),
                &split.train,
                &config,
                run,
                it,
                &inference,
                |done, total| bar.set_message(format!("novel view {done}/{total} rendered")),
            )?;
            log.write(&json!({
                "event": "novel_views",
                "iteration": it,
                "mode": report.added.choice.to_string(),
                "requested": report.requested,
                "added": report.added.frames.len(),
                "seconds": report.seconds,
                "wall_seconds": wall(&session_start),
            }))?;
            say(
                &bar,
                format!(
                    "iteration {it}: {} of {} novel views added in {:.1} s (recorded in {})",
                    report.added.frames.len(),
                    report.requested,
                    report.seconds,
                    run.novel().display()
                ),
            );
            added = Some(report.added);
        }
        if !sampler_has_novel && let Some(a) = added.as_ref().filter(|a| it >= a.at) {
            sampler = TrainSampler::new(
                &scene,
                &training_frames(Some(a), it),
                &config.sampler,
                state.seed,
            )?;
            sampler_has_novel = true;
        }
        let lr = config.schedule.lr(it);
        let rates = StepRates {
            base: lr,
            head: lr * config.optimiser.head_lr_scale,
        };
        let step_start = Instant::now();
        // The stratified jitter draws from the device generator: seeding it
        // per iteration makes a resumed run draw what the uninterrupted one would.
        device.seed(iteration_seed(state.seed ^ 0x6a09_e667_f3bc_c909, it));
        if config.occupancy.update_due(it)
            && let Some(grid) = model.occupancy()
        {
            let mut grid = grid.clone();
            let seed = crate::occupancy::update_seed(state.seed, it);
            crate::occupancy::update_grid(&mut grid, &model.valid(), seed, &inference);
            model = model.with_occupancy(Some(grid));
        }
        let drawn = sampler.batch(&scene, it)?;
        let drawn_rays = drawn.len() as u64;
        let drawn = match model.occupancy() {
            Some(grid) => {
                let (clipped, stats) = crate::occupancy::clip_batch(grid, drawn);
                skipping.add(stats);
                clipped
            }
            None => drawn,
        };
        let batch = to_tensors(&drawn, &space, device);
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
            state.rays_processed += drawn_rays;
            window.1 += drawn_rays;
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
            let mut entry = json!({
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
            });
            if let Some(grid) = model.occupancy() {
                let drawn = skipping.drawn.max(1) as f64;
                entry["occupied_cells"] = json!(grid.occupied_fraction());
                entry["rays_rendered"] = json!(skipping.kept as f64 / drawn);
                entry["ray_length_sampled"] = json!(skipping.span_sum / drawn);
                skipping = crate::occupancy::ClipStats::default();
            }
            log.write(&entry)?;
            let line = format!(
                "loss {:.4} rgb {:.5} open {:.4} depth {:.4} psnr {:.2} {:.0} rays/s",
                report.loss,
                report.rgb_mse,
                report.open,
                report.depth,
                report.psnr(),
                rays_per_second
            );
            // Without a visible bar (--quiet, or stderr not a terminal) the
            // progress goes to the log as plain lines.
            if bar.is_hidden() {
                say(&bar, format!("iteration {i}/{end}: {line}"));
            } else {
                bar.set_message(line);
            }
        }
        bar.set_position(i as u64);
        if log_cfg.eval_every > 0 && i.is_multiple_of(log_cfg.eval_every) && i < end {
            let m = evaluate(&model, &scene);
            log.write(&eval_line("eval", i, &m, None, wall(&session_start)))?;
            say(
                &bar,
                format!(
                    "iteration {i}: {}",
                    describe("held-out interior pixels (sample):", &m)
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
    let (interior, whole) = if session.final_render {
        let m = evaluate_views(
            &valid,
            &scene,
            &heldout,
            config.sampler.border_margin,
            log_cfg.render_chunk,
            &inference,
            &run.renders(),
        )?;
        (m.interior, Some(m.whole))
    } else {
        let m = evaluate_pixels(&valid, &scene, &pixels, log_cfg.render_chunk, &inference);
        (m, None)
    };
    let wall_seconds = wall(&session_start);
    log.write(&eval_line(
        "final",
        state.iteration,
        &interior,
        whole.as_ref(),
        wall_seconds,
    ))?;
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
        wall_seconds,
        rays_per_second: state.rays_processed as f64 / state.train_seconds.max(1e-9),
        peak_memory_bytes: peak_memory_bytes(),
        initial_interior: initial_eval(&run.metrics()),
        skipped_steps: state.skipped_steps,
        backend: session.backend.name().into(),
        heldout_frames: heldout,
    };
    write_json(&run.summary(), &summary)?;
    // The numbers are in metrics.jsonl: a missing font costs the picture only.
    let curve = run.dir.join("training_curve.png");
    let log =
        std::fs::read_to_string(run.metrics()).map_err(|e| TrainError::io(run.metrics(), e))?;
    if let Err(e) = crate::curve::draw(&crate::curve::parse(&log), &curve) {
        eprintln!("warning: {e}");
    }
    Ok(RunOutcome {
        dir: run.dir.clone(),
        summary,
    })
}

#[cfg(test)]
mod budget_tests {
    use super::BudgetFit;

    /// Steps of 0.5 s after a slow first one: the fit skips the first steps,
    /// times 20, and plans 95% of what is left of the budget.
    #[test]
    fn the_schedule_is_fitted_to_the_remaining_budget() {
        let mut fit = BudgetFit::new(100.0);
        let elapsed = |it: usize| if it == 0 { 0.0 } else { 4.0 + 0.5 * it as f64 };
        let mut fitted = None;
        for it in 0..100 {
            if let Some(n) = fit.observe(it, elapsed(it)) {
                fitted = Some((it, n));
                break;
            }
        }
        let (at, n) = fitted.expect("fitted after the timed steps");
        assert_eq!(at, BudgetFit::SKIP + BudgetFit::TIMED);
        // At iteration 23, 15.5 s have passed: 0.95 * 84.5 / 0.5 = 160.55 more.
        assert_eq!(n, 23 + 160);
        // A budget already spent plans no further iteration.
        let mut late = BudgetFit::new(1.0);
        assert_eq!(late.observe(3, 2.0), None);
        assert_eq!(late.observe(23, 12.0), Some(23));
    }

    /// Steps that become twice as slow half-way: the refits shorten the
    /// plan so that the run ends inside the budget, near its fitted end.
    #[test]
    fn a_run_that_slows_down_is_refitted_to_end_inside_the_budget() {
        let budget = 100.0;
        let mut fit = BudgetFit::new(budget);
        let step = |it: usize| if it < 100 { 0.25 } else { 0.5 };
        let (mut t, mut planned, mut refits) = (0.0, usize::MAX, 0);
        let mut it = 0;
        while it < planned && t < budget {
            if let Some(n) = fit.observe(it, t) {
                planned = n;
                refits += 1;
            }
            t += step(it);
            it += 1;
        }
        assert!(refits >= 3, "{refits} fits");
        // The plan was met before the budget ran out...
        assert_eq!(it, planned, "stopped at {it} of {planned} after {t} s");
        assert!(t <= budget);
        // ...and little of the budget is left unused.
        assert!(t > 0.85 * budget, "ended at {t} s");
        // Fitted once at 0.25 s a step, the plan would have been ~380
        // iterations, which take ~140 s at the slower pace.
        assert!(planned < 300, "{planned}");
    }
}
