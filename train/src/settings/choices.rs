//! The settings a run decides per capture, each with who decided it: the
//! capture kind's row, a preset, the `--config` file or a flag, laid over
//! each other in that order (the last one that says something wins).

use datasets::capture_kind::CaptureKind;

use super::args::{AppearanceArg, FieldArg, FieldModelArg, HashGridArg, PoseRefineArg, SamplerArg};
use super::table::{Appearance, Extent, FieldModel, Row, Sampler};
use crate::cli::Cli;
use crate::preset::Preset;

/// Who decided a setting.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum By {
    /// The capture kind's row of the defaults table, for this reason.
    Kind(CaptureKind, &'static str),
    /// Every row of the defaults table alike, for this reason.
    EveryKind(&'static str),
    /// A preset.
    Preset(Preset),
    /// The `--config` file, through this key.
    File(&'static str),
    /// A flag, as typed (`--field box`).
    Flag(String),
}

impl By {
    /// The reason as the printed lines give it, in brackets.
    pub fn reason(&self) -> String {
        match self {
            By::Kind(kind, why) => format!("auto: {}: {why}", kind.describe()),
            By::EveryKind(why) => format!("auto: {why}"),
            By::Preset(p) => format!("preset {}", p.name()),
            By::File(key) => format!("auto: the configuration's {key}"),
            By::Flag(flag) => flag.clone(),
        }
    }
}

/// A value and who decided it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decided<T> {
    /// The value.
    pub value: T,
    /// Who decided it.
    pub by: By,
}

/// What one layer says; `None` leaves a setting to the layers below.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Layer {
    /// What gives density and colour.
    pub model: Option<Decided<FieldModel>>,
    /// The field's extent.
    pub extent: Option<Decided<Extent>>,
    /// The sampler.
    pub sampler: Option<Decided<Sampler>>,
    /// The appearance model.
    pub appearance: Option<Decided<Appearance>>,
    /// The hash encoding.
    pub hash: Option<Decided<bool>>,
    /// Pose refinement.
    pub pose: Option<Decided<bool>>,
    /// The occupancy grid.
    pub grid: Option<Decided<bool>>,
}

/// Every setting decided.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Choices {
    /// What gives density and colour.
    pub model: Decided<FieldModel>,
    /// The field's extent.
    pub extent: Decided<Extent>,
    /// The sampler a layer chose; `None` leaves it to the field model
    /// ([`Choices::sampler`]).
    pub chosen_sampler: Option<Decided<Sampler>>,
    /// The appearance model.
    pub appearance: Decided<Appearance>,
    /// The hash encoding.
    pub hash: Decided<bool>,
    /// Pose refinement.
    pub pose: Decided<bool>,
    /// The occupancy grid.
    pub grid: Decided<bool>,
    /// The samples of the fast field's two proposal rounds (the capture
    /// kind's; a `--config` file's `model.proposal.samples` changes them).
    pub fast_rounds: Decided<[usize; 2]>,
}

fn decided<T>(value: T, by: By) -> Option<Decided<T>> {
    Some(Decided { value, by })
}

impl Choices {
    /// The row's settings.
    pub fn of_row(row: &Row) -> Self {
        let by = |why| By::Kind(row.kind, why);
        Self {
            model: Decided {
                value: row.model,
                by: by(row.model_why),
            },
            extent: Decided {
                value: row.extent,
                by: by(row.extent_why),
            },
            chosen_sampler: None,
            appearance: Decided {
                value: row.appearance,
                by: by(row.photographs_why),
            },
            hash: Decided {
                value: row.hash,
                by: by(if row.hash {
                    row.photographs_why
                } else {
                    super::table::NOT_MEASURED
                }),
            },
            pose: Decided {
                value: false,
                by: By::EveryKind(super::table::POSE_WHY),
            },
            grid: Decided {
                value: false,
                by: By::EveryKind("off unless a preset or --occupancy-grid asks for it"),
            },
            fast_rounds: Decided {
                value: row.fast_rounds,
                by: by(row.fast_rounds_why),
            },
        }
    }

    /// The sampler: the one a layer chose, else the field model's own (the
    /// fast field's hash-grid proposal networks, the Mip-NeRF field's
    /// coarse and fine levels of its MLP).
    pub fn sampler(&self) -> Decided<Sampler> {
        self.chosen_sampler
            .clone()
            .unwrap_or(match self.model.value {
                FieldModel::Fast => Decided {
                    value: Sampler::Proposal,
                    by: By::EveryKind(super::table::FAST_SAMPLER_WHY),
                },
                FieldModel::Mip => Decided {
                    value: Sampler::CoarseFine,
                    by: By::EveryKind(super::table::SAMPLER_WHY),
                },
            })
    }

