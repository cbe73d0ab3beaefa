//! Writes the decided settings into the configuration (keeping the
//! sub-settings a `--config` file gave), and the lines `train` prints for
//! them.

use datasets::Scene;
use model::{
    AppearanceCodesConfig, ExposureConfig, FastFieldConfig, HashGridConfig, OpenNerfConfig,
    PoseCorrectionConfig, ProposalConfig, UnboundedConfig,
};

use super::choices::{By, Choices};
use super::table::{Appearance, Extent, FieldModel, Sampler};
use crate::config::{TrainConfig, fast_field, fast_proposal};
use crate::error::TrainError;

/// The radius, in the field's normalised units, of the ball an unbounded
/// field keeps as it is: the ball around the scene box (the region the
/// cameras see in detail, which the loaders fit to the capture's points),
/// so that space beyond the box, the cameras' surroundings included, is
/// contracted.
pub fn contraction_radius(scene: &Scene) -> f32 {
    let corner = scene.scene_box.normalize_point(scene.scene_box.max);
    (corner[0] * corner[0] + corner[1] * corner[1] + corner[2] * corner[2]).sqrt() as f32
}

/// Writes `choices` into `config` for `scene`. The occupancy grid a preset
/// turns on stays off an unbounded field (it covers the scene box, not
/// contracted space); asked for by the file or a flag, it is refused there.
pub fn apply(choices: &Choices, config: &mut TrainConfig, scene: &Scene) -> Result<(), TrainError> {
    let unbounded = choices.extent.value == Extent::Unbounded;
    let grid = choices.grid.value && !(unbounded && matches!(choices.grid.by, By::Preset(_)));
    if unbounded && grid {
        return Err(TrainError::Config(format!(
            "the occupancy grid covers the scene box, and the field is unbounded ({}): \
             train without --occupancy-grid (and without occupancy.enabled in --config), \
             or with --field box",
            choices.extent.by.reason()
        )));
    }
    let fast = choices.model.value == FieldModel::Fast;
    if fast && choices.hash.value && matches!(choices.hash.by, By::File(_) | By::Flag(_)) {
        return Err(TrainError::Config(format!(
            "the hash grid beside the IPE ({}) belongs to the Mip-NeRF MLP; the fast field ({}) \
             has its own, model.fast.grid: leave out --hash-grid on and model.hash",
            choices.hash.by.reason(),
            choices.model.by.reason()
        )));
    }
    config.occupancy.enabled = grid;
    apply_field(choices, &mut config.model, scene);
    let model = &mut config.model;
    let frames = scene.frames.len();
    let appearance = choices.appearance.value;
    model.exposure = (appearance == Appearance::Exposure).then(|| ExposureConfig::new(frames));
    let dim = model.appearance.as_ref().map(|a| a.dim);
    model.appearance = (appearance == Appearance::Embedding).then(|| {
        let codes = AppearanceCodesConfig::new(frames);
        match dim {
            Some(d) => codes.with_dim(d),
            None => codes,
        }
    });
    model.pose = choices
        .pose
        .value
        .then(|| PoseCorrectionConfig::new(frames));
    model.hash = (choices.hash.value && !fast)
        .then(|| model.hash.clone().unwrap_or_else(HashGridConfig::new));
    Ok(())
}

/// Sets the field's extent and sampler on `model` for `scene`, keeping the
/// settings a `--config` file gave them.
pub fn apply_field(choices: &Choices, model: &mut OpenNerfConfig, scene: &Scene) {
    let unbounded = choices.extent.value == Extent::Unbounded;
    model.unbounded = match model.unbounded.take() {
        // A radius of 0 (a file that leaves it out) is the scene's.
        Some(mut given) if unbounded => {
            if given.radius == 0.0 {
                given.radius = contraction_radius(scene);
            }
            given.start_at_box.get_or_insert(true);
            Some(given)
        }
        _ if unbounded => {
            Some(UnboundedConfig::new(contraction_radius(scene)).with_start_at_box(Some(true)))
        }
        _ => None,
    };
    let fast = choices.model.value == FieldModel::Fast;
    model.fast = match model.fast.take() {
        Some(given) if fast => Some(given),
        _ if fast => Some(fast_field()),
        _ => None,
    };
    let proposal = choices.sampler().value == Sampler::Proposal;
    model.proposal = match model.proposal.take() {
        Some(given) if proposal => Some(given),
        _ if proposal => Some(default_proposal(choices)),
        _ => None,
    };
}

/// The proposal sampler the field of `choices` takes unless a `--config`
/// file changes its keys: the fast field's hash-grid proposal networks
/// ([`fast_proposal`]) with the capture kind's rounds, else Mip-NeRF 360's
/// proposal MLP.
pub fn default_proposal(choices: &Choices) -> ProposalConfig {
    if choices.model.value == FieldModel::Fast {
        fast_proposal().with_samples(choices.fast_rounds.value.to_vec())
    } else {
        ProposalConfig::new()
    }
}

