//! COLMAP's dense depth maps (`stereo/depth_maps/<image>.geometric.bin`):
//! an ASCII header `width&height&channels&`, then `width * height *
//! channels` little-endian `f32`, x fastest, then y, then channel (a
//! depth map has one channel, so it is row-major `height x width`). Depths
//! are z-depths in the reconstruction's units; zero, negative and
//! non-finite values mark pixels without a depth.

use std::path::{Path, PathBuf};

use crate::error::DatasetError;
use crate::grid::nearest_pixel;
use crate::scene::DepthImage;

/// Longest header read (three decimal numbers and three `&`).
const MAX_HEADER: usize = 64;

/// A depth map as stored: `height * width` raw depths.
#[derive(Debug, Clone, PartialEq)]
pub struct RawDepth {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major raw values.
    pub data: Vec<f32>,
}

/// The geometric depth map of image `name` in reconstruction `dir`.
pub fn depth_path(dir: &Path, name: &str) -> PathBuf {
    dir.join("stereo")
        .join("depth_maps")
        .join(format!("{name}.geometric.bin"))
}

/// Parses the `width&height&channels&` header; returns the sizes and the
/// header's length.
fn parse_header(path: &Path, bytes: &[u8]) -> Result<([usize; 3], usize), DatasetError> {
    let bad = || {
        DatasetError::invalid(
            path,
            "not a COLMAP depth map: expected a header width&height&channels&",
        )
    };
    let mut sizes = [0usize; 3];
    let mut pos = 0;
    for s in &mut sizes {
        let len = bytes[pos..]
            .iter()
            .take(MAX_HEADER)
            .position(|&b| b == b'&')
            .ok_or_else(bad)?;
        let text = std::str::from_utf8(&bytes[pos..pos + len]).map_err(|_| bad())?;
        *s = text.trim().parse().map_err(|_| bad())?;
        pos += len + 1;
    }
    Ok((sizes, pos))
}

/// Reads a one-channel depth map.
pub fn read_depth_map(path: &Path) -> Result<RawDepth, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    let ([w, h, c], start) = parse_header(path, &bytes)?;
    if c != 1 || w == 0 || h == 0 {
        return Err(DatasetError::invalid(
            path,
            format!("expected a one-channel depth map, found {w}x{h} with {c} channels"),
        ));
    }
    let (Ok(width), Ok(height)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(DatasetError::invalid(
            path,
            format!("size {w}x{h} is too large"),
        ));
    };
    let want = w.checked_mul(h).and_then(|n| n.checked_mul(4));
    let have = bytes.len() - start;
    match want {
        Some(n) if n == have => {}
        Some(n) if n > have => {
            return Err(DatasetError::invalid(
                path,
                format!("truncated: a {w}x{h} depth map needs {n} bytes of data, found {have}"),
            ));
        }
        _ => {
            return Err(DatasetError::invalid(
                path,
                format!("a {w}x{h} depth map holds {want:?} bytes of data, found {have}"),
            ));
        }
    }
    let data = bytes[start..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(RawDepth {
        width,
        height,
        data,
    })
}

/// The depth target of a `width x height` image: the map resampled
/// (nearest) to the image's size, times `scale`, with zero, negative and
/// non-finite depths as 0. Errors when the map's aspect ratio differs from
/// the image's by more than a pixel.
pub fn depth_target(
    path: &Path,
    raw: &RawDepth,
    (width, height): (u32, u32),
    scale: f64,
) -> Result<DepthImage, DatasetError> {
    let expected_h = raw.width as f64 * height as f64 / width as f64;
    let expected_w = raw.height as f64 * width as f64 / height as f64;
    if (raw.height as f64 - expected_h).abs() > 1.0 || (raw.width as f64 - expected_w).abs() > 1.0 {
        return Err(DatasetError::invalid(
            path,
            format!(
                "depth map is {}x{}, which does not have the aspect ratio of its {width}x{height} \
                 image",
                raw.width, raw.height
            ),
        ));
    }
    let mut data = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height {
        for x in 0..width {
            let (sx, sy) =
                nearest_pixel(x as f64, y as f64, (width, height), (raw.width, raw.height));
            let d = raw.data[sy as usize * raw.width as usize + sx as usize] as f64;
            data.push(if d > 0.0 && d.is_finite() {
                (d * scale) as f32
            } else {
                0.0
            });
        }
    }
    Ok(DepthImage {
        width,
        height,
        data: crate::scene::DepthData::F32(data),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode(w: usize, h: usize, values: &[f32]) -> Vec<u8> {
        let mut b = format!("{w}&{h}&1&").into_bytes();
        for v in values {
            b.extend(v.to_le_bytes());
        }
        b
    }

    #[test]
    fn reads_resamples_and_drops_invalid_depths() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("a.geometric.bin");
        std::fs::write(&p, encode(2, 1, &[2.0, f32::NAN])).expect("write");
        let raw = read_depth_map(&p).expect("valid");
        let d = depth_target(&p, &raw, (4, 2), 0.5).expect("same aspect");
        assert_eq!(*d.to_f32(), [1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0]);
        assert!(depth_target(&p, &raw, (4, 8), 1.0).is_err());
        let cut = encode(2, 2, &[1.0, 2.0, 3.0]);
        std::fs::write(&p, &cut[..cut.len() - 1]).expect("write");
        let msg = read_depth_map(&p).expect_err("cut").to_string();
        assert!(msg.contains("truncated"), "{msg}");
        std::fs::write(&p, b"12x3").expect("write");
        assert!(read_depth_map(&p).is_err());
    }
}
