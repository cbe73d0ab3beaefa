//! Training of OpenNeRF fields: configuration, learning-rate schedule, ray
//! batches, the one training step shared by every backend, checkpoints,
//! held-out evaluation and the training loop that writes a run directory.
//!
//! A run directory holds `config.json` (this crate's [`config::TrainConfig`];
//! its `"model"` key is the field's configuration), `model.bpk` (weights),
//! `scene.json`, `split.json`, `metrics.jsonl`, `summary.json`, `renders/`
//! and `checkpoints/`.
#![warn(missing_docs)]

pub mod accuracy;
pub mod appearance;
pub mod backend;
pub mod batch;
pub mod capture_defaults;
pub mod checkpoint;
// Flag help is written for `--help`, where `<out>` names a placeholder,
// not an HTML tag.
#[allow(rustdoc::invalid_html_tags)]
pub mod cli;
pub mod config;
pub mod curve;
pub mod data;
pub mod depth_choice;
pub mod error;
pub mod evaluate;
pub mod field_choice;
pub mod hash_choice;
pub mod interrupt;
pub mod loss_config;
pub mod metrics_log;
pub mod occupancy;
pub mod pose_choice;
pub mod preset;
pub mod progress;
pub mod report;
pub mod schedule;
pub mod step;
pub mod step_report;
pub mod summary;
pub mod training;
pub mod validate;
pub mod view_eval;
pub mod vlm;

pub use backend::BackendKind;
pub use config::TrainConfig;
pub use error::TrainError;
pub use training::{RunOutcome, SessionOptions, resume, train_new, train_new_with_stages};

use std::path::PathBuf;

/// Runs the command line: a new run, or `--resume`. Returns the outcome
/// (the binary prints where the results are). Raising `stop` ends the
/// training before its next step with a checkpoint
/// ([`TrainError::Interrupted`]).
pub fn run_cli(cli: &cli::Cli, stop: &interrupt::StopFlag) -> Result<RunOutcome, TrainError> {
    validate::cli(cli)?;
    let session = SessionOptions {
        backend: cli.compute.backend,
        device_index: cli.compute.device,
        time_budget: cli.time_budget,
        stop_at: cli.stop_at,
        progress: !cli.quiet,
        final_render: !cli.no_final_render,
        fit_schedule_to_budget: cli.time_budget.is_some() && cli.iters.is_none(),
        viewer: cli.viewer.then(|| training::ViewerSettings {
            host: cli.viewer_host.clone(),
            port: cli.viewer_port,
            every: cli.viewer_every,
        }),
        stop: stop.clone(),
    };
    if let Some(dir) = &cli.resume {
        return resume(dir, cli.iters, &session);
    }
    if let Some(path) = &cli.config {
        validate::config_keys(path, &TrainConfig::default_run(0))?;
    }
    // With --vlm, the scene's own maps (if any) are replaced and --pca
    // applies to the model's maps.
    let source = data::source_from_cli(&cli::Cli {
        pca: if cli.vlm.is_some() { None } else { cli.pca },
        ..cli.clone()
    })?;
    let out = cli.out.clone().unwrap_or_else(|| {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        PathBuf::from("runs").join(format!("{}-{secs}", data::run_name(&source)))
    });
    eprintln!("loading scene ({})", data::run_name(&source));
    // The run directory does not exist yet: the record waits in the log.
    let mut stages = field_ops::stages::StageLog::pending();
    stages.begin("scene");
    let scene = match &cli.vlm {
        Some(model) => vlm::prepare(
            &source,
            &vlm::VlmRequest {
                model: model.clone(),
                options: clip::DenseOptions {
                    variant: cli.dense.unwrap_or(clip::DenseVariant::Naclip),
                    short_side: cli.short_side,
                    ..clip::DenseOptions::default()
                },
                features: cli
                    .features_out
                    .clone()
                    .unwrap_or_else(|| out.join("features")),
                pca: cli.pca.unwrap_or(datasets::features::PcaSetting::Auto),
                backend: cli.compute.backend,
                device_index: cli.compute.device,
            },
        )?,
        None => data::load(&source)?,
    };
    stages.end()?;
    if scene.features.is_none() {
        eprintln!("{}", report::NO_FEATURES_WARNING);
    }
    let dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let mut base = TrainConfig::default_run(dim);
    let choice = field_choice::choose(cli.field, cli.sampler, &scene);
    eprintln!("{}", choice.message());
    let sampling = capture_defaults::for_scene(&scene).filter(|_| cli.preset.is_none());
    sampling.inspect(|d| d.apply(&mut base));
    if let Some(p) = cli.preset {
        apply_preset(p, &mut base, &scene, !choice.unbounded);
    }
    let mut config = match &cli.config {
        Some(path) => TrainConfig::from_file(path, &base)?,
        None => base,
    };
    config.apply(&overrides(cli));
    // Said only where the file and the flags keep what the default chose.
    sampling
        .filter(|d| d.kept_by(&config))
        .inspect(|d| eprintln!("{}", d.message()));
    apply_novel_and_grid_flags(cli, &mut config);
    depth_choice::apply(cli.sparse_depth, &scene, &mut config)?;
    let grid = config.occupancy.enabled;
    field_choice::apply(&choice, &mut config.model, grid, &scene)?;
    field_choice::ray_start(&config.model).inspect(|m| eprintln!("{m}"));
    choose_appearance_and_check(cli, &mut config, &scene)?;
    eprintln!(
        "scene {}: {} frames, features: {}; training {} iterations on {} into {}",
        scene.name,
        scene.frames.len(),
        scene
            .features
            .as_ref()
            .map_or("none".to_string(), |f| format!("{} channels", f.dim())),
        config.schedule.iterations,
        cli.compute.backend,
        out.display()
    );
    train_new_with_stages(
        std::borrow::Cow::Owned(scene),
        config,
        cli.holdout_every,
        &out,
        &session,
        stages,
    )
}

