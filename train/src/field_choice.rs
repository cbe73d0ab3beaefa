//! Which field and sampler a run models its scene with (`--field`,
//! `--sampler`), and why. `auto` takes what was measured better
//! (docs/measurements/unbounded.md): Mip-NeRF 360's contraction, its rays starting
//! where they enter the scene box, where a scene's content reaches far
//! past its box (the synthetic outdoor scene, and COLMAP captures, walked
//! around what they look at: on the statue it ends above the box at equal
//! seconds, with appearance codes), the box elsewhere (fern's LLFF capture
//! and the phone and nerfstudio captures, not measured better); the coarse
//! and fine level everywhere. `train` prints the choice and why.

use datasets::detect::Format;
use datasets::{Scene, SceneSource};
use model::{OpenNerfConfig, ProposalConfig, UnboundedConfig};

use crate::error::TrainError;

/// The field's extent (`--field`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum FieldArg {
    /// Chosen from the scene: `unbounded` for the synthetic outdoor scene
    /// and COLMAP captures, `box` otherwise (where the unbounded field was
    /// not measured better: docs/measurements/unbounded.md).
    #[default]
    Auto,
    /// The scene box mapped to `[-pi, pi]^3`; rays end where they leave it.
    Box,
    /// Mip-NeRF 360's contraction: the ball around the scene box kept as it
    /// is, everything beyond it contracted, rays from where they enter the
    /// scene box to effectively infinite distance.
    Unbounded,
}

/// How the MLP's samples are placed (`--sampler`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum SamplerArg {
    /// `coarse-fine`: at the default sizes the proposal sampler was both
    /// slower and less accurate, with either field (docs/measurements/unbounded.md).
    #[default]
    Auto,
    /// Mip-NeRF's coarse and fine level of the one MLP.
    CoarseFine,
    /// Mip-NeRF 360's proposal sampler: two rounds of 64 samples of a small
    /// density MLP, then the MLP's samples where they found density.
    Proposal,
}

/// What a run models its scene with, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldChoice {
    /// The contraction (else the box).
    pub unbounded: bool,
    /// The proposal sampler (else coarse and fine level).
    pub proposal: bool,
    /// Why this field, in words.
    pub field_reason: String,
    /// Why this sampler, in words.
    pub sampler_reason: String,
}

impl FieldChoice {
    /// The one-line message `train` prints.
    pub fn message(&self) -> String {
        format!(
            "field: {} ({}); sampler: {} ({})",
            if self.unbounded { "unbounded" } else { "box" },
            self.field_reason,
            if self.proposal {
                "proposal"
            } else {
                "coarse-fine"
            },
            self.sampler_reason,
        )
    }
}

/// The capture a scene was made from, in words, and whether its content
/// reaches past the region its cameras see in detail.
fn capture(scene: &Scene) -> (String, bool) {
    match scene.source.base() {
        SceneSource::Synthetic { size, .. } if size == "outdoor" => (
            "the synthetic outdoor scene, whose backdrop is far outside its box".into(),
            true,
        ),
        SceneSource::Synthetic { .. } => ("the synthetic room, a box".into(), false),
        SceneSource::Disk { loader, .. } => match loader.format() {
            Format::Colmap => (
                "a colmap capture, walked around what it looks at: the unbounded field, its rays \
                 from the scene box, measured above the box (docs/measurements/unbounded.md)"
                    .into(),
                true,
            ),
            Format::Llff => (
                "an llff capture: the unbounded field measured level with the box".into(),
                false,
            ),
            Format::Blender if scene.world.as_ref().is_some_and(|w| w.name == "nerfstudio") => (
                "a nerfstudio capture: the unbounded field not measured better on one".into(),
                false,
            ),
            Format::Blender => ("a Blender object with its known box".into(), false),
            phone if phone.is_phone() => (
                format!(
                    "a phone capture ({phone}): the unbounded field not measured better on one"
                ),
                false,
            ),
            other => (format!("a {other} room, the cameras inside it"), false),
        },
        SceneSource::WithFeatures { .. } => ("a scene with its box".into(), false),
    }
}