/// The line of the proposal rounds' samples; `by_file`: the `--config`
/// file gave them.
pub fn rounds_line(choices: &Choices, proposal: &ProposalConfig, by_file: bool) -> String {
    let rounds: Vec<String> = proposal.samples.iter().map(|n| n.to_string()).collect();
    let why = if by_file {
        "auto: the configuration's model.proposal.samples".to_string()
    } else if choices.model.value == FieldModel::Fast {
        choices.fast_rounds.by.reason()
    } else {
        "auto: Mip-NeRF 360's".to_string()
    };
    format!("proposal rounds: {} samples ({why})", rounds.join(" and "))
}

/// The field line.
pub fn field_line(choices: &Choices) -> String {
    let sampler = choices.sampler();
    format!(
        "field: {} ({}); sampler: {} ({})",
        match choices.extent.value {
            Extent::Box => "box",
            Extent::Unbounded => "unbounded",
        },
        choices.extent.by.reason(),
        match sampler.value {
            Sampler::CoarseFine => "coarse-fine",
            Sampler::Proposal => "proposal",
        },
        sampler.by.reason(),
    )
}

/// Where an unbounded field's rays start, in words (`None` for a box
/// field).
pub fn ray_start_line(model: &OpenNerfConfig) -> Option<String> {
    let u = model.unbounded.as_ref()?;
    Some(if u.start_at_box == Some(true) {
        format!(
            "unbounded field: rays start where they enter the scene box, or {} radii of the kept \
             ball from the camera where that is farther (model.unbounded.start_at_box)",
            u.near
        )
    } else {
        format!(
            "unbounded field: rays start {} radii of the kept ball from the camera \
             (model.unbounded.start_at_box false)",
            u.near
        )
    })
}

/// The appearance line.
pub fn appearance_line(choices: &Choices) -> String {
    let what = match choices.appearance.value {
        Appearance::Exposure => "a learned exposure per photograph",
        Appearance::Embedding => {
            "a learned appearance code per photograph (held-out and novel views: the zero code)"
        }
        Appearance::None => "none",
    };
    format!("appearance: {what} ({})", choices.appearance.by.reason())
}

/// The camera pose line.
pub fn pose_line(choices: &Choices) -> String {
    let reason = choices.pose.by.reason();
    if choices.pose.value {
        format!(
            "camera poses: refined with the field, training photographs only; held-out and \
             novel views keep their poses ({reason})"
        )
    } else {
        format!("camera poses: as given ({reason})")
    }
}

/// The fast field's density activation as `train` prints it:
/// `exp(raw - 1)` for a shift of -1, `exp(raw)` for none.
fn density_formula(shift: f32) -> String {
    if shift == 0.0 {
        "exp(raw)".into()
    } else {
        let sign = if shift < 0.0 { '-' } else { '+' };
        format!("exp(raw {sign} {})", shift.abs())
    }
}

/// A fast-field hash grid's sizes as the field model line gives them:
/// "16 levels of 2^15 rows x 2 features (16 to 512 cells across)".
fn grid_sizes(g: &HashGridConfig) -> String {
    format!(
        "{} levels of 2^{} rows x {} features ({} to {} cells across)",
        g.levels, g.log2_table, g.features, g.base_resolution, g.max_resolution
    )
}

/// What the field model line says of the grid's coarse-to-fine ramp.
fn ramp_phrase(fast: &FastFieldConfig) -> String {
    match fast.coarse_to_fine {
        Some(until) if until > 0.0 => format!(
            ", its finer levels let in one by one over the first {:.0}% of training",
            100.0 * until
        ),
        _ => String::new(),
    }
}

/// What the field model line says of the fast field's feature grid.
fn feature_grid_phrase(fast: &FastFieldConfig) -> String {
    let alone = if fast.head_reads_geometry == Some(false) {
        " (and not the geometry feature)"
    } else {
        ""
    };
    fast.feature_grid.as_ref().map_or_else(String::new, |g| {
        format!(
            "; the open-set head reads a hash grid of its own{alone}, {}",
            grid_sizes(g)
        )
    })
}

