//! A frame's depth and mask files (`depth_file_path`, `mask_path`), read
//! at their own size and resampled by nearest pixel to the colour image's.

use std::path::Path;

use image::DynamicImage;

use crate::error::DatasetError;
use crate::grid::{resample_nearest, same_aspect};
use crate::imageio;
use crate::npy::read_npy_f32;
use crate::scene::DepthImage;

/// nerfstudio's default `depth_unit_scale_factor`: 16-bit PNG millimetres.
pub const DEFAULT_DEPTH_UNIT_SCALE: f64 = 1e-3;

/// Checks that a `size` target file can cover an image of `image_size`
/// (the colour file's own size): the same aspect.
fn check_aspect(
    path: &Path,
    kind: &str,
    size: (u32, u32),
    image: &Path,
    image_size: (u32, u32),
) -> Result<(), DatasetError> {
    if same_aspect(size, image_size) {
        return Ok(());
    }
    Err(DatasetError::invalid(
        path,
        format!(
            "{kind} is {}x{} but its image {} is {}x{}: not the same aspect",
            size.0,
            size.1,
            image.display(),
            image_size.0,
            image_size.1
        ),
    ))
}

/// Fails naming `path` when it is not a file, for the frame `what` of the
/// transforms file `json`.
fn require_file(path: &Path, kind: &str, what: &str, json: &Path) -> Result<(), DatasetError> {
    if path.is_file() {
        return Ok(());
    }
    Err(DatasetError::invalid(
        path,
        format!("missing {kind} file for {what} of {}", json.display()),
    ))
}

/// Raw depth values and their size: a 16-bit PNG, or a float `.npy` of
/// shape `(h, w)` or `(h, w, 1)`.
fn read_raw_depth(path: &Path) -> Result<((u32, u32), Vec<f64>), DatasetError> {
    let is_npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    if is_npy {
        let (shape, data) = read_npy_f32(path)?;
        let (h, w) = match shape.as_slice() {
            [h, w] | [h, w, 1] => (*h, *w),
            other => {
                return Err(DatasetError::invalid(
                    path,
                    format!("depth array has shape {other:?}, expected (h, w) or (h, w, 1)"),
                ));
            }
        };
        let size = (
            u32::try_from(w).map_err(|_| DatasetError::invalid(path, "depth too wide"))?,
            u32::try_from(h).map_err(|_| DatasetError::invalid(path, "depth too tall"))?,
        );
        return Ok((size, data.into_iter().map(f64::from).collect()));
    }
    // Scale 1: the raw 16-bit values, exactly.
    let raw = imageio::load_depth16(path, 1.0, None)?;
    Ok((
        (raw.width, raw.height),
        raw.to_f32().iter().map(|&v| f64::from(v)).collect(),
    ))
}

/// The depth of one frame in metres (`value * unit_scale`; zero, negative
/// and non-finite values are no target) at the colour image's `target`
/// size. `image` and `image_size` are the colour file and its own size.
pub(super) fn load_depth(
    path: &Path,
    unit_scale: f64,
    (image, image_size): (&Path, (u32, u32)),
    target: (u32, u32),
    (what, json): (&str, &Path),
) -> Result<DepthImage, DatasetError> {
    require_file(path, "depth", what, json)?;
    let (size, raw) = read_raw_depth(path)?;
    check_aspect(path, "depth", size, image, image_size)?;
    let metres: Vec<f32> = raw
        .iter()
        .map(|&v| {
            let d = v * unit_scale;
            if d.is_finite() && d > 0.0 {
                d as f32
            } else {
                0.0
            }
        })
        .collect();
    Ok(DepthImage {
        width: target.0,
        height: target.1,
        data: crate::scene::DepthData::F32(resample_nearest(&metres, size, target)),
    })
}

/// The mask of one frame at the colour image's `target` size: `true`
/// (may be a target) where any colour channel of the mask file is nonzero.
pub(super) fn load_mask(
    path: &Path,
    (image, image_size): (&Path, (u32, u32)),
    target: (u32, u32),
    (what, json): (&str, &Path),
) -> Result<Vec<bool>, DatasetError> {
    require_file(path, "mask", what, json)?;
    let img = imageio::open(path)?;
    let size = (img.width(), img.height());
    check_aspect(path, "mask", size, image, image_size)?;
    let keep: Vec<bool> = match img {
        DynamicImage::ImageLuma8(b) => b.pixels().map(|p| p.0[0] != 0).collect(),
        DynamicImage::ImageLuma16(b) => b.pixels().map(|p| p.0[0] != 0).collect(),
        other => other
            .into_rgba16()
            .pixels()
            .map(|p| p.0[..3].iter().any(|&c| c != 0))
            .collect(),
    };
    Ok(resample_nearest(&keep, size, target))
}
