//! Loader options of the scene formats on disk, one type per format, and
//! [`LoaderOptions`]: a format with its options, as the
//! [`SceneSource`](crate::SceneSource) of a scene on disk records them.
//! What the formats share is one type each, flattened into their options:
//! [`FrameSelection`] (every format) and [`FeatureInput`] (the formats with
//! feature maps).

mod feature_input;
mod selection;

use serde::{Deserialize, Deserializer, Serialize};

use crate::detect::Format;
pub use feature_input::FeatureInput;
pub use selection::{FrameSelection, Resolution, parse_count};

/// A scene format with its loader options. Serialised adjacently tagged,
/// as the `format` and `options` keys of a disk scene's source
/// (`{"format": "replica", "options": {...}}`); `options` may be `null` or
/// leave fields out, which then take their defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "format", content = "options", rename_all = "snake_case")]
pub enum LoaderOptions {
    /// Nice-SLAM Replica ([`crate::replica`]).
    Replica(#[serde(deserialize_with = "null_as_default")] ReplicaOptions),
    /// Blender / nerfstudio ([`crate::blender`]).
    Blender(#[serde(deserialize_with = "null_as_default")] BlenderOptions),
    /// LLFF ([`crate::llff`]).
    Llff(#[serde(deserialize_with = "null_as_default")] LlffOptions),
    /// A COLMAP reconstruction ([`crate::colmap`]).
    Colmap(#[serde(deserialize_with = "null_as_default")] ColmapOptions),
    /// A ScanNet scene export ([`crate::scannet`]).
    Scannet(#[serde(deserialize_with = "null_as_default")] ScannetOptions),
    /// A 3D Scanner App "All Data" export ([`crate::phone::scanner`]).
    ScannerApp(#[serde(deserialize_with = "null_as_default")] PhoneOptions),
    /// A Record3D export, EXR + JPG or R3D ([`crate::phone::record3d`]).
    Record3d(#[serde(deserialize_with = "null_as_default")] PhoneOptions),
    /// A Polycam raw-data export ([`crate::phone::polycam`]).
    Polycam(#[serde(deserialize_with = "null_as_default")] PhoneOptions),
}

impl LoaderOptions {
    /// The scene box's margin, a fraction of its largest extent: every
    /// format has one.
    pub fn box_margin_mut(&mut self) -> &mut f64 {
        match self {
            Self::Replica(o) => &mut o.box_margin,
            Self::Blender(o) => &mut o.box_margin,
            Self::Llff(o) => &mut o.box_margin,
            Self::Colmap(o) => &mut o.box_margin,
            Self::Scannet(o) => &mut o.box_margin,
            Self::ScannerApp(o) | Self::Record3d(o) | Self::Polycam(o) => &mut o.box_margin,
        }
    }

    /// Which frames the loader keeps and at what size: every format has one.
    pub fn selection(&self) -> &FrameSelection {
        match self {
            Self::Replica(o) => &o.selection,
            Self::Blender(o) => &o.selection,
            Self::Llff(o) => &o.selection,
            Self::Colmap(o) => &o.selection,
            Self::Scannet(o) => &o.selection,
            Self::ScannerApp(o) | Self::Record3d(o) | Self::Polycam(o) => &o.selection,
        }
    }

    /// [`Self::selection`], to change.
    pub fn selection_mut(&mut self) -> &mut FrameSelection {
        match self {
            Self::Replica(o) => &mut o.selection,
            Self::Blender(o) => &mut o.selection,
            Self::Llff(o) => &mut o.selection,
            Self::Colmap(o) => &mut o.selection,
            Self::Scannet(o) => &mut o.selection,
            Self::ScannerApp(o) | Self::Record3d(o) | Self::Polycam(o) => &mut o.selection,
        }
    }

    /// The feature maps the loader attaches, `None` for a format that
    /// reads none (Blender, LLFF, ScanNet).
    pub fn feature_input(&self) -> Option<&FeatureInput> {
        match self {
            Self::Replica(o) => Some(&o.feature_input),
            Self::Colmap(o) => Some(&o.feature_input),
            Self::ScannerApp(o) | Self::Record3d(o) | Self::Polycam(o) => Some(&o.feature_input),
            Self::Blender(_) | Self::Llff(_) | Self::Scannet(_) => None,
        }
    }

    /// [`Self::feature_input`], to change.
    pub fn feature_input_mut(&mut self) -> Option<&mut FeatureInput> {
        match self {
            Self::Replica(o) => Some(&mut o.feature_input),
            Self::Colmap(o) => Some(&mut o.feature_input),
            Self::ScannerApp(o) | Self::Record3d(o) | Self::Polycam(o) => {
                Some(&mut o.feature_input)
            }
            Self::Blender(_) | Self::Llff(_) | Self::Scannet(_) => None,
        }
    }

    /// These options without a compression basis (not part of the saved
    /// options: a scene records its basis apart).
    pub fn without_basis(&self) -> Self {
        let mut o = self.clone();
        if let Some(input) = o.feature_input_mut() {
            input.basis = None;
        }
        o
    }

    /// The format these options load (its name, [`Format::name`], is the
    /// one the command line takes and messages use).
    pub fn format(&self) -> Format {
        match self {
            Self::Replica(_) => Format::Replica,
            Self::Blender(_) => Format::Blender,
            Self::Llff(_) => Format::Llff,
            Self::Colmap(_) => Format::Colmap,
            Self::Scannet(_) => Format::Scannet,
            Self::ScannerApp(_) => Format::ScannerApp,
            Self::Record3d(_) => Format::Record3d,
            Self::Polycam(_) => Format::Polycam,
        }
    }
}

/// Deserialises `null` as the type's default.
fn null_as_default<'de, D, T>(d: D) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Default,
{
    Ok(Option::<T>::deserialize(d)?.unwrap_or_default())
}

/// Options of the Replica loader ([`crate::replica::load_replica`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReplicaOptions {
    /// Frames kept (every `stride`-th of the trajectory; the paper uses
    /// 10) and their size (the paper uses 640x360).
    #[serde(flatten)]
    pub selection: FrameSelection,
    /// Feature maps, `frameNNNNNN.npy` (a stacked `.npy` or a directory).
    #[serde(flatten)]
    pub feature_input: FeatureInput,
    /// Scene-box margin, as a fraction of the largest extent.
    pub box_margin: f64,
    /// Depth pixels used for the box: every `box_pixel_step`-th in each axis.
    pub box_pixel_step: u32,
}

impl Default for ReplicaOptions {
    fn default() -> Self {
        Self {
            selection: FrameSelection::default(),
            feature_input: FeatureInput::default(),
            box_margin: 0.05,
            box_pixel_step: 8,
        }
    }
}

/// Options of the Blender loader ([`crate::blender::load_blender`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BlenderOptions {
    /// Transforms file name inside the scene directory; `None` tries
    /// `transforms.json`, then `transforms_train.json`.
    pub transforms: Option<String>,
    /// Integer downscale factor of the images (1 = full size).
    pub downscale: u32,
    /// Colour transparent pixels are composited over; also the scene's
    /// background.
    pub background: [f32; 3],
    /// Frames kept, in the transforms file's order (the size is
    /// [`Self::downscale`]'s: a resolution is refused).
    #[serde(flatten)]
    pub selection: FrameSelection,
    /// Box margin, as a fraction of its extent.
    pub box_margin: f64,
}

impl Default for BlenderOptions {
    fn default() -> Self {
        Self {
            transforms: None,
            downscale: 1,
            background: [1.0; 3],
            selection: FrameSelection::default(),
            box_margin: 0.05,
        }
    }
}

/// Options of the LLFF loader ([`crate::llff::load_llff`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LlffOptions {
    /// Image folder (`images_8`, `images_16`, `images`); `None` picks
    /// `images_8` if present, else the most downsampled `images_F`.
    pub images: Option<String>,
    /// Views kept, in image name order (the size is the image folder's: a
    /// resolution is refused).
    #[serde(flatten)]
    pub selection: FrameSelection,
    /// Box margin, as a fraction of its extent.
    pub box_margin: f64,
}

impl Default for LlffOptions {
    fn default() -> Self {
        Self {
            images: None,
            selection: FrameSelection::default(),
            box_margin: 0.05,
        }
    }
}

/// Options of the COLMAP loader ([`crate::colmap::load_colmap`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ColmapOptions {
    /// Image folder inside the reconstruction (`images`, or a downscaled
    /// copy such as `images_2`; intrinsics are scaled to its images' size).
    pub images: String,
    /// Use COLMAP's dense depth maps (`stereo/depth_maps/*.geometric.bin`)
    /// as depth targets (zero and NaN depths are no target).
    pub depth: bool,
    /// Use the sparse points as depth targets: each point's z-depth at the
    /// pixels of the features that observe it, no target elsewhere
    /// ([`crate::colmap::sparse_depth`]). Ignored with [`Self::depth`].
    pub sparse_depth: bool,
    /// Images kept, in name order (the size is [`Self::images`]' folder's:
    /// a resolution is refused).
    #[serde(flatten)]
    pub selection: FrameSelection,
    /// Scene-box margin, as a fraction of the largest extent.
    pub box_margin: f64,
    /// Feature maps, `<image stem>.npy` (a stacked `.npy` or a directory).
    #[serde(flatten)]
    pub feature_input: FeatureInput,
}

impl Default for ColmapOptions {
    fn default() -> Self {
        Self {
            images: "images".into(),
            depth: false,
            sparse_depth: false,
            selection: FrameSelection::default(),
            box_margin: 0.05,
            feature_input: FeatureInput::default(),
        }
    }
}

/// Options of the ScanNet loader ([`crate::scannet::load_scannet`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ScannetOptions {
    /// Frames kept (frames with invalid poses are skipped before the
    /// stride is applied) and the colour images' size [default: their own,
    /// 1296x968 for ScanNet].
    #[serde(flatten)]
    pub selection: FrameSelection,
    /// Scene-box margin, as a fraction of the largest extent.
    pub box_margin: f64,
    /// Depth pixels used for the box: every `box_pixel_step`-th in each axis.
    pub box_pixel_step: u32,
}

impl Default for ScannetOptions {
    fn default() -> Self {
        Self {
            selection: FrameSelection::default(),
            box_margin: 0.05,
            box_pixel_step: 8,
        }
    }
}

/// How sure ARKit is of a LiDAR depth pixel (its confidence map's levels).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum DepthConfidence {
    /// Level 0.
    #[cfg_attr(feature = "cli", value(help = "Every measured pixel"))]
    Low,
    /// Level 1.
    #[cfg_attr(feature = "cli", value(help = "Medium and high"))]
    Medium,
    /// Level 2, the default threshold: only what ARKit is sure of.
    #[cfg_attr(feature = "cli", value(help = "Only what ARKit is sure of"))]
    #[default]
    High,
}

impl DepthConfidence {
    /// The level in ARKit's confidence maps (0, 1 or 2).
    pub fn level(self) -> u8 {
        self as u8
    }

    /// The name on the command line (`low`, `medium`, `high`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Low => "low",
            Self::Medium => "medium",
            Self::High => "high",
        }
    }
}

