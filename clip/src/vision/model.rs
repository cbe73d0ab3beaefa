//! A CLIP vision tower loaded from a model directory, and dense feature
//! maps of whole images of any size: resized, normalised, cut into
//! overlapping windows of the model's input size, run in batches, averaged.

use std::path::{Path, PathBuf};

use crate::tower::resample::{antialiased_bilinear_weights, resample_chw};
use crate::tower::sliding::{WindowPlan, plan_windows};
use crate::tower::{ClipVisionConfig, ClipVisionEncoder, DenseVariant};
use burn::tensor::{Device, Tensor, TensorData};

use super::config::{ImageNorm, build_vision_config, hf_vision_options, open_clip_vision_options};
use super::layout::is_vision_tensor;
use crate::error::ClipError;
use crate::layout::Layout;
use crate::model_dir::weights_file;
use crate::tensors::TensorFile;

/// The short side images are resized to unless asked otherwise (at least
/// the model's input size): 336 px, as NACLIP evaluates most benchmarks.
pub const DEFAULT_SHORT_SIDE: usize = 336;

/// How dense maps are made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DenseOptions {
    /// The last block's variant.
    pub variant: DenseVariant,
    /// Short side after resizing, in pixels (`None`: [`DEFAULT_SHORT_SIDE`]
    /// or the model's input size, whichever is larger).
    pub short_side: Option<usize>,
    /// Windows run together.
    pub batch: usize,
}

impl Default for DenseOptions {
    fn default() -> Self {
        Self {
            variant: DenseVariant::Naclip,
            short_side: None,
            batch: 8,
        }
    }
}

/// A dense feature map: one unit vector per patch of the resized image.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseMap {
    /// Patch rows.
    pub rows: usize,
    /// Patch columns.
    pub cols: usize,
    /// Channels (the joint space's dimension).
    pub dim: usize,
    /// `rows * cols * dim` values.
    pub data: Vec<f32>,
}

/// A loaded vision tower.
#[derive(Debug)]
pub struct VisionModel {
    /// The directory it was loaded from.
    pub dir: PathBuf,
    /// Its weights file.
    pub weights: PathBuf,
    /// The encoder.
    pub encoder: ClipVisionEncoder,
    /// Its configuration.
    pub config: ClipVisionConfig,
    /// Pixel normalisation.
    pub norm: ImageNorm,
    /// Naming scheme of the weights.
    pub layout: Layout,
    /// What was assumed where the files were silent.
    pub notes: Vec<String>,
    device: Device,
}

impl VisionModel {
    /// Loads the vision tower of `dir` (Hugging Face or OpenCLIP naming)
    /// onto `device`.
    pub fn load(dir: &Path, device: &Device) -> Result<Self, ClipError> {
        let weights = weights_file(dir)?;
        let mut file = TensorFile::read(&weights, is_vision_tensor)?;
        let layout = Layout::detect_vision(&file)?;
        let sizes = layout.vision_sizes(&file)?;
        let options = match layout {
            Layout::HuggingFace => hf_vision_options(dir, &sizes)?,
            Layout::OpenClip => open_clip_vision_options(dir, &sizes)?,
        };
        let config = build_vision_config(&sizes, &options, &weights)?;
        let encoder = layout.build_vision(&mut file, &config, device)?;
        Ok(Self {
            dir: dir.to_path_buf(),
            weights,
            encoder,
            config,
            norm: options.norm,
            layout,
            notes: options.notes,
            device: device.clone(),
        })
    }

    /// A model made in memory (e.g. random weights of a real size for
    /// benchmarks), normalised with OpenAI's constants.
    pub fn from_encoder(
        encoder: ClipVisionEncoder,
        config: ClipVisionConfig,
        device: &Device,
    ) -> Self {
        Self {
            dir: PathBuf::from("<in memory>"),
            weights: PathBuf::from("<in memory>"),
            encoder,
            config,
            norm: ImageNorm {
                mean: super::config::OPENAI_MEAN,
                std: super::config::OPENAI_STD,
            },
            layout: Layout::HuggingFace,
            notes: Vec::new(),
            device: device.clone(),
        }
    }

    /// Output dimension.
    pub fn dim(&self) -> usize {
        self.config.embed_dim
    }

    /// The device it runs on.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// The short side `options` resize to for this model.
    pub fn short_side(&self, options: &DenseOptions) -> usize {
        options
            .short_side
            .unwrap_or(DEFAULT_SHORT_SIDE.max(self.config.image_size))
    }

