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
pub mod backend;
pub mod batch;
pub mod checkpoint;
// Flag help is written for `--help`, where `<out>` names a placeholder,
// not an HTML tag.
#[allow(rustdoc::invalid_html_tags)]
pub mod cli;
pub mod config;
pub mod curve;
pub mod data;
pub mod error;
pub mod evaluate;
pub mod fast_config;
pub mod interrupt;
pub mod loss_config;
pub mod metrics_log;
pub mod model_checks;
pub mod occupancy;
pub mod preset;
pub mod progress;
pub mod report;
pub mod schedule;
pub mod settings;
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
    let mut scene = match &cli.vlm {
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
    let settings::Resolved {
        config,
        lines,
        background,
        ..
    } = settings::resolve(cli, &scene)?;
    scene.background = background;
    for line in &lines {
        eprintln!("{line}");
    }
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

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
