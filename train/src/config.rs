//! The full training configuration (`config.json` of a run directory) and
//! its presets.

use std::path::Path;

use datasets::sampler::SamplerConfig;
use model::{FeatureHeadConfig, HashGridConfig, MipMlpConfig, OpenNerfConfig};
use serde::{Deserialize, Serialize};

pub use field_ops::novel::{NovelMode, NovelViewConfig};

pub use crate::fast_config::{FAST_DENSITY_SHIFT, fast_feature_grid, fast_field, fast_proposal};
pub use crate::loss_config::LossConfig;

use crate::error::TrainError;
use crate::schedule::ScheduleConfig;

/// Adam settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct OptimiserConfig {
    /// First-moment decay.
    pub beta_1: f32,
    /// Second-moment decay.
    pub beta_2: f32,
    /// Denominator floor.
    pub epsilon: f32,
    /// The feature head's learning rate relative to the scheduled rate (the
    /// head only sees the detached trunk, so it can take larger steps).
    pub head_lr_scale: f64,
    /// The pose corrections' learning rate relative to the scheduled rate
    /// (`--pose-refine`).
    pub pose_lr_scale: f64,
}

impl Default for OptimiserConfig {
    fn default() -> Self {
        Self {
            beta_1: 0.9,
            beta_2: 0.999,
            epsilon: 1e-8,
            head_lr_scale: 1.0,
            pose_lr_scale: 0.2,
        }
    }
}

/// How often the loop logs, evaluates and saves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LoggingConfig {
    /// A `metrics.jsonl` line every this many iterations; the steps'
    /// values are read back from the device then (and before an evaluation
    /// or a checkpoint), not at every step.
    pub log_every: usize,
    /// A held-out evaluation every this many iterations (0 = only at the start and end).
    pub eval_every: usize,
    /// A checkpoint every this many iterations (0 = only at the end).
    pub checkpoint_every: usize,
    /// Checkpoints kept (the newest ones).
    pub keep_checkpoints: usize,
    /// Held-out pixels measured by the periodic evaluation.
    pub eval_pixels: usize,
    /// Rays rendered at once at inference.
    pub render_chunk: usize,
    /// Consecutive non-finite steps tolerated before training stops.
    pub max_nonfinite_steps: usize,
}

impl Default for LoggingConfig {
    fn default() -> Self {
        Self {
            log_every: 25,
            eval_every: 500,
            checkpoint_every: 500,
            keep_checkpoints: 2,
            eval_pixels: 2048,
            render_chunk: 2048,
            max_nonfinite_steps: 20,
        }
    }
}

/// Everything a run is configured by; serialised as `config.json` (the
/// `"model"` key is what evaluation reads back).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainConfig {
    /// The field.
    pub model: OpenNerfConfig,
    /// Ray batches.
    #[serde(default)]
    pub sampler: SamplerConfig,
    /// Loss weights.
    #[serde(default)]
    pub losses: LossConfig,
    /// Adam.
    #[serde(default)]
    pub optimiser: OptimiserConfig,
    /// Learning-rate schedule and length.
    #[serde(default)]
    pub schedule: ScheduleConfig,
    /// Logging, evaluation and checkpoint cadence.
    #[serde(default)]
    pub logging: LoggingConfig,
    /// Seed of the initialisation, the ray sampler and the stratified jitter.
    #[serde(default)]
    pub seed: u64,
    /// Novel views rendered by the field and added as training frames.
    #[serde(default)]
    pub novel: NovelViewConfig,
    /// Empty-space skipping with an occupancy grid (off by default; keys
    /// that a run's file leaves out, as older runs do, take their default).
    #[serde(default, deserialize_with = "crate::occupancy::deserialize_config")]
    pub occupancy: model::OccupancyConfig,
}

