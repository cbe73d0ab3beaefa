//! The common scene type every loader returns, and the frames it holds.

use std::borrow::Cow;

use model::geometry::{Camera, SceneBox};

use crate::grid::nearest_pixel;
use crate::options::LoaderOptions;

/// An RGB image with values in `[0, 1]`, row-major `[height, width, 3]`,
/// stored as its source gave it: 8-bit where it came from an 8-bit file
/// (a quarter of the memory of floats, which a capture of hundreds of
/// frames needs), floats where it was rendered or composited.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height * width * 3` values.
    pub data: RgbData,
}

/// The values of an [`RgbImage`].
#[derive(Debug, Clone, PartialEq)]
pub enum RgbData {
    /// 8-bit values, `v / 255` each.
    U8(Vec<u8>),
    /// Values in `[0, 1]`.
    F32(Vec<f32>),
}

impl RgbImage {
    /// An image of float values in `[0, 1]`.
    pub fn from_f32(width: u32, height: u32, data: Vec<f32>) -> Self {
        Self {
            width,
            height,
            data: RgbData::F32(data),
        }
    }

    /// An image of 8-bit values.
    pub fn from_u8(width: u32, height: u32, data: Vec<u8>) -> Self {
        Self {
            width,
            height,
            data: RgbData::U8(data),
        }
    }

    /// Number of values (`3 * width * height` in a well-formed image).
    pub fn len(&self) -> usize {
        match &self.data {
            RgbData::U8(v) => v.len(),
            RgbData::F32(v) => v.len(),
        }
    }

    /// Whether the image holds no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value `i` of the row-major `[height, width, 3]` array, in `[0, 1]`.
    pub fn value(&self, i: usize) -> f32 {
        match &self.data {
            RgbData::U8(v) => f32::from(v[i]) / 255.0,
            RgbData::F32(v) => v[i],
        }
    }

    /// Every value in `[0, 1]`, row-major `[height, width, 3]` (borrowed
    /// when they are floats already).
    pub fn to_f32(&self) -> Cow<'_, [f32]> {
        match &self.data {
            RgbData::U8(v) => v.iter().map(|&b| f32::from(b) / 255.0).collect(),
            RgbData::F32(v) => Cow::Borrowed(v),
        }
    }

    /// Every value as a byte (`round(255 v)`, clamped), row-major
    /// (borrowed when they are bytes already).
    pub fn to_u8(&self) -> Cow<'_, [u8]> {
        match &self.data {
            RgbData::U8(v) => Cow::Borrowed(v),
            RgbData::F32(v) => v
                .iter()
                .map(|&x| (x.clamp(0.0, 1.0) * 255.0).round() as u8)
                .collect(),
        }
    }

    /// Bytes the values take in memory.
    pub fn memory_bytes(&self) -> usize {
        match &self.data {
            RgbData::U8(v) => v.len(),
            RgbData::F32(v) => 4 * v.len(),
        }
    }

    /// Colour of pixel `(x, y)`.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        match &self.data {
            RgbData::U8(v) => [v[i], v[i + 1], v[i + 2]].map(|b| f32::from(b) / 255.0),
            RgbData::F32(v) => [v[i], v[i + 1], v[i + 2]],
        }
    }

    /// Colour at image point `(u, v)` of an `image_width x image_height`
    /// camera (pixel centres at integers): the nearest pixel after scaling
    /// to this image's size.
    pub fn lookup(&self, u: f64, v: f64, image_width: u32, image_height: u32) -> [f32; 3] {
        let (x, y) = nearest_pixel(u, v, (image_width, image_height), (self.width, self.height));
        self.get(x, y)
    }
}