/// Chooses the appearance model (printing the choice), then checks the
/// whole configuration before anything is written, so that a bad value
/// from a `--config` file is named with the file.
/// The flags that override single keys of the configuration.
fn overrides(cli: &cli::Cli) -> config::Overrides {
    config::Overrides {
        iters: cli.iters,
        rays: cli.rays,
        samples: cli.samples,
        width: cli.width,
        depth: cli.depth,
        lambda_open: cli.lambda_open,
        lambda_depth: cli.lambda_depth,
        lr: cli.lr,
        unseen_depth: cli.unseen_depth,
        seed: cli.seed,
        log_every: cli.log_every.map(|n| n as usize),
    }
}

fn choose_appearance_and_check(
    cli: &cli::Cli,
    config: &mut TrainConfig,
    scene: &datasets::Scene,
) -> Result<(), TrainError> {
    let appearance = appearance::choose(cli.appearance, &config.model, scene);
    eprintln!("{}", appearance.message());
    appearance::apply(&appearance, &mut config.model, scene);
    let pose = pose_choice::choose(cli.pose_refine, &config.model);
    eprintln!("{}", pose.message());
    pose_choice::apply(&pose, &mut config.model, scene);
    let hash = hash_choice::choose(cli.hash_grid, &config.model, scene);
    hash_choice::apply(&hash, &mut config.model);
    eprintln!("{}", hash.message(&config.model));
    match (config.validate(), &cli.config) {
        (Err(TrainError::Config(msg)), Some(path)) => Err(TrainError::Config(format!(
            "{msg} (the configuration of {}, with the flags laid over it)",
            path.display()
        ))),
        _ => Ok(()),
    }
}

/// Lays preset `p` over `base` with the settings for `scene`'s kind (and
/// its occupancy grid when `grid`), and says what it set.
fn apply_preset(p: preset::Preset, base: &mut TrainConfig, scene: &datasets::Scene, grid: bool) {
    let centres = scene.frames.iter().map(|f| f.camera.pose.center());
    let count = preset::CameraCount::of(&scene.scene_box, centres);
    let kind = count.kind();
    let s = p.apply(base, kind, grid);
    eprintln!(
        "preset {} with the {} settings ({} of {} cameras inside the scene box): \
         {} samples per ray and level, {} rays a batch, {} iterations{}",
        p.name(),
        kind.name(),
        count.inside,
        count.all,
        s.samples,
        s.rays,
        s.iterations,
        if grid {
            ""
        } else {
            ", no occupancy grid (the field is unbounded)"
        },
    );
}

/// Lays the novel-view, occupancy-grid and head top-k flags over the configuration.
fn apply_novel_and_grid_flags(cli: &cli::Cli, config: &mut TrainConfig) {
    if cli.occupancy_grid {
        config.occupancy.enabled = true;
    }
    if let Some(r) = cli.grid_resolution {
        config.occupancy.resolution = r;
    }
    let grid = &mut config.occupancy;
    let flags = [
        (cli.grid_early_samples, &mut grid.early_samples),
        (cli.grid_early_updates, &mut grid.early_updates),
        (cli.grid_dilation, &mut grid.dilation),
        (cli.grid_keep_dropped, &mut grid.keep_dropped_updates),
    ];
    for (flag, field) in flags {
        if let Some(v) = flag {
            *field = v;
        }
    }
    if let Some(k) = cli.head_top_k {
        config.model.head_top_k = (k > 0).then_some(k);
    }
    let novel = &mut config.novel;
    if let Some(n) = cli.novel_views {
        novel.views = n;
    }
    if let Some(a) = cli.novel_after {
        novel.after = Some(a);
    }
    if let Some(m) = cli.novel_views_mode {
        novel.mode = m;
    }
    if let Some(w) = cli.novel_depth_weight {
        novel.depth_weight = w;
    }
    if let Some(s) = cli.novel_scale {
        novel.scale = s;
    }
    if let Some(e) = cli.novel_max_color_error {
        novel.max_color_error = e.is_finite().then_some(e);
    }
    if let Some(o) = cli.novel_oracle {
        novel.oracle = Some(o);
    }
    if let Some(n) = cli.novel_normalisation {
        novel.normalisation = n;
    }
    if let Some(w) = cli.novel_color_weight {
        novel.color_weight = w;
    }
    if cli.novel_keep_fog {
        novel.mask_features = false;
    }
    if let Some(c) = &cli.extractor_command {
        // Refused before this point (`validate::cli`) when it cannot be split.
        novel.extractor = validate::extractor_words(c).ok();
    }
}

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
