//! Whether a run learns each training photograph's exposure
//! (`--appearance exposure`, see `model::exposure`) or appearance code
//! (`--appearance embedding`, see `model::appearance`), and why. `train`
//! prints the choice and why.

use datasets::detect::Format;
use datasets::{Scene, SceneSource};
use model::{AppearanceCodesConfig, ExposureConfig, OpenNerfConfig};

/// How the photographs' appearance is modelled (`--appearance`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum AppearanceArg {
    /// `embedding` for a COLMAP capture with the unbounded field (measured
    /// to lift its held-out views), else `none`, unless the `--config` file
    /// asks for `model.exposure` or `model.appearance`.
    #[default]
    Auto,
    /// Every photograph is taken at the same exposure.
    None,
    /// A gain and an offset per colour channel for each training
    /// photograph, applied to its rays' colours in the training loss only.
    Exposure,
    /// A learned code per training photograph given to the colour branch
    /// (nerfacto's appearance embedding); every render uses the zero code.
    Embedding,
}

/// What a run models appearance with, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AppearanceChoice {
    /// A learned exposure per training photograph.
    pub exposure: bool,
    /// A learned appearance code per training photograph.
    pub embedding: bool,
    /// Why, in words.
    pub reason: String,
}

impl AppearanceChoice {
    /// The one-line message `train` prints.
    pub fn message(&self) -> String {
        let what = match (self.exposure, self.embedding) {
            (true, _) => "a learned exposure per photograph",
            (_, true) => {
                "a learned appearance code per photograph (held-out and novel views: the zero code)"
            }
            _ => "none",
        };
        format!("appearance: {what} ({})", self.reason)
    }
}

/// The capture a scene was made from, in words.
fn capture(scene: &Scene) -> String {
    match scene.source.base() {
        SceneSource::Synthetic { .. } => "a synthetic scene, rendered at one exposure".into(),
        SceneSource::Disk { loader, .. } => format!("a {} capture", loader.format()),
        SceneSource::WithFeatures { .. } => "a scene with its features".into(),
    }
}

/// Whether `scene` was loaded from a COLMAP reconstruction.
pub(crate) fn is_colmap(scene: &Scene) -> bool {
    matches!(scene.source.base(), SceneSource::Disk { loader, .. } if loader.format() == Format::Colmap)
}

/// Chooses from the flag and the configuration (`model` as `--config` and
/// the presets left it).
pub fn choose(arg: AppearanceArg, model: &OpenNerfConfig, scene: &Scene) -> AppearanceChoice {
    let ((exposure, embedding), reason) = match arg {
        AppearanceArg::Auto if model.exposure.is_some() => (
            (true, false),
            "auto: the configuration's model.exposure".to_string(),
        ),
        AppearanceArg::Auto if model.appearance.is_some() => (
            (false, true),
            "auto: the configuration's model.appearance".to_string(),
        ),
        AppearanceArg::Auto if model.unbounded.is_some() && is_colmap(scene) => (
            (false, true),
            "auto: a colmap capture with the unbounded field, where codes were measured to lift \
             the held-out views (docs/measurements/unbounded.md)"
                .to_string(),
        ),
        AppearanceArg::Auto => ((false, false), format!("auto: {}", capture(scene))),
        AppearanceArg::None => ((false, false), "--appearance none".into()),
        AppearanceArg::Exposure => ((true, false), "--appearance exposure".into()),
        AppearanceArg::Embedding => ((false, true), "--appearance embedding".into()),
    };
    AppearanceChoice {
        exposure,
        embedding,
        reason,
    }
}

/// Sets `model.exposure` and `model.appearance` as `choice` says, with a
/// correction or code for each of `scene`'s frames (the frames a run adds
/// later, novel views, get none); a code length the configuration gave is
/// kept.
pub fn apply(choice: &AppearanceChoice, model: &mut OpenNerfConfig, scene: &Scene) {
    let frames = scene.frames.len();
    model.exposure = choice.exposure.then(|| ExposureConfig::new(frames));
    let dim = model.appearance.as_ref().map(|a| a.dim);
    model.appearance = choice.embedding.then(|| {
        let codes = AppearanceCodesConfig::new(frames);
        match dim {
            Some(d) => codes.with_dim(d),
            None => codes,
        }
    });
}