/// Command-line overrides applied on top of a configuration.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Overrides {
    /// Total iterations.
    pub iters: Option<usize>,
    /// Rays per batch.
    pub rays: Option<usize>,
    /// Samples per ray per level.
    pub samples: Option<usize>,
    /// Trunk width.
    pub width: Option<usize>,
    /// Trunk depth.
    pub depth: Option<usize>,
    /// Open-set loss weight.
    pub lambda_open: Option<f32>,
    /// Depth loss weight.
    pub lambda_depth: Option<f32>,
    /// Initial learning rate.
    pub lr: Option<f64>,
    /// Weight of the unseen patches' depth smoothness.
    pub unseen_depth: Option<f32>,
    /// Seed.
    pub seed: Option<u64>,
    /// Iterations between two log lines (and reads of the steps' values).
    pub log_every: Option<usize>,
}

impl TrainConfig {
    /// A small model that trains the CI-sized synthetic scene in about a
    /// minute on two cores (tests). `feature_dim` is the head's output size
    /// (0 when the scene has no features: the head is then kept minimal).
    pub fn tiny(feature_dim: usize) -> Self {
        let mlp = MipMlpConfig::new()
            .with_width(64)
            .with_depth(4)
            .with_skip_layer(2)
            .with_max_deg(10);
        Self {
            model: OpenNerfConfig::new(head_config(feature_dim, 64))
                .with_mlp(mlp)
                .with_num_samples(32),
            sampler: SamplerConfig {
                rays_per_batch: 256,
                ..Default::default()
            },
            losses: LossConfig::default(),
            optimiser: OptimiserConfig::default(),
            schedule: ScheduleConfig {
                iterations: 300,
                lr_init: 5e-3,
                lr_final: 5e-4,
                warmup_iters: 20,
                warmup_factor: 0.1,
            },
            logging: LoggingConfig {
                log_every: 10,
                eval_every: 100,
                checkpoint_every: 100,
                eval_pixels: 512,
                ..Default::default()
            },
            seed: 0,
            novel: NovelViewConfig::default(),
            occupancy: model::OccupancyConfig::default(),
        }
    }

    /// The default run (no arguments): a few minutes on a 2-core CPU.
    pub fn default_run(feature_dim: usize) -> Self {
        let mut c = Self::tiny(feature_dim);
        c.model.mlp = c.model.mlp.clone().with_width(96).with_max_deg(12);
        c.model.num_samples = 48;
        c.schedule.iterations = 1000;
        c.schedule.warmup_iters = 50;
        c.logging = LoggingConfig {
            log_every: 25,
            eval_every: 250,
            checkpoint_every: 500,
            eval_pixels: 1024,
            ..Default::default()
        };
        c
    }

    /// The paper-sized model (Mip-NeRF 8 x 256, 64 + 64 samples, 1024 rays,
    /// head 2 x 256).
    pub fn paper(feature_dim: usize) -> Self {
        Self {
            model: OpenNerfConfig::new(head_config(feature_dim, 256)),
            sampler: SamplerConfig {
                rays_per_batch: 1024,
                ..Default::default()
            },
            losses: LossConfig::default(),
            optimiser: OptimiserConfig::default(),
            schedule: ScheduleConfig {
                iterations: 200_000,
                lr_init: 5e-4,
                lr_final: 5e-6,
                warmup_iters: 2500,
                warmup_factor: 0.01,
            },
            logging: LoggingConfig::default(),
            seed: 0,
            novel: NovelViewConfig::default(),
            occupancy: model::OccupancyConfig::default(),
        }
    }