    /// These choices with what `layer` says laid over them.
    pub fn overlaid(self, layer: Layer) -> Self {
        Self {
            model: layer.model.unwrap_or(self.model),
            extent: layer.extent.unwrap_or(self.extent),
            chosen_sampler: layer.sampler.or(self.chosen_sampler),
            appearance: layer.appearance.unwrap_or(self.appearance),
            hash: layer.hash.unwrap_or(self.hash),
            pose: layer.pose.unwrap_or(self.pose),
            grid: layer.grid.unwrap_or(self.grid),
            fast_rounds: self.fast_rounds,
        }
    }
}

impl Layer {
    /// What a preset says: the occupancy grid (where the field is a box:
    /// `train` leaves it off an unbounded field).
    pub fn of_preset(p: Preset) -> Self {
        Self {
            grid: decided(true, By::Preset(p)),
            ..Self::default()
        }
    }

    /// What a `--config` file says, from the keys it gives (a key set to
    /// `null` says "off").
    pub fn of_file(patch: &serde_json::Value) -> Self {
        let model = &patch["model"];
        let key = |k: &str| model.as_object().and_then(|m| m.get(k));
        let on = |k: &str| key(k).map(|v| !v.is_null());
        let file = By::File;
        let appearance = match (on("exposure"), on("appearance")) {
            (Some(true), _) => decided(Appearance::Exposure, file("model.exposure")),
            (_, Some(true)) => decided(Appearance::Embedding, file("model.appearance")),
            (Some(false), _) => decided(Appearance::None, file("model.exposure")),
            (_, Some(false)) => decided(Appearance::None, file("model.appearance")),
            _ => None,
        };
        Self {
            model: on("fast").and_then(|f| {
                let m = if f { FieldModel::Fast } else { FieldModel::Mip };
                decided(m, file("model.fast"))
            }),
            extent: on("unbounded").and_then(|u| {
                let e = if u { Extent::Unbounded } else { Extent::Box };
                decided(e, file("model.unbounded"))
            }),
            sampler: on("proposal").and_then(|p| {
                let s = if p {
                    Sampler::Proposal
                } else {
                    Sampler::CoarseFine
                };
                decided(s, file("model.proposal"))
            }),
            appearance,
            hash: on("hash").and_then(|h| decided(h, file("model.hash"))),
            pose: on("pose").and_then(|p| decided(p, file("model.pose"))),
            grid: patch["occupancy"]["enabled"]
                .as_bool()
                .and_then(|g| decided(g, file("occupancy.enabled"))),
        }
    }

    /// What the flags say (`auto` and flags left out say nothing).
    pub fn of_flags(flags: &Flags) -> Self {
        let flag = |name: &str, value: &str| By::Flag(format!("--{name} {value}"));
        Self {
            model: match flags.field_model {
                FieldModelArg::Auto => None,
                FieldModelArg::Mip => decided(FieldModel::Mip, flag("field-model", "mip")),
                FieldModelArg::Fast => decided(FieldModel::Fast, flag("field-model", "fast")),
            },
            extent: match flags.field {
                FieldArg::Auto => None,
                FieldArg::Box => decided(Extent::Box, flag("field", "box")),
                FieldArg::Unbounded => decided(Extent::Unbounded, flag("field", "unbounded")),
            },
            sampler: match flags.sampler {
                SamplerArg::Auto => None,
                SamplerArg::CoarseFine => {
                    decided(Sampler::CoarseFine, flag("sampler", "coarse-fine"))
                }
                SamplerArg::Proposal => decided(Sampler::Proposal, flag("sampler", "proposal")),
            },
            appearance: match flags.appearance {
                AppearanceArg::Auto => None,
                AppearanceArg::None => decided(Appearance::None, flag("appearance", "none")),
                AppearanceArg::Exposure => {
                    decided(Appearance::Exposure, flag("appearance", "exposure"))
                }
                AppearanceArg::Embedding => {
                    decided(Appearance::Embedding, flag("appearance", "embedding"))
                }
            },
            hash: match flags.hash_grid.unwrap_or_default() {
                HashGridArg::Auto => None,
                HashGridArg::Off => decided(false, flag("hash-grid", "off")),
                HashGridArg::On => decided(true, flag("hash-grid", "on")),
            },
            pose: match flags.pose_refine.unwrap_or_default() {
                PoseRefineArg::Auto => None,
                PoseRefineArg::Off => decided(false, flag("pose-refine", "off")),
                PoseRefineArg::On => decided(true, flag("pose-refine", "on")),
            },
            grid: flags.occupancy_grid.then(|| Decided {
                value: true,
                by: By::Flag("--occupancy-grid".into()),
            }),
        }
    }
}

