//! 2D feature extractors: the trait the pipeline calls on colour images
//! (training frames and rendered novel views), the simulated VLM used by the
//! synthetic scene, and an adapter that runs an external command.

use half::f16;

mod command;

pub use command::{CommandExtractor, save_png};

use crate::error::DatasetError;
use crate::features::FeatureMap;
use crate::numeric::{hash01, normalized};
use crate::scene::RgbImage;
use crate::text::TextEmbeddings;

/// A pixel-aligned open-vocabulary feature extractor.
pub trait FeatureExtractor {
    /// Channels of the maps it produces.
    fn dim(&self) -> usize;
    /// The feature map of one colour image (possibly at a lower resolution).
    fn extract(&self, image: &RgbImage) -> Result<FeatureMap, DatasetError>;
    /// The feature maps of several images, in their order. An extractor
    /// with a start-up cost pays it once here (a command runs once for all
    /// of them, a model loads once); the default extracts one at a time.
    fn extract_batch(&self, images: &[&RgbImage]) -> Result<Vec<FeatureMap>, DatasetError> {
        images.iter().map(|image| self.extract(image)).collect()
    }
    /// Hands the feature map of each image to `each`, in order, as it is
    /// made: a caller that compresses maps then holds one full-dimensional
    /// map at a time, not all of them. The default extracts one image at a
    /// time; an extractor with a start-up cost runs one batch
    /// ([`FeatureExtractor::extract_batch`]) and hands its maps on.
    fn extract_each(
        &self,
        images: &[&RgbImage],
        each: &mut dyn FnMut(FeatureMap) -> Result<(), DatasetError>,
    ) -> Result<(), DatasetError> {
        for image in images {
            each(self.extract(image)?)?;
        }
        Ok(())
    }
}

/// Checks that an image's buffer matches its size.
fn check_image(image: &RgbImage) -> Result<(), DatasetError> {
    let n = image.width as usize * image.height as usize * 3;
    if image.width == 0 || image.height == 0 || image.len() != n {
        return Err(DatasetError::invalid(
            "<image>",
            format!(
                "{}x{} image with {} values (expected {n})",
                image.width,
                image.height,
                image.len()
            ),
        ));
    }
    Ok(())
}

/// A simulated pixel-aligned VLM (deterministic in the colour image only):
///
/// 1. sees the image at `1 / downsample` resolution (area average, then a
///    3x3 blur), so small or far objects smear into their surroundings;
/// 2. turns each colour into class probabilities by its distance to per-class
///    colour prototypes (similar-looking classes get confused), with logit
///    noise hashed from the pixel position and colour;
/// 3. mixes the class text embeddings with those probabilities (so the
///    similarity structure between classes is that of the embeddings), adds
///    noise in a fixed random subspace (again hashed from position and
///    colour, so not multi-view consistent) and L2-normalises.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedExtractor {
    /// Class embeddings, rows L2-normalised, `C x D`.
    embeddings: TextEmbeddings,
    /// Expected image colour of each class, `C`.
    prototypes: Vec<[f32; 3]>,
    /// Log prior per class added to the colour logits, `C`.
    log_prior: Vec<f32>,
    /// Noise directions, `NOISE_DIRS x D`.
    noise_basis: Vec<f32>,
    /// Resolution reduction factor.
    downsample: u32,
    /// Width of the colour kernel (RGB distance).
    sigma: f32,
    /// Amplitude of the logit noise.
    logit_noise: f32,
    /// Norm of the feature-space noise relative to the unit class mixture.
    feature_noise: f32,
    /// Seed of the hashed noise.
    seed: u64,
}

/// Dimension of the feature-noise subspace.
const NOISE_DIRS: usize = 12;
/// Classes kept in each pixel's mixture (the rest are negligible).
const TOP_CLASSES: usize = 3;