    /// Reads a configuration file and lays it over `base`: keys the file
    /// leaves out keep their value in `base`, at any depth. The head's
    /// `out_dim` is replaced by the scene's feature dimension later.
    pub fn from_file(path: &Path, base: &TrainConfig) -> Result<Self, TrainError> {
        let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e))?;
        let patch: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| TrainError::json(path, e))?;
        Self::merged(base, patch).map_err(|e| TrainError::json(path, e))
    }

    /// `base` with the keys of `patch` laid over it (recursively).
    pub fn merged(base: &TrainConfig, patch: serde_json::Value) -> Result<Self, String> {
        let mut value = serde_json::to_value(base).map_err(|e| e.to_string())?;
        optional_defaults(&mut value, &patch).map_err(|e| e.to_string())?;
        merge_json(&mut value, patch);
        serde_json::from_value(value).map_err(|e| e.to_string())
    }

    /// Sets the head's output size to the scene's feature dimension (a
    /// minimal head when the scene has no features).
    pub fn set_feature_dim(&mut self, feature_dim: usize) {
        if feature_dim == 0 {
            self.model.head = head_config(0, 8);
        } else {
            self.model.head.out_dim = feature_dim;
        }
    }

    /// Applies command-line overrides. A new initial rate keeps the ratio of
    /// the final rate to it.
    pub fn apply(&mut self, o: &Overrides) {
        if let Some(v) = o.iters {
            self.schedule.iterations = v;
        }
        if let Some(v) = o.rays {
            self.sampler.rays_per_batch = v;
        }
        if let Some(v) = o.samples {
            self.model.num_samples = v;
        }
        if let Some(v) = o.width {
            self.model.mlp.width = v;
        }
        if let Some(v) = o.depth {
            self.model.mlp.depth = v;
        }
        if let Some(v) = o.lambda_open {
            self.losses.lambda_open = v;
        }
        if let Some(v) = o.lambda_depth {
            self.losses.lambda_depth = v;
        }
        if let Some(v) = o.unseen_depth {
            self.losses.unseen_depth_weight = v;
        }
        if let Some(v) = o.lr {
            let ratio = self.schedule.lr_final / self.schedule.lr_init;
            self.schedule.lr_init = v;
            self.schedule.lr_final = v * ratio;
        }
        if let Some(v) = o.seed {
            self.seed = v;
        }
        if let Some(v) = o.log_every {
            self.logging.log_every = v;
        }
    }

    /// Checks ranges; the message names the offending key.
    pub fn validate(&self) -> Result<(), TrainError> {
        let bad = |m: String| Err(TrainError::Config(m));
        if self.sampler.rays_per_batch == 0 {
            return bad("sampler.rays_per_batch must be at least 1".into());
        }
        if self.logging.log_every == 0 {
            return bad("logging.log_every must be at least 1 (--log-every)".into());
        }
        if self.sampler.depth_rays >= self.sampler.rays_per_batch {
            return bad(format!(
                "sampler.depth_rays ({}) must be less than sampler.rays_per_batch ({}): the \
                 rest of each batch is drawn from every pixel",
                self.sampler.depth_rays, self.sampler.rays_per_batch
            ));
        }
        if !(self.sampler.feature_balance.is_finite() && self.sampler.feature_balance >= 0.0) {
            return bad(format!(
                "sampler.feature_balance must be finite and non-negative, got {}",
                self.sampler.feature_balance
            ));
        }
        if self.sampler.balance_clusters == 0 {
            return bad("sampler.balance_clusters must be at least 1".into());
        }
        if self.model.num_samples == 0 {
            return bad("model.num_samples must be at least 1".into());
        }
        crate::occupancy::validate(&self.occupancy).map_err(TrainError::Config)?;
        crate::model_checks::field(&self.model).map_err(TrainError::Config)?;
        crate::model_checks::hash(&self.model).map_err(TrainError::Config)?;
        if let Some(a) = &self.model.appearance
            && !(1..=1024).contains(&a.dim)
        {
            return bad(format!(
                "model.appearance.dim must be in 1..=1024, got {}",
                a.dim
            ));
        }
        if self.model.mlp.width == 0 || self.model.mlp.depth == 0 {
            return bad("model.mlp.width and model.mlp.depth must be at least 1".into());
        }
        for (k, v) in [
            ("losses.lambda_open", self.losses.lambda_open),
            ("losses.lambda_depth", self.losses.lambda_depth),
            ("losses.coarse_weight", self.losses.coarse_weight),
            ("losses.interlevel_weight", self.losses.interlevel_weight),
            ("losses.distortion_weight", self.losses.distortion_weight),
            (
                "losses.box_distortion_weight",
                self.losses.box_distortion_weight,
            ),
            ("losses.exposure_penalty", self.losses.exposure_penalty),
            ("losses.pose_penalty", self.losses.pose_penalty),
            ("losses.appearance_penalty", self.losses.appearance_penalty),
            (
                "losses.unseen_depth_weight",
                self.losses.unseen_depth_weight,
            ),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{k} must be finite and non-negative, got {v}"));
            }
        }
        let cap = self.losses.depth_cap;
        if !(cap.is_finite() && cap >= 1.0) {
            return bad(format!(
                "losses.depth_cap must be finite and at least 1 (a multiple of each ray's depth \
                 target), got {cap}"
            ));
        }
        for (k, v) in [
            ("losses.unseen_patches", self.losses.unseen_patches),
            ("losses.unseen_patch_side", self.losses.unseen_patch_side),
            (
                "losses.unseen_patch_stride",
                self.losses.unseen_patch_stride,
            ),
        ] {
            if v == 0 {
                return bad(format!("{k} must be at least 1"));
            }
        }
        if !(self.optimiser.head_lr_scale.is_finite() && self.optimiser.head_lr_scale > 0.0) {
            return bad("optimiser.head_lr_scale must be positive".into());
        }
        let pose_scale = self.optimiser.pose_lr_scale;
        if !(pose_scale.is_finite() && pose_scale > 0.0) {
            return bad(format!(
                "optimiser.pose_lr_scale must be positive and finite, got {pose_scale}"
            ));
        }
        if self.logging.render_chunk == 0 {
            return bad("logging.render_chunk must be at least 1".into());
        }
        self.novel.validate().map_err(TrainError::Config)?;
        self.schedule.validate().map_err(TrainError::Config)
    }
}

