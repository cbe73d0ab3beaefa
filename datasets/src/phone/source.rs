//! Where a phone capture's images, depth and confidence maps are read from,
//! and how each is decoded: files on disk (PNG, JPEG, EXR) or entries of an
//! archive, raw or LZFSE-compressed.

use std::path::{Path, PathBuf};

use crate::error::DatasetError;
use crate::imageio;
use crate::scene::{DepthImage, RgbImage};

pub mod decode;

/// An entry of a ZIP archive (a Record3D `.r3d` file's), read in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct ZipEntry {
    /// The archive.
    pub archive: PathBuf,
    /// The entry's name in it (e.g. `rgbd/3.jpg`).
    pub name: String,
}

impl ZipEntry {
    /// `archive:name`, as errors name the entry.
    pub fn describe(&self) -> PathBuf {
        decode::entry_path(&self.archive, &self.name)
    }

    /// The entry's bytes.
    pub fn read(&self) -> Result<Vec<u8>, DatasetError> {
        decode::read_zip_entry(&self.archive, &self.name)
    }
}

/// Where the bytes of a stored map come from.
#[derive(Debug, Clone, PartialEq)]
pub enum ByteSource {
    /// A file.
    File(PathBuf),
    /// An entry of a ZIP archive.
    Zip(ZipEntry),
}

impl ByteSource {
    /// The file, or the archive of an entry.
    pub fn path(&self) -> &Path {
        match self {
            Self::File(p) => p,
            Self::Zip(z) => &z.archive,
        }
    }

    /// The name errors give: the file, or `archive:entry`.
    pub fn describe(&self) -> PathBuf {
        match self {
            Self::File(p) => p.clone(),
            Self::Zip(z) => z.describe(),
        }
    }

    /// The bytes.
    pub fn read(&self) -> Result<Vec<u8>, DatasetError> {
        match self {
            Self::File(p) => std::fs::read(p).map_err(|e| DatasetError::io(p, e)),
            Self::Zip(z) => z.read(),
        }
    }

    /// The bytes, LZFSE-decompressed.
    fn read_lzfse(&self) -> Result<Vec<u8>, DatasetError> {
        decode::lzfse(&self.read()?, &self.describe())
    }
}

/// A colour image of a capture.
#[derive(Debug, Clone, PartialEq)]
pub enum ImageSource {
    /// A JPEG or PNG file.
    File(PathBuf),
    /// A JPEG or PNG entry of a ZIP archive.
    Zip(ZipEntry),
}

impl ImageSource {
    /// The path errors name (the archive of an entry: see
    /// [`ImageSource::describe`]).
    pub fn path(&self) -> &Path {
        match self {
            Self::File(p) => p,
            Self::Zip(z) => &z.archive,
        }
    }

    /// The file, or `archive:entry`.
    pub fn describe(&self) -> PathBuf {
        match self {
            Self::File(p) => p.clone(),
            Self::Zip(z) => z.describe(),
        }
    }

    /// Width and height of the image.
    pub fn dimensions(&self) -> Result<(u32, u32), DatasetError> {
        match self {
            Self::File(p) => imageio::dimensions(p),
            Self::Zip(z) => {
                let named = z.describe();
                image::ImageReader::new(std::io::Cursor::new(z.read()?))
                    .with_guessed_format()
                    .map_err(|e| DatasetError::io(&named, e))?
                    .into_dimensions()
                    .map_err(|e| {
                        DatasetError::invalid(&named, format!("cannot read image size: {e}"))
                    })
            }
        }
    }

    /// The image's sharpness ([`crate::sharpness::image_sharpness`]).
    pub fn sharpness(&self) -> Result<f64, DatasetError> {
        let img = match self {
            Self::File(p) => imageio::open(p)?,
            Self::Zip(z) => imageio::decode(z.read()?, &z.describe())?,
        };
        Ok(crate::sharpness::image_sharpness(&img))
    }

    /// The image as `[0, 1]` RGB, resampled to `size`.
    pub fn load_rgb(&self, size: (u32, u32)) -> Result<RgbImage, DatasetError> {
        match self {
            Self::File(p) => imageio::load_rgb(p, None, Some(size)),
            Self::Zip(z) => {
                let named = z.describe();
                let img = imageio::decode(z.read()?, &named)?;
                imageio::to_rgb(img, &named, None, Some(size))
            }
        }
    }
}