impl SimulatedExtractor {
    /// An extractor for classes with these text `embeddings` and expected
    /// colours `prototypes` (one per class), seeded by `seed`.
    pub fn new(
        embeddings: TextEmbeddings,
        prototypes: Vec<[f32; 3]>,
        seed: u64,
    ) -> Result<Self, DatasetError> {
        if prototypes.len() != embeddings.len() || embeddings.is_empty() || embeddings.dim == 0 {
            return Err(DatasetError::invalid(
                "<extractor>",
                format!(
                    "{} colour prototypes for {} class embeddings of dim {}",
                    prototypes.len(),
                    embeddings.len(),
                    embeddings.dim
                ),
            ));
        }
        let dim = embeddings.dim;
        let data = embeddings
            .data
            .chunks_exact(dim)
            .flat_map(normalized)
            .collect();
        let embeddings = TextEmbeddings { data, ..embeddings };
        let noise_basis = (0..NOISE_DIRS)
            .flat_map(|j| {
                let v: Vec<f32> = (0..dim)
                    .map(|k| (hash01(seed ^ (((j * dim + k) as u64) << 8) ^ 0xfea7) - 0.5) as f32)
                    .collect();
                normalized(&v)
            })
            .collect();
        Ok(Self {
            log_prior: vec![0.0; prototypes.len()],
            embeddings,
            prototypes,
            noise_basis,
            downsample: 4,
            sigma: 0.06,
            logit_noise: 0.5,
            feature_noise: 0.25,
            seed,
        })
    }

    /// The same extractor with a log prior per class added to the colour
    /// logits (a real VLM favours classes that are common in its training
    /// data).
    pub fn with_log_prior(mut self, log_prior: Vec<f32>) -> Result<Self, DatasetError> {
        if log_prior.len() != self.prototypes.len() || log_prior.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::invalid(
                "<extractor>",
                format!(
                    "{} finite prior values needed, got {:?}",
                    self.prototypes.len(),
                    log_prior
                ),
            ));
        }
        self.log_prior = log_prior;
        Ok(self)
    }

    /// The same extractor seeing the image at `1 / downsample` resolution
    /// (1: full resolution), as extractors differ in the resolution of the
    /// maps they cache.
    pub fn with_downsample(mut self, downsample: u32) -> Result<Self, DatasetError> {
        if downsample == 0 {
            return Err(DatasetError::invalid(
                "<extractor>",
                "downsample factor must be at least 1",
            ));
        }
        self.downsample = downsample;
        Ok(self)
    }

    /// The class embeddings (rows L2-normalised) the features are mixed from.
    pub fn embeddings(&self) -> &TextEmbeddings {
        &self.embeddings
    }

    /// Resolution of the map for a `width x height` image.
    pub fn map_size(&self, width: u32, height: u32) -> (u32, u32) {
        (
            (width / self.downsample).max(1),
            (height / self.downsample).max(1),
        )
    }

    /// The low-resolution colour image the extractor "sees": area average
    /// onto the map grid, then a 3x3 binomial blur.
    ///
    /// # Shapes
    /// `[height, width, 3]` -> `[map_h, map_w, 3]`.
    pub fn perceived(&self, image: &RgbImage) -> Result<RgbImage, DatasetError> {
        check_image(image)?;
        let (w, h) = self.map_size(image.width, image.height);
        let (iw, ih) = (image.width as usize, image.height as usize);
        let mut avg = vec![0f32; (w * h * 3) as usize];
        for y in 0..h as usize {
            let (y0, y1) = (
                y * ih / h as usize,
                ((y + 1) * ih / h as usize).max(y * ih / h as usize + 1),
            );
            for x in 0..w as usize {
                let (x0, x1) = (
                    x * iw / w as usize,
                    ((x + 1) * iw / w as usize).max(x * iw / w as usize + 1),
                );
                let mut s = [0f32; 3];
                for yy in y0..y1 {
                    for xx in x0..x1 {
                        let c = image.get(xx as u32, yy as u32);
                        (0..3).for_each(|k| s[k] += c[k]);
                    }
                }
                let n = ((y1 - y0) * (x1 - x0)) as f32;
                let o = 3 * (y * w as usize + x);
                (0..3).for_each(|k| avg[o + k] = s[k] / n);
            }
        }
        let mut out = vec![0f32; avg.len()];
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let mut s = [0f32; 3];
                let mut wsum = 0f32;
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (xx, yy) = (x + dx, y + dy);
                        if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            continue;
                        }
                        let wt = ((2 - dx.abs()) * (2 - dy.abs())) as f32;
                        let o = 3 * (yy as usize * w as usize + xx as usize);
                        (0..3).for_each(|k| s[k] += wt * avg[o + k]);
                        wsum += wt;
                    }
                }
                let o = 3 * (y as usize * w as usize + x as usize);
                (0..3).for_each(|k| out[o + k] = s[k] / wsum);
            }
        }
        Ok(RgbImage::from_f32(w, h, out))
    }

    /// Class probabilities (top classes only, renormalised) of a perceived
    /// colour at map pixel `(x, y)`, as `(class, probability)` pairs.
    pub fn class_mixture(&self, color: [f32; 3], x: u32, y: u32) -> Vec<(usize, f32)> {
        let key = self.pixel_key(color, x, y);
        let inv = 1.0 / (2.0 * self.sigma * self.sigma);
        let mut logits: Vec<(usize, f32)> = self
            .prototypes
            .iter()
            .enumerate()
            .map(|(c, p)| {
                let d2: f32 = (0..3).map(|k| (color[k] - p[k]).powi(2)).sum();
                let noise = (hash01(key ^ (c as u64).wrapping_mul(0x2545_f491)) - 0.5) as f32;
                (
                    c,
                    -d2 * inv + self.log_prior[c] + 2.0 * self.logit_noise * noise,
                )
            })
            .collect();
        logits.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        logits.truncate(TOP_CLASSES);
        let top = logits[0].1;
        let mut sum = 0.0;
        for l in &mut logits {
            l.1 = (l.1 - top).exp();
            sum += l.1;
        }
        logits.iter().map(|&(c, p)| (c, p / sum)).collect()
    }

    /// Hash key of a map pixel's position and (8-bit quantised) colour.
    fn pixel_key(&self, color: [f32; 3], x: u32, y: u32) -> u64 {
        let q = color.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u64);
        let k = ((x as u64) << 48) ^ ((y as u64) << 32) ^ (q[0] << 16) ^ (q[1] << 8) ^ q[2];
        (hash01(k ^ self.seed.rotate_left(17)) * (1u64 << 53) as f64) as u64
    }
}