/// Where `patch` sets keys of the field's optional parts (`model.unbounded`,
/// `model.proposal` and its `hash`, `model.exposure`, `model.fast`, ...)
/// that `base` leaves out, `base` first
/// gets their defaults, so that a file may give only the keys it changes
/// (an unbounded field's `radius` defaults to 0: the ball around the scene
/// box).
fn optional_defaults(
    base: &mut serde_json::Value,
    patch: &serde_json::Value,
) -> Result<(), serde_json::Error> {
    let parts = [
        (
            "unbounded",
            serde_json::to_value(model::UnboundedConfig::new(0.0))?,
        ),
        (
            "proposal",
            serde_json::to_value(model::ProposalConfig::new())?,
        ),
        // `train` sets the photographs' count from the scene.
        (
            "exposure",
            serde_json::to_value(model::ExposureConfig::new(0))?,
        ),
        (
            "pose",
            serde_json::to_value(model::PoseCorrectionConfig::new(0))?,
        ),
        (
            "appearance",
            serde_json::to_value(model::AppearanceCodesConfig::new(0))?,
        ),
        ("hash", serde_json::to_value(HashGridConfig::new())?),
        // The fast field `--field-model fast` builds, so that a file's
        // keys change only themselves.
        ("fast", serde_json::to_value(fast_field())?),
    ];
    for (key, defaults) in parts {
        if patch["model"][key].is_object() && base["model"][key].is_null() {
            base["model"][key] = defaults;
        }
    }
    // The proposal sampler's hash grid, within the proposal's keys.
    let proposal = &patch["model"]["proposal"];
    if proposal["hash"].is_object() && base["model"]["proposal"]["hash"].is_null() {
        base["model"]["proposal"]["hash"] = serde_json::to_value(HashGridConfig::new())?;
    }
    // The fast field's feature grid, within the fast field's keys.
    let fast = &patch["model"]["fast"];
    if fast["feature_grid"].is_object() && base["model"]["fast"]["feature_grid"].is_null() {
        base["model"]["fast"]["feature_grid"] = serde_json::to_value(fast_feature_grid())?;
    }
    Ok(())
}