/// Chooses the field and the sampler for `scene` from the flags.
pub fn choose(field: FieldArg, sampler: SamplerArg, scene: &Scene) -> FieldChoice {
    let (what, reaches_past) = capture(scene);
    let (unbounded, field_reason) = match field {
        FieldArg::Auto => (reaches_past, format!("auto: {what}")),
        FieldArg::Box => (false, "--field box".into()),
        FieldArg::Unbounded => (true, "--field unbounded".into()),
    };
    let (proposal, sampler_reason) = match sampler {
        SamplerArg::Auto => (
            false,
            "auto: more accurate and faster than the proposal sampler at these sizes".to_string(),
        ),
        SamplerArg::CoarseFine => (false, "--sampler coarse-fine".into()),
        SamplerArg::Proposal => (true, "--sampler proposal".into()),
    };
    FieldChoice {
        unbounded,
        proposal,
        field_reason,
        sampler_reason,
    }
}

/// The radius, in the field's normalised units, of the ball an unbounded
/// field keeps as it is: the ball around the scene box (the region the
/// cameras see in detail, which the loaders fit to the capture's points),
/// so that space beyond the box, the cameras' surroundings included, is
/// contracted.
pub fn contraction_radius(scene: &Scene) -> f32 {
    let corner = scene.scene_box.normalize_point(scene.scene_box.max);
    (corner[0] * corner[0] + corner[1] * corner[1] + corner[2] * corner[2]).sqrt() as f32
}

/// Sets the chosen field and sampler on the field's configuration `model`
/// (for `scene`). An occupancy grid asked for (`grid`) with an unbounded
/// field is refused: the grid covers the scene box, not contracted space.
pub fn apply(
    choice: &FieldChoice,
    model: &mut OpenNerfConfig,
    grid: bool,
    scene: &Scene,
) -> Result<(), TrainError> {
    if choice.unbounded && grid {
        return Err(TrainError::Config(format!(
            "the occupancy grid covers the scene box, and the field is unbounded ({}): \
             train without --occupancy-grid (and without occupancy.enabled in --config), \
             or with --field box",
            choice.field_reason
        )));
    }
    // Settings a --config file gave are kept.
    model.unbounded = match model.unbounded.take() {
        // A radius of 0 (a file that leaves it out) is the scene's.
        Some(mut given) if choice.unbounded => {
            if given.radius == 0.0 {
                given.radius = contraction_radius(scene);
            }
            given.start_at_box.get_or_insert(true);
            Some(given)
        }
        _ if choice.unbounded => {
            Some(UnboundedConfig::new(contraction_radius(scene)).with_start_at_box(Some(true)))
        }
        _ => None,
    };
    model.proposal = match model.proposal.take() {
        Some(given) if choice.proposal => Some(given),
        _ if choice.proposal => Some(ProposalConfig::new()),
        _ => None,
    };
    Ok(())
}

/// Where an unbounded field's rays start, in words (`None` for a box
/// field), for `train` to print.
pub fn ray_start(model: &OpenNerfConfig) -> Option<String> {
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

/// Checks the unbounded field's and the proposal sampler's settings; the
/// message names the offending key.
pub fn validate(model: &OpenNerfConfig) -> Result<(), String> {
    if let Some(u) = &model.unbounded {
        let positive = |k: &str, v: f32| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!(
                    "model.unbounded.{k} must be positive and finite, got {v}"
                ))
            }
        };
        positive("radius", u.radius)?;
        positive("near", u.near)?;
        positive("far", u.far)?;
        if u.far <= u.near {
            return Err(format!(
                "model.unbounded.far ({}) must be larger than model.unbounded.near ({})",
                u.far, u.near
            ));
        }
        // The frustum moments overflow f32 for intervals wider than ~4e9.
        if u.far * u.radius > 1e8 {
            return Err(format!(
                "model.unbounded.far x radius must be at most 1e8 normalised units, got {}",
                u.far * u.radius
            ));
        }
    }
    if let Some(p) = &model.proposal {
        if p.samples.is_empty() || p.samples.contains(&0) {
            return Err(format!(
                "model.proposal.samples must list at least one round of at least 1 sample, got {:?}",
                p.samples
            ));
        }
        if p.width == 0 || p.depth == 0 || p.max_deg <= p.min_deg {
            return Err(format!(
                "model.proposal needs width and depth of at least 1 and max_deg above min_deg, \
                 got width {}, depth {}, degrees {}..{}",
                p.width, p.depth, p.min_deg, p.max_deg
            ));
        }
        for (k, v) in [
            ("dilation_bias", p.dilation_bias),
            ("dilation_multiplier", p.dilation_multiplier),
            ("anneal_slope", p.anneal_slope),
            ("resample_padding", p.resample_padding),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!(
                    "model.proposal.{k} must be finite and non-negative, got {v}"
                ));
            }
        }
    }
    Ok(())
}