/// A depth map of a capture, in the colour camera's view at the depth
/// sensor's resolution.
#[derive(Debug, Clone, PartialEq)]
pub enum DepthSource {
    /// A 16-bit single-channel PNG in millimetres (0 = no depth).
    PngMillimetres(PathBuf),
    /// A float EXR in metres: its one channel, or the one named `Z`,
    /// `depth`, `Y` or `R`.
    Exr(PathBuf),
    /// An LZFSE stream of little-endian float32 metres, row-major.
    LzfseF32 {
        /// The compressed bytes.
        data: ByteSource,
        /// Width and height; when `None`, inferred from the length as one
        /// of [`decode::KNOWN_DEPTH_SIZES`].
        size: Option<(u32, u32)>,
    },
}

impl DepthSource {
    /// The path errors name (the archive of an entry: see
    /// [`DepthSource::describe`]).
    pub fn path(&self) -> &Path {
        match self {
            Self::PngMillimetres(p) | Self::Exr(p) => p,
            Self::LzfseF32 { data, .. } => data.path(),
        }
    }

    /// The file, or `archive:entry`.
    pub fn describe(&self) -> PathBuf {
        match self {
            Self::PngMillimetres(p) | Self::Exr(p) => p.clone(),
            Self::LzfseF32 { data, .. } => data.describe(),
        }
    }

    /// The depth map in metres; invalid values (0, negative, NaN,
    /// infinite) are 0.
    pub fn load(&self) -> Result<DepthImage, DatasetError> {
        let mut depth = match self {
            Self::PngMillimetres(p) => imageio::load_depth16(p, 1000.0, None)?,
            Self::Exr(p) => decode::exr_depth(p)?,
            Self::LzfseF32 { data, size } => {
                decode::f32_depth(&data.read_lzfse()?, *size, &data.describe())?
            }
        };
        for d in depth.values_mut() {
            if !(d.is_finite() && *d > 0.0) {
                *d = 0.0;
            }
        }
        Ok(depth)
    }
}

/// A confidence map of a capture: ARKit's levels 0 (low), 1 (medium) and
/// 2 (high), one per depth pixel.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfidenceSource {
    /// An 8-bit single-channel PNG of levels 0, 1, 2.
    Png(PathBuf),
    /// An 8-bit single-channel PNG of levels 0, 1, 2, or of the levels
    /// scaled to 0..255 (0, 127 or 128, 255), as some Polycam versions
    /// write them.
    PngScaled(PathBuf),
    /// An LZFSE stream of u8 levels 0, 1, 2, row-major.
    LzfseU8(ByteSource),
}

impl ConfidenceSource {
    /// The path errors name (the archive of an entry: see
    /// [`ConfidenceSource::describe`]).
    pub fn path(&self) -> &Path {
        match self {
            Self::Png(p) | Self::PngScaled(p) => p,
            Self::LzfseU8(data) => data.path(),
        }
    }

    /// The file, or `archive:entry`.
    pub fn describe(&self) -> PathBuf {
        match self {
            Self::Png(p) | Self::PngScaled(p) => p.clone(),
            Self::LzfseU8(data) => data.describe(),
        }
    }

    /// The levels, checked to be `size` and to hold only 0, 1 and 2.
    pub fn load(&self, size: (u32, u32)) -> Result<Vec<u8>, DatasetError> {
        let named = self.describe();
        let (levels, found) = match self {
            Self::Png(p) => luma8(p)?,
            Self::PngScaled(p) => {
                let (values, found) = luma8(p)?;
                (decode::unscaled_levels(values, p)?, found)
            }
            Self::LzfseU8(data) => (decode::u8_levels(data.read_lzfse()?, size, &named)?, size),
        };
        check_levels(&named, levels, found, size)
    }
}

/// The values and size of an 8-bit single-channel PNG.
fn luma8(p: &Path) -> Result<(Vec<u8>, (u32, u32)), DatasetError> {
    let img = imageio::open(p)?;
    let found = (img.width(), img.height());
    match img {
        image::DynamicImage::ImageLuma8(b) => Ok((b.into_raw(), found)),
        other => Err(DatasetError::invalid(
            p,
            format!(
                "confidence must be an 8-bit single-channel PNG, found {:?}",
                other.color()
            ),
        )),
    }
}

/// `levels` of a `found`-sized map, checked against the depth map's `size`
/// and ARKit's three levels.
pub(crate) fn check_levels(
    path: &Path,
    levels: Vec<u8>,
    found: (u32, u32),
    size: (u32, u32),
) -> Result<Vec<u8>, DatasetError> {
    if found != size {
        return Err(DatasetError::invalid(
            path,
            format!(
                "confidence map is {}x{} but its depth map is {}x{}",
                found.0, found.1, size.0, size.1
            ),
        ));
    }
    if let Some(bad) = levels.iter().find(|&&l| l > 2) {
        return Err(DatasetError::invalid(
            path,
            format!("confidence level {bad} is not one of ARKit's 0 (low), 1 (medium), 2 (high)"),
        ));
    }
    Ok(levels)
}
