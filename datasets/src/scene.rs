//! The common scene type every loader returns, and the frames it holds.

use half::f16;
use model::geometry::{Camera, SceneBox};

/// An RGB image with values in `[0, 1]`, row-major `[height, width, 3]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height * width * 3` values in `[0, 1]`.
    pub data: Vec<f32>,
}

impl RgbImage {
    /// Colour of pixel `(x, y)`.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// A depth map in metres (z-depth), row-major `[height, width]`; `0` marks
/// pixels without a valid measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height * width` depths; `0` = invalid.
    pub data: Vec<f32>,
}

impl DepthImage {
    /// Depth of pixel `(x, y)` (0 when invalid).
    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.data[y as usize * self.width as usize + x as usize]
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
    /// Per-pixel class index (synthetic scenes only; `u16::MAX` = none).
    pub labels: Option<Vec<u16>>,
}

/// A pixel-aligned feature map of one frame, row-major `[height, width, dim]`,
/// stored as `f16`. Its resolution may be lower than the frame's image.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMap {
    /// Map width.
    pub width: u32,
    /// Map height.
    pub height: u32,
    /// Channels per pixel (D, or k PCA coefficients).
    pub dim: usize,
    /// `height * width * dim` values.
    pub data: Vec<f16>,
}

impl FeatureMap {
    /// Feature vector at map pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> &[f16] {
        let i = (y as usize * self.width as usize + x as usize) * self.dim;
        &self.data[i..i + self.dim]
    }

    /// Feature at image point `(u, v)` of an `image_width x image_height`
    /// image (pixel centres at integers): nearest map pixel after scaling.
    pub fn lookup(&self, u: f64, v: f64, image_width: u32, image_height: u32) -> &[f16] {
        let sx = self.width as f64 / image_width as f64;
        let sy = self.height as f64 / image_height as f64;
        let x = (((u + 0.5) * sx).floor().max(0.0) as u32).min(self.width - 1);
        let y = (((v + 0.5) * sy).floor().max(0.0) as u32).min(self.height - 1);
        self.pixel(x, y)
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
    /// A dataset on disk.
    Disk {
        /// Format: `replica`, `blender` or `llff`.
        format: String,
        /// Scene directory.
        path: std::path::PathBuf,
        /// Loader options as given (stride, resolution, ...), format-specific.
        options: serde_json::Value,
    },
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
    pub pca: Option<crate::features::Pca>,
    /// Dimension of the original feature space (D).
    pub feature_dim: Option<usize>,
}