/// A depth map in metres (z-depth), row-major `[height, width]`; `0` marks
/// pixels without a valid measurement. Stored as 32-bit floats, or as
/// half floats where the loader compacts it ([`DepthImage::to_half`]: a
/// phone's LiDAR depth, whose centimetre accuracy half floats keep to
/// within 2 mm up to 8 m).
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height * width` depths; `0` = invalid.
    pub data: DepthData,
}

/// The values of a [`DepthImage`].
#[derive(Debug, Clone, PartialEq)]
pub enum DepthData {
    /// 32-bit floats.
    F32(Vec<f32>),
    /// Half floats.
    F16(Vec<half::f16>),
}

impl DepthImage {
    /// A depth map of 32-bit floats.
    pub fn from_f32(width: u32, height: u32, data: Vec<f32>) -> Self {
        Self {
            width,
            height,
            data: DepthData::F32(data),
        }
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        match &self.data {
            DepthData::F32(v) => v.len(),
            DepthData::F16(v) => v.len(),
        }
    }

    /// Whether the map holds no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value `i` of the row-major map (0 when invalid).
    pub fn value(&self, i: usize) -> f32 {
        match &self.data {
            DepthData::F32(v) => v[i],
            DepthData::F16(v) => v[i].to_f32(),
        }
    }

    /// Depth of pixel `(x, y)` (0 when invalid).
    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.value(y as usize * self.width as usize + x as usize)
    }

    /// Every value as a 32-bit float, row-major (borrowed when they are
    /// 32-bit already).
    pub fn to_f32(&self) -> Cow<'_, [f32]> {
        match &self.data {
            DepthData::F32(v) => Cow::Borrowed(v),
            DepthData::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
        }
    }

    /// The values as 32-bit floats to change in place (a half-float map
    /// is widened first).
    pub fn values_mut(&mut self) -> &mut Vec<f32> {
        if let DepthData::F16(v) = &self.data {
            self.data = DepthData::F32(v.iter().map(|h| h.to_f32()).collect());
        }
        match &mut self.data {
            DepthData::F32(v) => v,
            DepthData::F16(_) => unreachable!("widened above"),
        }
    }

    /// The map stored as half floats (values rounded to the nearest).
    pub fn to_half(self) -> Self {
        let data = match self.data {
            DepthData::F32(v) => DepthData::F16(v.into_iter().map(half::f16::from_f32).collect()),
            half @ DepthData::F16(_) => half,
        };
        Self { data, ..self }
    }

    /// Bytes the values take in memory.
    pub fn memory_bytes(&self) -> usize {
        match &self.data {
            DepthData::F32(v) => 4 * v.len(),
            DepthData::F16(v) => 2 * v.len(),
        }
    }
}

/// One posed view.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Name used for output files (e.g. `frame000010`).
    pub name: String,
    /// Intrinsics (at the image's resolution) and camera-to-world pose (OpenCV).
    pub camera: Camera,
    /// Colour image.
    pub rgb: RgbImage,
    /// Sensor (or rendered) depth, when the capture has it.
    pub depth: Option<DepthImage>,
    /// Weight of this frame's depth in the depth loss (1 for sensor depth,
    /// less for depth rendered by the field itself).
    pub depth_weight: f32,
    /// Weight of this frame's colour in the colour loss (1 for captured
    /// colour; novel views rendered by the field itself may carry less).
    pub color_weight: f32,
    /// Per-pixel class index (synthetic scenes only; `u16::MAX` = none).
    pub labels: Option<Vec<u16>>,
    /// Pixels that may be training targets, row-major `[height, width]` at
    /// the colour image's size (`None`: all of them). Masked-out pixels
    /// (e.g. a moving person, the capture rig) are never sampled.
    pub mask: Option<Vec<bool>>,
}

impl Frame {
    /// A captured frame: its colour and depth weigh 1 in the losses, it
    /// has no class labels and every pixel may be a target.
    pub fn captured(
        name: String,
        camera: Camera,
        rgb: RgbImage,
        depth: Option<DepthImage>,
    ) -> Self {
        Self {
            name,
            camera,
            rgb,
            depth,
            depth_weight: 1.0,
            color_weight: 1.0,
            labels: None,
            mask: None,
        }
    }

    /// Whether pixel `(x, y)` may be a training target: its [`Frame::mask`]
    /// allows it (every pixel does without a mask).
    pub fn is_target_pixel(&self, x: u32, y: u32) -> bool {
        self.mask.as_ref().is_none_or(|m| {
            m.get(y as usize * self.rgb.width as usize + x as usize)
                .copied()
                .unwrap_or(false)
        })
    }
}

/// How a scene can be rebuilt (saved in a run directory as `scene.json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SceneSource {
    /// The built-in generated scene.
    Synthetic {
        /// Generator seed.
        seed: u64,
        /// Size preset (`ci` or `bench`).
        size: String,
        /// Compression of the feature maps (`None`: the size preset's).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        pca: Option<crate::features::PcaSetting>,
    },
    /// A dataset on disk: `{"kind": "disk", "format": ..., "options": ...,
    /// "path": ...}`.
    Disk {
        /// The format and its loader options (stride, resolution, ...).
        #[serde(flatten)]
        loader: LoaderOptions,
        /// Scene directory.
        path: std::path::PathBuf,
    },
    /// Another scene with its feature maps (and class embeddings) taken from
    /// a directory instead: maps a vision-language model made for it.
    WithFeatures {
        /// The scene the maps belong to (its own maps, if any, are dropped).
        base: Box<SceneSource>,
        /// `<frame name>.npy` per frame (`H x W x D`), and `classes.npy` +
        /// `classes.txt` when the base scene has classes.
        features: std::path::PathBuf,
        /// Compression of the maps.
        pca: crate::features::PcaSetting,
        /// How the maps were made, when a model of this toolkit made them.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vlm: Option<VlmSource>,
    },
}

/// The vision-language model that made a scene's feature maps.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VlmSource {
    /// The CLIP model directory (both towers).
    pub model: std::path::PathBuf,
    /// The dense variant of its last block.
    pub dense: model::dense_variant::DenseVariant,
    /// Short side images were resized to, in pixels.
    pub short_side: usize,
}