/// Lays `patch` over `base`: objects merge key by key, anything else replaces.
pub fn merge_json(base: &mut serde_json::Value, patch: serde_json::Value) {
    match (base, patch) {
        (serde_json::Value::Object(b), serde_json::Value::Object(p)) => {
            for (k, v) in p {
                match b.get_mut(&k) {
                    Some(slot) => merge_json(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

/// A head of `layers = 2` hidden layers of `width` with `out_dim` outputs
/// (a one-layer, width-8 stub when there are no features).
fn head_config(out_dim: usize, width: usize) -> FeatureHeadConfig {
    if out_dim == 0 {
        FeatureHeadConfig::new(1).with_width(8).with_layers(1)
    } else {
        FeatureHeadConfig::new(out_dim).with_width(width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_sizing_one_part_of_the_fast_field_keeps_the_rest_as_train_builds_it() {
        let base = TrainConfig::default_run(0);
        let patch = serde_json::json!({"model": {"fast": {"grid": {"max_resolution": 128}}}});
        let merged = TrainConfig::merged(&base, patch).expect("merges");
        let fast = merged.model.fast.expect("the fast field");
        let built = fast_field();
        assert_eq!(fast.grid.max_resolution, 128);
        assert_eq!(fast.grid.log2_table, built.grid.log2_table);
        assert_eq!(fast.grid.levels, built.grid.levels);
        assert_eq!(fast.density_width, built.density_width);
        // Not the library's defaults (2^19 rows).
        assert_eq!(fast.grid.log2_table, 15);
    }

    #[test]
    fn json_roundtrip_and_partial_files_take_defaults() {
        let c = TrainConfig::tiny(16);
        let text = serde_json::to_string(&c).unwrap();
        let back: TrainConfig = serde_json::from_str(&text).unwrap();
        assert_eq!(back.model.head.out_dim, 16);
        assert_eq!(back.model.mlp.width, 64);
        assert_eq!(back.schedule, c.schedule);
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(v.get("model").is_some());
        let patch = serde_json::json!({
            "model": {"mlp": {"width": 32}, "head_top_k": 8},
            "losses": {"lambda_open": 0.5},
            "schedule": {"iterations": 9}
        });
        let partial = TrainConfig::merged(&c, patch).unwrap();
        assert_eq!(partial.losses.lambda_open, 0.5);
        assert_eq!(partial.losses.coarse_weight, 0.1);
        assert_eq!(partial.model.mlp.width, 32);
        assert_eq!(partial.model.mlp.depth, 4);
        assert_eq!(partial.model.head_top_k, Some(8));
        assert_eq!(partial.model.num_samples, 32);
        assert_eq!(partial.schedule.iterations, 9);
        assert_eq!(partial.schedule.lr_init, c.schedule.lr_init);
        assert_eq!(partial.sampler.border_margin, 10);
        assert!(
            TrainConfig::merged(&c, serde_json::json!({"model": {"mlp": {"width": "wide"}}}))
                .is_err()
        );
    }

    #[test]
    fn depth_rays_must_leave_rays_drawn_from_every_pixel() {
        let c = TrainConfig::default_run(0);
        let with = |n: usize| {
            TrainConfig::merged(&c, serde_json::json!({"sampler": {"depth_rays": n}}))
                .expect("merges")
                .validate()
        };
        assert!(with(255).is_ok());
        let err = with(256).expect_err("no uniform ray left").to_string();
        assert!(err.contains("sampler.depth_rays (256)"), "{err}");
    }

    /// The `sampler` section of a run's `config.json` keeps its keys and
    /// the training defaults (256 rays, balanced over 32 clusters).
    #[test]
    fn sampler_section_keeps_its_keys_and_defaults() {
        let want = r#"{"rays_per_batch":256,"border_margin":10,"min_near":0.05,"feature_balance":1.0,"balance_clusters":32,"depth_rays":0}"#;
        for c in [TrainConfig::tiny(16), TrainConfig::default_run(0)] {
            assert_eq!(serde_json::to_string(&c.sampler).unwrap(), want);
        }
        assert_eq!(
            serde_json::to_string(&SamplerConfig::default()).unwrap(),
            want
        );
        let paper = serde_json::to_value(TrainConfig::paper(512)).unwrap();
        assert_eq!(paper["sampler"]["rays_per_batch"], 1024);
    }

    #[test]
    fn overrides_apply_and_validation_names_the_key() {
        let mut c = TrainConfig::tiny(8);
        c.apply(&Overrides {
            iters: Some(7),
            lr: Some(1e-2),
            width: Some(32),
            samples: Some(5),
            ..Default::default()
        });
        assert_eq!(c.schedule.iterations, 7);
        assert_eq!(c.model.mlp.width, 32);
        assert_eq!(c.model.num_samples, 5);
        assert!((c.schedule.lr_final - 1e-3).abs() < 1e-12);
        c.validate().unwrap();
        c.losses.lambda_depth = -1.0;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("losses.lambda_depth"), "{e}");
    }
}
