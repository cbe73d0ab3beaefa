//! The one place where a new run's settings are decided, in one pass:
//! the built-in configuration, then the defaults of the capture's kind
//! (told from the loaded scene's content, [`datasets::capture_kind`]; one
//! row of [`table`]), then `--preset`, then the `--config` file, then the
//! flags. Every per-capture setting (field, sampler, appearance, hash
//! encoding, pose refinement, occupancy grid, sizes) records who decided
//! it, and `train` prints each with that reason. Nothing decided here is
//! read back to decide something else.

pub mod args;
pub mod choices;
pub mod depth;
pub mod flags;
pub mod sizes;
pub mod table;
pub mod write;

use std::path::Path;

use datasets::Scene;
use datasets::capture_kind::{CaptureKind, capture_kind};

use crate::cli::Cli;
use crate::config::{Overrides, TrainConfig};
use crate::error::TrainError;
use choices::{Choices, Layer};
use sizes::Sizes;
use table::Extent;

/// A new run's configuration, and the lines that say how it was decided.
#[derive(Debug, Clone)]
pub struct Resolved {
    /// The configuration the run trains with.
    pub config: TrainConfig,
    /// The capture's kind, whose row gave the defaults.
    pub kind: CaptureKind,
    /// The colour composited behind the field: the loader's, or for a
    /// rendered object the plain colour around it in its views.
    pub background: Option<[f32; 3]>,
    /// One line per decision, in the order `train` prints them.
    pub lines: Vec<String>,
}

/// Decides the configuration of a new run of `scene` from the command
/// line (see the module docs).
pub fn resolve(cli: &Cli, scene: &Scene) -> Result<Resolved, TrainError> {
    let (kind, evidence) = capture_kind(scene);
    let row = table::row(kind);
    let mut lines = vec![format!(
        "capture: {} ({})",
        kind.describe(),
        evidence.describe()
    )];
    let patch = cli.config.as_deref().map(read_patch).transpose()?;
    let key_flags = overrides(cli);
    let mut choices = Choices::of_row(&row);
    if let Some(p) = cli.preset {
        choices = choices.overlaid(Layer::of_preset(p));
    }
    if let Some(patch) = &patch {
        choices = choices.overlaid(Layer::of_file(patch));
    }
    choices = choices.overlaid(Layer::of_flags(&choices::Flags::of_cli(cli)));
    if choices.model.value == table::FieldModel::Fast
        && (cli.width.is_some() || cli.depth.is_some())
    {
        return Err(TrainError::Config(format!(
            "--width and --depth size the Mip-NeRF MLP, and the field is the fast field ({}): \
             its sizes are model.fast in a --config file (model.fast.density_width, \
             model.fast.color_width, ...)",
            choices.model.by.reason()
        )));
    }
    lines.push(write::field_line(&choices));
    let background = match (scene.background, kind, evidence.plain_background) {
        (None, CaptureKind::RenderedObject, Some(c)) => {
            lines.push(format!(
                "background: ({:.3}, {:.3}, {:.3}) composited behind the field (auto: a rendered \
                 object: its views show that plain colour around it)",
                c[0], c[1], c[2]
            ));
            Some(c)
        }
        (given, ..) => given,
    };

    let dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let mut base = TrainConfig::default_run(dim);
    let sampler = choices.sampler().value;
    let sizes = Sizes::of_row(&row, choices.model.value, sampler).filter(|_| cli.preset.is_none());
    if let Some(p) = cli.preset {
        let unbounded = choices.extent.value == Extent::Unbounded;
        let s = p.apply(&mut base, row.preset, !unbounded);
        lines.push(preset_line(p, &row, &s, unbounded));
    }
    sizes.inspect(|s| s.apply(&mut base));
    // The proposal sampler the field takes, in the layer under the file, so
    // that a file's proposal keys change only themselves (and the fast
    // field keeps its hash-grid proposal networks).
    if sampler == table::Sampler::Proposal {
        base.model
            .proposal
            .get_or_insert_with(|| write::default_proposal(&choices));
    }
    let mut config = match (&patch, &cli.config) {
        (Some(patch), Some(path)) => {
            TrainConfig::merged(&base, patch.clone()).map_err(|e| TrainError::json(path, e))?
        }
        _ => base,
    };
    config.apply(&key_flags);
    flags::apply_novel_and_grid(cli, &mut config);
    let set_by_file = |section: &str, key: &str| {
        patch
            .as_ref()
            .is_some_and(|p| p[section].get(key).is_some())
    };
    let samples_set = cli.samples.is_some() || set_by_file("model", "num_samples");
    let rays_set = cli.rays.is_some() || set_by_file("sampler", "rays_per_batch");
    if let Some(s) = sizes.filter(|s| s.kept(samples_set, rays_set)) {
        let why = row.sizes_why_for(choices.model.value, sampler);
        lines.push(s.line(&choices::By::Kind(kind, why).reason()));
    }
    lines.extend(depth::apply(cli.sparse_depth, scene, &mut config)?);
    write::apply(&choices, &mut config, scene)?;
    lines.push(write::model_line(&choices, &config.model));
    if let Some(proposal) = &config.model.proposal {
        let by_file = patch
            .as_ref()
            .is_some_and(|p| !p["model"]["proposal"]["samples"].is_null());
        lines.push(write::rounds_line(&choices, proposal, by_file));
    }
    lines.extend(write::ray_start_line(&config.model));
    lines.push(write::appearance_line(&choices));
    lines.push(write::pose_line(&choices));
    lines.extend(write::hash_line(&choices, &config.model));
    // Checked again, without the file's name, where the run starts.
    if let (Err(TrainError::Config(msg)), Some(path)) = (config.validate(), &cli.config) {
        return Err(TrainError::Config(format!(
            "{msg} (the configuration of {}, with the flags laid over it)",
            path.display()
        )));
    }
    Ok(Resolved {
        config,
        kind,
        background,
        lines,
    })
}

/// The line `train` prints for a `--preset`: what it set on a capture of
/// `row`'s kind.
fn preset_line(
    preset: crate::preset::Preset,
    row: &table::Row,
    set: &crate::preset::PresetSettings,
    unbounded: bool,
) -> String {
    format!(
        "preset {} with the {} settings ({}): {} samples per ray and level, {} rays a batch, \
         {} iterations{}",
        preset.name(),
        row.preset.name(),
        row.kind.describe(),
        set.samples,
        set.rays,
        set.iterations,
        if unbounded {
            ", no occupancy grid (the field is unbounded)"
        } else {
            ""
        },
    )
}

/// The settings of `scene`'s capture kind with `flags` laid over them (no
/// preset, no file): what a library caller building its own configuration
/// writes with [`write::apply`].
pub fn choices_for(scene: &Scene, flags: &choices::Flags) -> Choices {
    let (kind, _) = capture_kind(scene);
    Choices::of_row(&table::row(kind)).overlaid(Layer::of_flags(flags))
}

/// The flags that override single keys of the configuration.
pub fn overrides(cli: &Cli) -> Overrides {
    Overrides {
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

/// The `--config` file as JSON.
fn read_patch(path: &Path) -> Result<serde_json::Value, TrainError> {
    let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| TrainError::json(path, e))
}