/// Options of the phone-capture loaders ([`crate::phone`]): 3D Scanner
/// App, Record3D and Polycam.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PhoneOptions {
    /// Frames kept, in capture order, and the colour images' size
    /// [default: their own].
    #[serde(flatten)]
    pub selection: FrameSelection,
    /// Depth pixels less sure than this are no depth target.
    pub min_depth_confidence: DepthConfidence,
    /// Depth beyond this many metres (the LiDAR's range) is no target.
    pub max_depth: f64,
    /// Scene-box margin, as a fraction of the largest extent.
    pub box_margin: f64,
    /// Depth pixels used for the box and the point cloud of a capture
    /// without a mesh: every `box_pixel_step`-th in each axis.
    pub box_pixel_step: u32,
    /// Feature maps, `<frame name>.npy` (a stacked `.npy` or a directory).
    #[serde(flatten)]
    pub feature_input: FeatureInput,
}

/// The LiDAR's range on current iPhones and iPads, metres.
pub const PHONE_MAX_DEPTH: f64 = 5.0;

impl Default for PhoneOptions {
    fn default() -> Self {
        Self {
            selection: FrameSelection::default(),
            min_depth_confidence: DepthConfidence::High,
            max_depth: PHONE_MAX_DEPTH,
            box_margin: 0.05,
            box_pixel_step: 8,
            feature_input: FeatureInput::default(),
        }
    }
}
