//! Image decoding and resampling shared by the loaders.

use std::path::Path;

use image::imageops::FilterType;
use image::{DynamicImage, ImageBuffer, Rgb};

use crate::error::DatasetError;
use crate::scene::{DepthImage, RgbImage};

/// Decodes any supported image file.
pub fn open(path: &Path) -> Result<DynamicImage, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    decode(bytes, path)
}

/// Decodes an image file's bytes (read from `path`, or from an entry of an
/// archive that `path` names in errors).
pub fn decode(bytes: Vec<u8>, path: &Path) -> Result<DynamicImage, DatasetError> {
    if let Some(problem) = jpeg_truncation(&bytes) {
        return Err(DatasetError::invalid(path, problem));
    }
    image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| DatasetError::io(path, e))?
        .decode()
        .map_err(|e| DatasetError::invalid(path, format!("cannot decode image: {e}")))
}

/// Why a JPEG file is incomplete, if it is one and is. The decoder fills
/// the missing part of a truncated JPEG with grey without an error, so a
/// cut-off copy would otherwise be trained on as it is. The image data
/// follows the last start-of-scan marker (`FF DA`) and must be closed by an
/// end-of-image marker (`FF D9`); inside the entropy-coded data `FF` is
/// always followed by `00` or a restart marker, so no other `FF D9` occurs
/// there (an embedded thumbnail's markers come before the main scan).
pub fn jpeg_truncation(bytes: &[u8]) -> Option<String> {
    if !bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        return None;
    }
    let find_last = |marker: u8| bytes.windows(2).rposition(|w| w == [0xFF, marker]);
    let Some(scan) = find_last(0xDA) else {
        return Some("JPEG file has no image data (no start-of-scan marker; truncated?)".into());
    };
    match find_last(0xD9) {
        Some(end) if end > scan => None,
        _ => Some(format!(
            "JPEG file is truncated: its image data stops after {} bytes without an \
             end-of-image marker (copy the file again)",
            bytes.len()
        )),
    }
}

/// Loads a colour image as linear-in-file `[0, 1]` RGB, compositing any alpha
/// channel over `background` first (when `None`, alpha is dropped), then
/// resampling to `size` with a triangle filter whose support widens with the
/// downscale factor (an antialiasing area filter).
pub fn load_rgb(
    path: &Path,
    background: Option<[f32; 3]>,
    size: Option<(u32, u32)>,
) -> Result<RgbImage, DatasetError> {
    to_rgb(open(path)?, path, background, size)
}

/// [`load_rgb`] of an image already decoded (from `path`, named in errors).
/// An 8-bit image that needs no compositing (no background asked for, or
/// no transparent pixel) stays 8-bit, resampled in 8 bits; any other is
/// converted to floats first.
pub fn to_rgb(
    img: DynamicImage,
    path: &Path,
    background: Option<[f32; 3]>,
    size: Option<(u32, u32)>,
) -> Result<RgbImage, DatasetError> {
    let (w, h) = (img.width(), img.height());
    let resize = match size {
        Some((0, _)) | Some((_, 0)) => {
            return Err(DatasetError::invalid(path, "target resolution is zero"));
        }
        Some(s) if s != (w, h) => Some(s),
        _ => None,
    };
    if is_eight_bit(&img) && (background.is_none() || is_opaque(&img)) {
        let rgb = img.into_rgb8();
        let rgb = match resize {
            Some((tw, th)) => image::imageops::resize(&rgb, tw, th, FilterType::Triangle),
            None => rgb,
        };
        let (width, height) = rgb.dimensions();
        return Ok(RgbImage::from_u8(width, height, rgb.into_raw()));
    }
    let rgba = img.into_rgba32f();
    let mut rgb: ImageBuffer<Rgb<f32>, Vec<f32>> = ImageBuffer::new(w, h);
    for (dst, src) in rgb.pixels_mut().zip(rgba.pixels()) {
        let [r, g, b, a] = src.0;
        dst.0 = match background {
            Some(bg) => [
                r * a + bg[0] * (1.0 - a),
                g * a + bg[1] * (1.0 - a),
                b * a + bg[2] * (1.0 - a),
            ],
            None => [r, g, b],
        };
    }
    let rgb = match resize {
        Some((tw, th)) => image::imageops::resize(&rgb, tw, th, FilterType::Triangle),
        None => rgb,
    };
    let (width, height) = rgb.dimensions();
    Ok(RgbImage::from_f32(
        width,
        height,
        rgb.into_raw()
            .into_iter()
            .map(|v| v.clamp(0.0, 1.0))
            .collect(),
    ))
}

/// Whether the image holds 8-bit channels.
fn is_eight_bit(img: &DynamicImage) -> bool {
    use image::ColorType as C;
    matches!(img.color(), C::L8 | C::La8 | C::Rgb8 | C::Rgba8)
}

/// Whether no pixel of the image is transparent.
fn is_opaque(img: &DynamicImage) -> bool {
    match img {
        DynamicImage::ImageLumaA8(b) => b.pixels().all(|p| p.0[1] == u8::MAX),
        DynamicImage::ImageRgba8(b) => b.pixels().all(|p| p.0[3] == u8::MAX),
        other => !other.color().has_alpha(),
    }
}

/// Loads a 16-bit depth PNG as metres (`value / scale`, 0 stays invalid),
/// resampled to `size` by nearest neighbour (averaging depths across an edge
/// would invent surfaces).
pub fn load_depth16(
    path: &Path,
    scale: f64,
    size: Option<(u32, u32)>,
) -> Result<DepthImage, DatasetError> {
    let img = open(path)?;
    let raw = match img {
        DynamicImage::ImageLuma16(b) => b,
        other => {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "depth must be a 16-bit single-channel PNG, found {:?}",
                    other.color()
                ),
            ));
        }
    };
    let (w, h) = raw.dimensions();
    let (tw, th) = size.unwrap_or((w, h));
    let mut data = Vec::with_capacity(tw as usize * th as usize);
    for y in 0..th {
        let sy = (((y as f64 + 0.5) * h as f64 / th as f64) as u32).min(h - 1);
        for x in 0..tw {
            let sx = (((x as f64 + 0.5) * w as f64 / tw as f64) as u32).min(w - 1);
            data.push((raw.get_pixel(sx, sy).0[0] as f64 / scale) as f32);
        }
    }
    Ok(DepthImage {
        width: tw,
        height: th,
        data: crate::scene::DepthData::F32(data),
    })
}

/// Writes `height * width * 3` bytes as an 8-bit RGB PNG: the one PNG
/// writer of frames, renders, figures and plots.
pub fn save_rgb8(path: &Path, width: u32, height: u32, data: &[u8]) -> Result<(), DatasetError> {
    if data.len() != width as usize * height as usize * 3 {
        return Err(DatasetError::invalid(
            path,
            format!(
                "cannot write image: {} bytes do not hold {width}x{height} RGB pixels",
                data.len()
            ),
        ));
    }
    image::save_buffer(path, data, width, height, image::ColorType::Rgb8)
        .map_err(|e| DatasetError::invalid(path, format!("cannot write image: {e}")))
}

/// Width and height of an image file, from its header only.
pub fn dimensions(path: &Path) -> Result<(u32, u32), DatasetError> {
    image::image_dimensions(path)
        .map_err(|e| DatasetError::invalid(path, format!("cannot read image size: {e}")))
}
