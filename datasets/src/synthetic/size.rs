//! The synthetic scene's size presets.

use std::fmt;
use std::str::FromStr;

use crate::error::DatasetError;
use crate::features::PcaSetting;

/// Size presets of the synthetic scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SceneSize {
    /// About 20 views at 96x54: builds in well under a second, for tests.
    #[cfg_attr(
        feature = "cli",
        value(help = "Small: what the tests and the default run use")
    )]
    #[default]
    Ci,
    /// 200 views at 320x180, for benchmark runs.
    #[cfg_attr(feature = "cli", value(help = "Larger, for benchmarks"))]
    Bench,
    /// The paper's Replica setting: 200 views at 640x360 (the camera path of
    /// [`SceneSize::Bench`]) with 768-D feature maps at a quarter of the
    /// image resolution (160x90, what OpenNeRF's own code caches).
    #[cfg_attr(
        feature = "cli",
        value(
            help = "The paper's Replica scale: 200 views at 640x360, 768-D feature maps at 160x90"
        )
    )]
    Paper,
    /// [`SceneSize::Paper`] with the feature maps at the full 640x360.
    #[cfg_attr(
        feature = "cli",
        value(help = "As `paper`, with the feature maps at the full 640x360")
    )]
    PaperFull,
    /// Not a room: objects on a ground plane seen by a ring of 24 cameras
    /// at 80x60, with pillars around them and a backdrop 12 m away
    /// ([`super::outdoor::build_outdoor`]), an unbounded capture at the size of
    /// [`SceneSize::Ci`].
    #[cfg_attr(
        feature = "cli",
        value(
            help = "Not a room: a table, a chair and a plant seen from a ring of 24 cameras \
                      at 80x60, pillars 4.5 to 7 m around them and a backdrop 12 m away (an \
                      unbounded capture; `--field auto` contracts it)"
        )
    )]
    Outdoor,
}

impl SceneSize {
    /// `(views, width, height)` of the preset.
    pub fn views(self) -> (usize, u32, u32) {
        match self {
            SceneSize::Ci => (20, 96, 54),
            SceneSize::Outdoor => (24, 80, 60),
            SceneSize::Bench => (200, 320, 180),
            SceneSize::Paper | SceneSize::PaperFull => (200, 640, 360),
        }
    }

    /// Surface points per square metre and minimum candidates per box face.
    pub(crate) fn point_density(self) -> (f64, usize) {
        match self {
            SceneSize::Ci => (30.0, 3),
            // The backdrop's faces are large: a sparse cloud on them.
            SceneSize::Outdoor => (1.0, 6),
            SceneSize::Bench | SceneSize::Paper | SceneSize::PaperFull => (250.0, 8),
        }
    }

    /// PCA compression of the feature targets when none is chosen (off for
    /// the small preset).
    pub fn default_pca(self) -> PcaSetting {
        match self {
            SceneSize::Ci | SceneSize::Outdoor => PcaSetting::Off,
            SceneSize::Bench | SceneSize::Paper | SceneSize::PaperFull => PcaSetting::Auto,
        }
    }

    /// Dimension of the simulated feature maps: that of the class text
    /// embeddings, or 768 at the paper's scale (the embeddings lifted by
    /// [`super::lift::lift_embeddings`]).
    pub fn feature_dim(self) -> Option<usize> {
        match self {
            SceneSize::Ci | SceneSize::Bench | SceneSize::Outdoor => None,
            SceneSize::Paper | SceneSize::PaperFull => Some(PAPER_FEATURE_DIM),
        }
    }

    /// Image pixels per feature-map pixel along each axis.
    pub fn feature_downsample(self) -> u32 {
        match self {
            SceneSize::Ci | SceneSize::Bench | SceneSize::Paper | SceneSize::Outdoor => 4,
            SceneSize::PaperFull => 1,
        }
    }
}

/// Feature dimension of the paper-scale presets (that of OpenNeRF's
/// OpenSeg features).
pub const PAPER_FEATURE_DIM: usize = 768;

impl fmt::Display for SceneSize {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SceneSize::Ci => "ci",
            SceneSize::Bench => "bench",
            SceneSize::Paper => "paper",
            SceneSize::PaperFull => "paper-full",
            SceneSize::Outdoor => "outdoor",
        })
    }
}

impl FromStr for SceneSize {
    type Err = DatasetError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "ci" => Ok(SceneSize::Ci),
            "bench" => Ok(SceneSize::Bench),
            "paper" => Ok(SceneSize::Paper),
            "paper-full" => Ok(SceneSize::PaperFull),
            "outdoor" => Ok(SceneSize::Outdoor),
            other => Err(DatasetError::invalid(
                "<synthetic scene>",
                format!(
                    "unknown size {other:?} (expected \"ci\", \"bench\", \"paper\", \"paper-full\" or \"outdoor\")"
                ),
            )),
        }
    }
}
