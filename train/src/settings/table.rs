//! The defaults of each kind of capture: one row per
//! [`CaptureKind`], one column per setting, each with the page that
//! measured it. `train` lays a preset, the `--config` file and the flags
//! over the row of the capture it loaded.

use datasets::capture_kind::CaptureKind;

use crate::preset::SceneKind;

/// What gives density and colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldModel {
    /// The Mip-NeRF MLP.
    Mip,
    /// The fast field: hash grids and small MLPs.
    Fast,
}

/// Why a row keeps the Mip-NeRF MLP.
pub const FIELD_MODEL_WHY: &str = "the paper's field; the fast field is not yet measured better on any kind of capture \
     (docs/measurements/fast-field.md)";

/// The field's extent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extent {
    /// The scene box mapped to `[-pi, pi]^3`.
    Box,
    /// Mip-NeRF 360's contraction beyond the ball around the scene box.
    Unbounded,
}

/// Where the MLP's samples are placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampler {
    /// Mip-NeRF's coarse and fine level of the one MLP.
    CoarseFine,
    /// Mip-NeRF 360's proposal rounds, then the MLP.
    Proposal,
}

/// How the photographs' appearance is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Appearance {
    /// One exposure for every photograph.
    None,
    /// A learned gain and offset per training photograph.
    Exposure,
    /// A learned code per training photograph.
    Embedding,
}

/// One row of the table: what a kind of capture trains with unless told
/// otherwise, and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// The capture kind.
    pub kind: CaptureKind,
    /// What gives density and colour.
    pub model: FieldModel,
    /// Why this field model.
    pub model_why: &'static str,
    /// The field's extent.
    pub extent: Extent,
    /// Why this extent.
    pub extent_why: &'static str,
    /// Samples per ray and level (`None`: the built-in 48).
    pub samples: Option<usize>,
    /// Rays per batch (`None`: the built-in 256).
    pub rays: Option<usize>,
    /// Why these sizes (when the row sets any).
    pub sizes_why: &'static str,
    /// The fast field's samples per ray (`None`: as the Mip-NeRF field's,
    /// `samples`): fewer where its proposal networks place them well enough.
    pub fast_samples: Option<usize>,
    /// Why the fast field's samples (when the row sets them).
    pub fast_samples_why: &'static str,
    /// The samples of the fast field's two proposal rounds.
    pub fast_rounds: [usize; 2],
    /// Why these rounds.
    pub fast_rounds_why: &'static str,
    /// The appearance model.
    pub appearance: Appearance,
    /// The hash encoding beside the IPE.
    pub hash: bool,
    /// Why these appearance and hash settings.
    pub photographs_why: &'static str,
    /// Which settings of a `--preset` apply.
    pub preset: SceneKind,
}

impl Row {
    /// The samples per ray this row sets for a field `model` sampled by
    /// `sampler` (`None`: the built-in number): the fast field's own where
    /// its proposal networks place them, the row's otherwise.
    pub fn samples_for(&self, model: FieldModel, sampler: Sampler) -> Option<usize> {
        match (model, sampler) {
            (FieldModel::Fast, Sampler::Proposal) => self.fast_samples.or(self.samples),
            _ => self.samples,
        }
    }

    /// Why this row's sizes for a field `model` sampled by `sampler`.
    pub fn sizes_why_for(&self, model: FieldModel, sampler: Sampler) -> &'static str {
        match (model, sampler, self.fast_samples) {
            (FieldModel::Fast, Sampler::Proposal, Some(_)) => self.fast_samples_why,
            _ => self.sizes_why,
        }
    }
}

/// The fast field's proposal rounds where fewer samples were measured
/// better.
pub const FEWER_ROUNDS: [usize; 2] = [32, 16];

/// Why [`FEWER_ROUNDS`].
pub const FEWER_ROUNDS_WHY: &str = "more iterations in the same seconds: above rounds of 64 and 32 on \
     lego at 120 s and on the statue and fern at 600 s, level on the cup \
     (docs/measurements/fast-field.md)";

/// Why every row keeps the coarse and fine sampler for the Mip-NeRF field.
pub const SAMPLER_WHY: &str = "more accurate and faster than the proposal sampler at these sizes";

/// Why the fast field takes its proposal networks unless told otherwise.
pub const FAST_SAMPLER_WHY: &str = "the fast field's hash-grid proposal networks, above its coarse and \
     fine levels on lego and the bench room in equal seconds \
     (docs/measurements/fast-field.md)";

/// Why every row keeps the poses as given.
pub const POSE_WHY: &str = "not measured to lift held-out views (docs/measurements/unbounded.md)";

/// Why a row leaves a setting off.
pub const NOT_MEASURED: &str = "not measured to help this capture";