/// The flags that decide per-capture settings.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Flags {
    /// `--field-model`.
    pub field_model: FieldModelArg,
    /// `--field`.
    pub field: FieldArg,
    /// `--sampler`.
    pub sampler: SamplerArg,
    /// `--appearance`.
    pub appearance: AppearanceArg,
    /// `--hash-grid`.
    pub hash_grid: Option<HashGridArg>,
    /// `--pose-refine`.
    pub pose_refine: Option<PoseRefineArg>,
    /// `--occupancy-grid`.
    pub occupancy_grid: bool,
}

impl Flags {
    /// The flags of the command line.
    pub fn of_cli(cli: &Cli) -> Self {
        Self {
            field_model: cli.field_model,
            field: cli.field,
            sampler: cli.sampler,
            appearance: cli.appearance,
            hash_grid: cli.hash_grid,
            pose_refine: cli.pose_refine,
            occupancy_grid: cli.occupancy_grid,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_file_says_what_its_keys_give_and_null_is_off() {
        let l = Layer::of_file(&json!({
            "model": {"unbounded": null, "exposure": {"frames": 3}, "hash": {"levels": 4}},
            "occupancy": {"enabled": true}
        }));
        assert_eq!(l.extent.map(|d| d.value), Some(Extent::Box));
        assert_eq!(l.appearance.map(|d| d.value), Some(Appearance::Exposure));
        assert_eq!(
            l.hash.map(|d| (d.value, d.by)),
            Some((true, By::File("model.hash")))
        );
        assert_eq!(l.grid.map(|d| d.value), Some(true));
        assert_eq!(l.sampler, None);
        assert_eq!(l.pose, None);
        assert_eq!(Layer::of_file(&json!({"seed": 3})), Layer::default());
    }

    #[test]
    fn the_last_layer_that_says_something_wins() {
        let row = super::super::table::row(CaptureKind::PhotographedObject);
        let file = Layer::of_file(&json!({"model": {"hash": null}}));
        let flags = Layer::of_flags(&Flags {
            field: FieldArg::Box,
            ..Flags::default()
        });
        let c = Choices::of_row(&row).overlaid(file).overlaid(flags);
        assert_eq!(c.extent.value, Extent::Box);
        assert_eq!(c.extent.by.reason(), "--field box");
        assert!(!c.hash.value);
        assert_eq!(c.hash.by.reason(), "auto: the configuration's model.hash");
        // What nobody overrode stays the row's.
        assert_eq!(c.appearance.value, Appearance::Embedding);
        assert_eq!(
            c.sampler(),
            Decided {
                value: Sampler::CoarseFine,
                by: By::EveryKind(super::super::table::SAMPLER_WHY)
            },
            "the Mip-NeRF field keeps its sampler"
        );
        assert!(
            c.appearance
                .by
                .reason()
                .starts_with("auto: a photographed object walked around:")
        );
    }

    #[test]
    fn the_fast_field_takes_its_proposal_networks_unless_a_layer_chose_a_sampler() {
        let row = super::super::table::row(CaptureKind::Room);
        let fast = Layer::of_flags(&Flags {
            field_model: FieldModelArg::Fast,
            ..Flags::default()
        });
        let c = Choices::of_row(&row).overlaid(fast.clone()).sampler();
        assert_eq!(c.value, Sampler::Proposal);
        assert!(c.by.reason().contains("proposal networks"), "{c:?}");
        let flag = Layer::of_flags(&Flags {
            field_model: FieldModelArg::Fast,
            sampler: SamplerArg::CoarseFine,
            ..Flags::default()
        });
        let file = Layer::of_file(&json!({"model": {"proposal": null}}));
        for chosen in [
            Choices::of_row(&row).overlaid(flag),
            Choices::of_row(&row).overlaid(file).overlaid(fast),
        ] {
            let c = chosen.sampler();
            assert_eq!(c.value, Sampler::CoarseFine, "{c:?}");
        }
    }
}