impl FeatureExtractor for SimulatedExtractor {
    fn dim(&self) -> usize {
        self.embeddings.dim
    }

    fn extract(&self, image: &RgbImage) -> Result<FeatureMap, DatasetError> {
        let seen = self.perceived(image)?;
        let dim = self.embeddings.dim;
        let mut data = Vec::with_capacity((seen.width * seen.height) as usize * dim);
        let mut f = vec![0f32; dim];
        for y in 0..seen.height {
            for x in 0..seen.width {
                let color = seen.get(x, y);
                f.iter_mut().for_each(|v| *v = 0.0);
                for (c, p) in self.class_mixture(color, x, y) {
                    f.iter_mut()
                        .zip(self.embeddings.row(c))
                        .for_each(|(v, e)| *v += p * e);
                }
                let key = self.pixel_key(color, x, y);
                for (j, dir) in self.noise_basis.chunks_exact(dim).enumerate() {
                    // Uniform in [-1, 1] per direction, scaled so the noise
                    // vector's expected norm is `feature_noise`.
                    let a = (2.0 * hash01(key ^ ((j as u64 + 1) << 40)) - 1.0) as f32
                        * self.feature_noise
                        * (3.0 / NOISE_DIRS as f32).sqrt();
                    f.iter_mut().zip(dir).for_each(|(v, d)| *v += a * d);
                }
                let n = f.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-12);
                data.extend(f.iter().map(|v| f16::from_f32(v / n)));
            }
        }
        Ok(FeatureMap {
            width: seen.width,
            height: seen.height,
            dim,
            data,
        })
    }
}