    /// The windows of an `height x width` image.
    pub fn plan(
        &self,
        (height, width): (usize, usize),
        options: &DenseOptions,
    ) -> Result<WindowPlan, ClipError> {
        plan_windows(
            (height, width),
            self.short_side(options),
            self.config.image_size,
            self.config.patch_size,
        )
        .map_err(ClipError::Image)
    }

    /// The image resized to `plan.resized` (antialiased bilinear) and
    /// normalised.
    ///
    /// # Shapes
    /// - `rgb`: `[height, width, 3]` in `[0, 1]`; output: `[3, rows * p, cols * p]`.
    pub fn preprocess(
        &self,
        rgb: &[f32],
        (height, width): (usize, usize),
        plan: &WindowPlan,
    ) -> Vec<f32> {
        let n = height * width;
        let mut chw = vec![0f32; 3 * n];
        for (i, px) in rgb.chunks_exact(3).enumerate() {
            for c in 0..3 {
                chw[c * n + i] = px[c];
            }
        }
        let (h2, w2) = plan.resized;
        let mut out = resample_chw(
            &chw,
            3,
            (height, width),
            (h2, w2),
            &antialiased_bilinear_weights(height, h2),
            &antialiased_bilinear_weights(width, w2),
        );
        for (c, plane) in out.chunks_exact_mut(h2 * w2).enumerate() {
            let (m, s) = (self.norm.mean[c], self.norm.std[c]);
            plane.iter_mut().for_each(|v| *v = (*v - m) / s);
        }
        out
    }

    /// Dense features of normalised pixels whose sides are whole patches.
    ///
    /// # Shapes
    /// - `pixels`: `[batch, 3, h, w]` values; output: `[batch, h / p, w / p, dim]`.
    pub fn dense_pixels(
        &self,
        pixels: Vec<f32>,
        shape: [usize; 4],
        variant: DenseVariant,
    ) -> Result<Vec<f32>, ClipError> {
        let t = Tensor::<4>::from_data(TensorData::new(pixels, shape), &self.device);
        self.encoder
            .dense(t, variant)
            .try_into_vec_as::<f32>()
            .map_err(|e| ClipError::invalid(&self.weights, format!("cannot read features: {e:?}")))
    }

    /// Dense features of every window of `plan` over a preprocessed image,
    /// `options.batch` windows at a time.
    ///
    /// # Shapes
    /// - `image`: `[3, rows * p, cols * p]` (see [`VisionModel::preprocess`]);
    ///   output: `[windows, g, g, dim]`, `g` the window's patch grid.
    pub fn window_features(
        &self,
        image: &[f32],
        plan: &WindowPlan,
        options: &DenseOptions,
    ) -> Result<Vec<f32>, ClipError> {
        let (c, w2) = (plan.crop, plan.resized.1);
        let plane = plan.resized.0 * w2;
        let mut features = Vec::new();
        for origins in plan.origins.chunks(options.batch.max(1)) {
            let mut batch = Vec::with_capacity(origins.len() * 3 * c * c);
            for &(y0, x0) in origins {
                for ch in 0..3 {
                    for y in y0..y0 + c {
                        let row = ch * plane + y * w2;
                        batch.extend_from_slice(&image[row + x0..row + x0 + c]);
                    }
                }
            }
            features.extend(self.dense_pixels(batch, [origins.len(), 3, c, c], options.variant)?);
        }
        Ok(features)
    }

    /// The dense map of one `[height, width, 3]` image with values in `[0, 1]`.
    pub fn dense_map(
        &self,
        rgb: &[f32],
        (height, width): (usize, usize),
        options: &DenseOptions,
    ) -> Result<DenseMap, ClipError> {
        if rgb.len() != height * width * 3 {
            return Err(ClipError::Image(format!(
                "a {width}x{height} image needs {} values, got {}",
                height * width * 3,
                rgb.len()
            )));
        }
        let plan = self.plan((height, width), options)?;
        let image = self.preprocess(rgb, (height, width), &plan);
        let features = self.window_features(&image, &plan, options)?;
        Ok(DenseMap {
            rows: plan.grid.0,
            cols: plan.grid.1,
            dim: self.dim(),
            data: plan.assemble(&features, self.dim()),
        })
    }
}
