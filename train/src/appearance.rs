//! Whether a run learns each training photograph's exposure
//! (`--appearance`, see `model::exposure`), and why. `train` prints the
//! choice and why.

use datasets::{Scene, SceneSource};
use model::{ExposureConfig, OpenNerfConfig};

/// How the photographs' appearance is modelled (`--appearance`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum AppearanceArg {
    /// `none`, unless the `--config` file asks for `model.exposure`.
    #[default]
    Auto,
    /// Every photograph is taken at the same exposure.
    None,
    /// A gain and an offset per colour channel for each training
    /// photograph, applied to its rays' colours in the training loss only.
    Exposure,
}

/// What a run models appearance with, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AppearanceChoice {
    /// A learned exposure per training photograph.
    pub exposure: bool,
    /// Why, in words.
    pub reason: String,
}

impl AppearanceChoice {
    /// The one-line message `train` prints.
    pub fn message(&self) -> String {
        let what = if self.exposure {
            "a learned exposure per photograph"
        } else {
            "none"
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

/// Chooses from the flag and the configuration (`model` as `--config` and
/// the presets left it).
pub fn choose(arg: AppearanceArg, model: &OpenNerfConfig, scene: &Scene) -> AppearanceChoice {
    let (exposure, reason) = match arg {
        AppearanceArg::Auto if model.exposure.is_some() => {
            (true, "auto: the configuration's model.exposure".to_string())
        }
        AppearanceArg::Auto => (false, format!("auto: {}", capture(scene))),
        AppearanceArg::None => (false, "--appearance none".into()),
        AppearanceArg::Exposure => (true, "--appearance exposure".into()),
    };
    AppearanceChoice { exposure, reason }
}

/// Sets `model.exposure` as `choice` says, with a correction for each of
/// `scene`'s frames (the frames a run adds later, novel views, get none).
pub fn apply(choice: &AppearanceChoice, model: &mut OpenNerfConfig, scene: &Scene) {
    model.exposure = choice
        .exposure
        .then(|| ExposureConfig::new(scene.frames.len()));
}
