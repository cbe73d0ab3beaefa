//! The external extractor: a command run on a directory of images.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};

use super::{FeatureExtractor, check_image};
use crate::error::DatasetError;
use crate::features::FeatureMap;
use crate::npy::NpyInfo;
use crate::scene::RgbImage;

/// Runs an external extractor: `program args... <input_dir> <output_dir>`.
/// The images are written as `<name>.png` into `input_dir`; the command must
/// write `<name>.npy` (`H x W x D`, float16 or float32) into `output_dir`.
#[derive(Debug, Clone, PartialEq)]
pub struct CommandExtractor {
    /// The program to run.
    pub program: PathBuf,
    /// Arguments before the two directories.
    pub args: Vec<String>,
    /// Expected feature dimension D.
    pub dim: usize,
}

/// Distinguishes the scratch directories of concurrent calls.
static SCRATCH_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A scratch directory removed on drop.
struct Scratch(PathBuf);

impl Scratch {
    fn new() -> Result<Self, DatasetError> {
        let n = SCRATCH_COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("opennerf-extract-{}-{n}", std::process::id()));
        for sub in ["in", "out"] {
            std::fs::create_dir_all(dir.join(sub)).map_err(|e| DatasetError::io(&dir, e))?;
        }
        Ok(Self(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        // Best effort: a leftover scratch directory is harmless.
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Writes an RGB image in `[0, 1]` as an 8-bit PNG.
pub fn save_png(image: &RgbImage, path: &Path) -> Result<(), DatasetError> {
    check_image(image)?;
    crate::imageio::save_rgb8(path, image.width, image.height, &image.to_u8())
}

impl CommandExtractor {
    /// An extractor running `program args...` and expecting `dim` channels.
    pub fn new(program: impl Into<PathBuf>, args: Vec<String>, dim: usize) -> Self {
        Self {
            program: program.into(),
            args,
            dim,
        }
    }

    /// Runs the command once on several named images and reads the maps back
    /// in the same order.
    pub fn extract_many(
        &self,
        images: &[(&str, &RgbImage)],
    ) -> Result<Vec<FeatureMap>, DatasetError> {
        let scratch = Scratch::new()?;
        let (input, output) = (scratch.0.join("in"), scratch.0.join("out"));
        for (name, image) in images {
            save_png(image, &input.join(format!("{name}.png")))?;
        }
        let result = Command::new(&self.program)
            .args(&self.args)
            .arg(&input)
            .arg(&output)
            .output()
            .map_err(|e| {
                DatasetError::invalid(
                    &self.program,
                    format!("cannot run the extractor command: {e}"),
                )
            })?;
        if !result.status.success() {
            return Err(DatasetError::invalid(
                &self.program,
                format!(
                    "extractor command failed ({}): {}",
                    result.status,
                    String::from_utf8_lossy(&result.stderr).trim()
                ),
            ));
        }
        images
            .iter()
            .map(|(name, image)| self.read_map(&output.join(format!("{name}.npy")), image))
            .collect()
    }

    /// Reads and validates one output map.
    fn read_map(&self, path: &Path, image: &RgbImage) -> Result<FeatureMap, DatasetError> {
        if !path.is_file() {
            return Err(DatasetError::invalid(
                path,
                "the extractor command wrote no feature map here",
            ));
        }
        let info = NpyInfo::open(path)?;
        info.expect_rank(3, "height x width x dim")?;
        let (h, w, d) = (info.shape[0], info.shape[1], info.shape[2]);
        if d != self.dim
            || h == 0
            || w == 0
            || h > image.height as usize
            || w > image.width as usize
        {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "feature map {h}x{w}x{d} does not fit a {}x{} image with dim {}",
                    image.height, image.width, self.dim
                ),
            ));
        }
        let data = info.read_f16_range(0, h * w * d)?;
        if data.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::invalid(
                path,
                "feature map contains NaN or infinite values",
            ));
        }
        Ok(FeatureMap {
            width: w as u32,
            height: h as u32,
            dim: d,
            data,
        })
    }
}

impl FeatureExtractor for CommandExtractor {
    fn dim(&self) -> usize {
        self.dim
    }

    fn extract(&self, image: &RgbImage) -> Result<FeatureMap, DatasetError> {
        self.extract_many(&[("image", image)])?
            .pop()
            .ok_or_else(|| DatasetError::invalid(&self.program, "no feature map returned"))
    }

    /// One run of the command for every image (`image_0000.png`, ...).
    fn extract_batch(&self, images: &[&RgbImage]) -> Result<Vec<FeatureMap>, DatasetError> {
        if images.is_empty() {
            return Ok(Vec::new());
        }
        let names: Vec<String> = (0..images.len()).map(|i| format!("image_{i:04}")).collect();
        let named: Vec<(&str, &RgbImage)> = names
            .iter()
            .map(String::as_str)
            .zip(images.iter().copied())
            .collect();
        self.extract_many(&named)
    }

    /// One run of the command for every image; the maps it wrote are then
    /// handed on in order.
    fn extract_each(
        &self,
        images: &[&RgbImage],
        each: &mut dyn FnMut(FeatureMap) -> Result<(), DatasetError>,
    ) -> Result<(), DatasetError> {
        for map in self.extract_batch(images)? {
            each(map)?;
        }
        Ok(())
    }
}