impl SceneSource {
    /// The scene under any feature overlay.
    pub fn base(&self) -> &SceneSource {
        match self {
            Self::WithFeatures { base, .. } => base.base(),
            other => other,
        }
    }

    /// The model that made the maps, for a scene whose maps a
    /// vision-language model of this toolkit made.
    pub fn vlm(&self) -> Option<&VlmSource> {
        match self {
            Self::WithFeatures { vlm, .. } => vlm.as_ref(),
            _ => None,
        }
    }

    /// The scene's kind for names and messages: `synthetic` or the format
    /// on disk by its command-line name (`replica`, `blender`, `llff`,
    /// `scanner-app`, ...).
    pub fn kind_name(&self) -> &'static str {
        match self {
            Self::WithFeatures { base, .. } => base.kind_name(),
            Self::Synthetic { .. } => "synthetic",
            Self::Disk { loader, .. } => loader.format().name(),
        }
    }
}

/// A loaded scene: posed frames, optional feature maps (one per frame, in the
/// same order), the scene box and, when known, a labelled point cloud.
#[derive(Clone)]
pub struct Scene {
    /// Human-readable name.
    pub name: String,
    /// Frames in capture order.
    pub frames: Vec<Frame>,
    /// Per-frame feature maps, possibly PCA-compressed (see [`crate::features`]).
    pub features: Option<crate::features::FeatureSet>,
    /// Box enclosing cameras and geometry.
    pub scene_box: SceneBox,
    /// Background colour composited behind the field (`None` = none, e.g. rooms).
    pub background: Option<[f32; 3]>,
    /// Surface point cloud, with labels when known.
    pub points: Option<crate::points::PointCloud>,
    /// Class names and text embeddings that go with `points`' labels.
    pub classes: Option<crate::text::TextEmbeddings>,
    /// How to rebuild this scene.
    pub source: SceneSource,
    /// The capture's own world frame, when the loader moved the scene out
    /// of it (e.g. COLMAP's arbitrary frame, oriented, centred and scaled).
    pub world: Option<WorldFrame>,
}

/// A capture's own world frame and the map from it to the scene's frame
/// (the one every pose, point and output of the run is in).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WorldFrame {
    /// Name of the capture's frame (`colmap`, `nerfstudio`).
    pub name: String,
    /// `p_scene = scale * R p_capture + t`.
    pub to_scene: model::geometry::Similarity,
    /// What the map was fitted to, in words (empty when the capture gave
    /// it, and in runs written before this was recorded).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub fitted_to: String,
}

/// What a run directory records about its scene (`scene.json`): enough to
/// rebuild it and to map the field's outputs back to world units and to the
/// full feature space.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SceneMeta {
    /// How to rebuild the scene.
    pub source: SceneSource,
    /// The box the field's coordinates are normalised into.
    pub scene_box: SceneBox,
    /// Background colour, if the scene has one.
    pub background: Option<[f32; 3]>,
    /// PCA basis when the feature targets were compressed (the head then
    /// predicts `k` coefficients; lift with it before comparing with text).
    pub pca: Option<crate::features::PcaBasis>,
    /// Dimension of the original feature space (D).
    pub feature_dim: Option<usize>,
    /// The capture's own world frame, when the scene was moved out of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub world: Option<WorldFrame>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cell of the second grid whose span (in the first grid's pixel
    /// units) contains the point, found by scanning every cell.
    fn brute_force(u: f64, (fw, _): (u32, u32), tw: u32) -> u32 {
        let edge = u + 0.5; // distance from the image's left edge
        (0..tw)
            .find(|&x| {
                let (lo, hi) = (
                    x as f64 * fw as f64 / tw as f64,
                    (x + 1) as f64 * fw as f64 / tw as f64,
                );
                edge >= lo && edge < hi
            })
            .unwrap_or(if edge < 0.0 { 0 } else { tw - 1 })
    }

    #[test]
    fn nearest_pixel_is_the_cell_under_the_point_and_clamps() {
        for (from, to) in [
            ((320, 180), (80, 45)),
            ((40, 22), (160, 90)),
            ((7, 5), (3, 2)),
        ] {
            for i in -3..(4 * from.0 as i32 + 3) {
                let u = i as f64 / 4.0 - 0.5;
                let v = u.min(from.1 as f64);
                let (x, y) = nearest_pixel(u, v, from, to);
                assert_eq!(x, brute_force(u, from, to.0), "u {u}, {from:?} -> {to:?}");
                assert_eq!(y, brute_force(v, (from.1, 0), to.1), "v {v}");
            }
        }
        let img = RgbImage::from_f32(2, 1, vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        // Pixel 3 of an 8-wide camera lies in the first half of the image.
        assert_eq!(img.lookup(3.0, 0.0, 8, 4), [0.1, 0.2, 0.3]);
        assert_eq!(img.lookup(4.0, 3.0, 8, 4), [0.4, 0.5, 0.6]);
    }
}