/// The field model line, with its sizes from `model`.
pub fn model_line(choices: &Choices, model: &OpenNerfConfig) -> String {
    let reason = choices.model.by.reason();
    match &model.fast {
        Some(f) => {
            format!(
                "field model: fast, a hash grid of {}{}, a density MLP of {} x {} (density {}) \
                 with a {}-wide geometry feature, a colour MLP of {} x {} on {} \
                 spherical-harmonics bands{} ({reason})",
                grid_sizes(&f.grid),
                ramp_phrase(f),
                f.density_layers,
                f.density_width,
                density_formula(f.density_shift.unwrap_or(0.0)),
                f.geo_features,
                f.color_layers,
                f.color_width,
                f.sh_degree,
                feature_grid_phrase(f)
            )
        }
        None => format!(
            "field model: mip, the Mip-NeRF MLP of {} x {} ({reason})",
            model.mlp.depth, model.mlp.width
        ),
    }
}

/// The hash grid line, with the grid's sizes from `model` (`None` for the
/// fast field, whose grid the field model line gives).
pub fn hash_line(choices: &Choices, model: &OpenNerfConfig) -> Option<String> {
    if model.fast.is_some() {
        return None;
    }
    let reason = choices.hash.by.reason();
    Some(match &model.hash {
        Some(h) => format!(
            "hash grid: {} levels of 2^{} rows x {} features, {} to {} cells across, beside the \
             IPE ({reason})",
            h.levels, h.log2_table, h.features, h.base_resolution, h.max_resolution
        ),
        None => format!("hash grid: none, the IPE alone ({reason})"),
    })
}

#[cfg(test)]
mod tests {
    use super::super::choices::{Flags, Layer};
    use super::super::{args::HashGridArg, choices_for};
    use super::*;

    fn synthetic() -> Scene {
        use datasets::synthetic::{SceneSize, generate};
        generate(0, SceneSize::Ci).expect("the tiny scene")
    }

    #[test]
    fn the_density_formula_reads_as_arithmetic() {
        assert_eq!(density_formula(0.0), "exp(raw)");
        assert_eq!(density_formula(-1.0), "exp(raw - 1)");
        assert_eq!(density_formula(2.5), "exp(raw + 2.5)");
    }

    #[test]
    fn the_hash_grid_follows_the_file_and_the_flags_win() {
        let scene = synthetic();
        let hash = |file: serde_json::Value, flag: Option<HashGridArg>| {
            let mut config = TrainConfig::default_run(4);
            if let Some(levels) = file["model"]["hash"]["levels"].as_u64() {
                config.model.hash = Some(HashGridConfig::new().with_levels(levels as usize));
            }
            let choices = choices_for(&scene, &Flags::default())
                .overlaid(Layer::of_file(&file))
                .overlaid(Layer::of_flags(&Flags {
                    hash_grid: flag,
                    ..Flags::default()
                }));
            apply(&choices, &mut config, &scene).expect("applies");
            config.model.hash
        };
        let none = serde_json::json!({});
        assert!(hash(none.clone(), None).is_none(), "the room's row: off");
        let file = serde_json::json!({"model": {"hash": {"levels": 4}}});
        let kept = hash(file.clone(), None).expect("the file's grid");
        assert_eq!(kept.levels, 4, "the configuration's settings are kept");
        assert!(hash(file, Some(HashGridArg::Off)).is_none());
        assert!(hash(none, Some(HashGridArg::On)).is_some());
    }

    /// The fast field's proposal rounds are its capture kind's, and say
    /// so; the Mip-NeRF field's are Mip-NeRF 360's; a file's are named as
    /// the file's.
    #[test]
    fn the_proposal_rounds_are_the_kinds_and_say_whose_they_are() {
        use super::super::args::FieldModelArg;
        use super::super::table::row;
        use datasets::capture_kind::CaptureKind;
        let fast = Layer::of_flags(&Flags {
            field_model: FieldModelArg::Fast,
            ..Flags::default()
        });
        for (kind, rounds) in [
            (CaptureKind::PhotographedObject, vec![32, 16]),
            (CaptureKind::Room, vec![64, 32]),
        ] {
            let choices = Choices::of_row(&row(kind)).overlaid(fast.clone());
            let proposal = default_proposal(&choices);
            assert_eq!(proposal.samples, rounds, "{kind:?}");
            assert!(proposal.hash.is_some(), "{kind:?}: the hash-grid networks");
            let line = rounds_line(&choices, &proposal, false);
            assert!(
                line.starts_with(&format!(
                    "proposal rounds: {} and {} samples (auto: {}:",
                    rounds[0],
                    rounds[1],
                    kind.describe()
                )),
                "{line}"
            );
            let by_file = rounds_line(&choices, &proposal, true);
            assert!(by_file.ends_with("(auto: the configuration's model.proposal.samples)"));
        }
        let mip = Choices::of_row(&row(CaptureKind::PhotographedObject));
        let proposal = default_proposal(&mip);
        assert_eq!(proposal.samples, ProposalConfig::new().samples);
        assert!(proposal.hash.is_none());
        assert!(rounds_line(&mip, &proposal, false).ends_with("(auto: Mip-NeRF 360's)"));
    }
}
