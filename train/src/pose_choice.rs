//! Whether a run refines each training photograph's camera pose with the
//! field (`--pose-refine`, see `model::pose`), and why. `train` prints the
//! choice and why.

use datasets::Scene;
use model::{OpenNerfConfig, PoseCorrectionConfig};

/// Whether the training cameras' poses are refined (`--pose-refine`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum PoseRefineArg {
    /// `off`, unless the `--config` file asks for `model.pose`: on the
    /// captures measured it did not lift the held-out views
    /// (docs/measurements/unbounded.md).
    #[default]
    Auto,
    /// The poses as the capture gives them.
    Off,
    /// A rotation about its centre and a shift of its centre for each
    /// training photograph, learned with the field.
    On,
}

/// Whether a run refines its poses, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoseChoice {
    /// A learned correction per training photograph.
    pub refine: bool,
    /// Why, in words.
    pub reason: String,
}

impl PoseChoice {
    /// The one-line message `train` prints.
    pub fn message(&self) -> String {
        if self.refine {
            format!(
                "camera poses: refined with the field, training photographs only; held-out and \
                 novel views keep their poses ({})",
                self.reason
            )
        } else {
            format!("camera poses: as given ({})", self.reason)
        }
    }
}

/// Chooses from the flag (`None`: not given, `auto`) and the configuration
/// (`model` as `--config` and the presets left it).
pub fn choose(arg: Option<PoseRefineArg>, model: &OpenNerfConfig) -> PoseChoice {
    let (refine, reason) = match arg.unwrap_or_default() {
        PoseRefineArg::Auto if model.pose.is_some() => {
            (true, "auto: the configuration's model.pose".to_string())
        }
        PoseRefineArg::Auto => (
            false,
            "auto: not measured to lift held-out views (docs/measurements/unbounded.md)"
                .to_string(),
        ),
        PoseRefineArg::Off => (false, "--pose-refine off".into()),
        PoseRefineArg::On => (true, "--pose-refine on".into()),
    };
    PoseChoice { refine, reason }
}

/// Sets `model.pose` as `choice` says, with a correction for each of
/// `scene`'s frames (only training frames' rays reach theirs).
pub fn apply(choice: &PoseChoice, model: &mut OpenNerfConfig, scene: &Scene) {
    model.pose = choice
        .refine
        .then(|| PoseCorrectionConfig::new(scene.frames.len()));
}