/// The row of `kind`.
pub fn row(kind: CaptureKind) -> Row {
    let plain = Row {
        kind,
        model: FieldModel::Mip,
        model_why: FIELD_MODEL_WHY,
        extent: Extent::Box,
        extent_why: "",
        samples: None,
        rays: None,
        sizes_why: "",
        fast_samples: None,
        fast_samples_why: "",
        fast_rounds: FEWER_ROUNDS,
        fast_rounds_why: FEWER_ROUNDS_WHY,
        appearance: Appearance::None,
        hash: false,
        photographs_why: NOT_MEASURED,
        preset: SceneKind::Object,
    };
    match kind {
        CaptureKind::RenderedObject => Row {
            extent_why: "its region is known and nothing lies past it",
            photographs_why: "renders, at one exposure",
            ..plain
        },
        CaptureKind::PhotographedObject => Row {
            extent: Extent::Unbounded,
            extent_why: "the unbounded field, its rays from the scene box, measured above the box \
                         (docs/measurements/unbounded.md)",
            fast_samples: Some(24),
            fast_samples_why: "the fast field's proposal networks place 24 samples well enough: \
                               more iterations in the same seconds lifted the statue and the \
                               cup at 600 s (docs/measurements/fast-field.md)",
            appearance: Appearance::Embedding,
            hash: true,
            photographs_why: "appearance codes and the hash encoding lifted the held-out views \
                              of the statue and the cup at 600 s \
                              (docs/measurements/real-capture-defaults.md)",
            ..plain
        },
        CaptureKind::Room => Row {
            extent_why: "the cameras stand inside its box",
            fast_rounds: [64, 32],
            fast_rounds_why: "rounds of 32 and 16 lowered the bench room's held-out PSNR at 300 s \
                              (docs/measurements/fast-field.md)",
            preset: SceneKind::Room,
            ..plain
        },
        CaptureKind::ForwardFacing => Row {
            extent_why: "the unbounded field measured level with the box \
                         (docs/measurements/unbounded.md)",
            samples: Some(16),
            sizes_why: "more iterations in the same seconds fit it better, \
                        docs/measurements/fern.md",
            hash: true,
            photographs_why: "the hash encoding lifted the held-out views of fern, the statue \
                              and the cup at 600 s, appearance codes not fern's \
                              (docs/measurements/real-capture-defaults.md)",
            preset: SceneKind::Room,
            ..plain
        },
        CaptureKind::OpenScene => Row {
            model_why: "the paper's field: the fast field ends above it in colour and mIoU on \
                        three synthetic open scenes at 120 s but its median depth further off \
                        on two of them (docs/measurements/fast-field.md)",
            extent: Extent::Unbounded,
            fast_rounds: [64, 32],
            fast_rounds_why: "no open scene measured with fewer (docs/measurements/fast-field.md)",
            extent_why: "its content reaches far past the box (docs/measurements/unbounded.md)",
            ..plain
        },
    }
}

/// The table as Markdown: one row per kind, the sizes as `train` uses
/// them (the built-in 48 samples and 256 rays where a row keeps them).
pub fn markdown() -> String {
    let mut s = String::from(
        "| capture kind | field model | field | sampler | samples per ray and level | the fast \
         field's proposal rounds | the fast field's samples per ray | rays a batch | appearance | \
         hash grid | preset settings |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for kind in CaptureKind::ALL {
        let r = row(kind);
        s.push_str(&format!(
            "| {} | {} | {} | coarse-fine | {} | {} and {} | {} | {} | {} | {} | {} |\n",
            kind.describe(),
            match r.model {
                FieldModel::Mip => "mip",
                FieldModel::Fast => "fast",
            },
            match r.extent {
                Extent::Box => "box",
                Extent::Unbounded => "unbounded",
            },
            r.samples.unwrap_or(48),
            r.fast_rounds[0],
            r.fast_rounds[1],
            r.samples_for(FieldModel::Fast, Sampler::Proposal)
                .unwrap_or(48),
            r.rays.unwrap_or(256),
            match r.appearance {
                Appearance::None => "none",
                Appearance::Exposure => "exposure",
                Appearance::Embedding => "codes",
            },
            if r.hash { "on" } else { "off" },
            r.preset.name(),
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table in the reference docs is the one `train` uses.
    #[test]
    fn the_documented_table_is_the_one_in_use() {
        let table = markdown();
        println!("{table}");
        let page = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../docs/reference/capture-defaults.md"
        );
        let text = std::fs::read_to_string(page).expect("the reference page");
        assert!(
            text.contains(&table),
            "docs/reference/capture-defaults.md lacks the table train uses:\n{table}"
        );
    }

    #[test]
    fn every_row_says_why_it_differs_from_the_built_in_settings() {
        for kind in CaptureKind::ALL {
            let r = row(kind);
            assert!(!r.extent_why.is_empty(), "{kind:?}");
            assert!(r.model_why.contains("docs/"), "{kind:?}");
            if r.samples.is_some() || r.rays.is_some() {
                assert!(r.sizes_why.contains("docs/"), "{kind:?}");
            }
            if r.fast_samples.is_some() {
                assert!(r.fast_samples_why.contains("docs/"), "{kind:?}");
            }
            assert!(r.fast_rounds_why.contains("docs/"), "{kind:?}");
            if r.appearance != Appearance::None || r.hash {
                assert!(r.photographs_why.contains("docs/"), "{kind:?}");
            }
        }
    }
}
