//! Decoders of the sources' bytes: ZIP entries, LZFSE streams, raw float32
//! and u8 maps, single-channel float EXR, scaled confidence PNGs.

use std::io::{Cursor, Read};
use std::path::{Path, PathBuf};

use crate::error::DatasetError;
use crate::scene::DepthImage;

/// Depth sizes a Record3D `.depth` map is taken to have when the metadata
/// does not state `dw` and `dh`: the LiDAR's, then the TrueDepth camera's.
pub const KNOWN_DEPTH_SIZES: [(u32, u32); 2] = [(256, 192), (640, 480)];

/// `archive:entry`, the name errors give an entry of an archive.
pub fn entry_path(archive: &Path, entry: &str) -> PathBuf {
    let mut s = archive.as_os_str().to_owned();
    s.push(":");
    s.push(entry);
    PathBuf::from(s)
}

/// Opens `archive` as a ZIP archive.
fn open_zip(archive: &Path) -> Result<zip::ZipArchive<std::fs::File>, DatasetError> {
    let file = std::fs::File::open(archive).map_err(|e| DatasetError::io(archive, e))?;
    zip::ZipArchive::new(file)
        .map_err(|e| DatasetError::invalid(archive, format!("not a readable ZIP archive: {e}")))
}

/// The names of the entries of the ZIP archive `archive`.
pub fn zip_names(archive: &Path) -> Result<Vec<String>, DatasetError> {
    open_zip(archive)?
        .file_names()
        .map(|n| n.map(|n| n.into_owned()))
        .collect::<Result<_, _>>()
        .map_err(|e| DatasetError::invalid(archive, format!("unreadable entry name: {e}")))
}

/// The bytes of `entry` of the ZIP archive `archive`, decompressed in
/// memory.
pub fn read_zip_entry(archive: &Path, entry: &str) -> Result<Vec<u8>, DatasetError> {
    let named = || entry_path(archive, entry);
    let mut zip = open_zip(archive)?;
    let mut file = zip
        .by_name(entry)
        .map_err(|e| DatasetError::invalid(named(), format!("cannot open the entry: {e}")))?;
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes)
        .map_err(|e| DatasetError::invalid(named(), format!("cannot read the entry: {e}")))?;
    Ok(bytes)
}

/// `bytes` (of `path`) decompressed as one LZFSE stream.
pub fn lzfse(bytes: &[u8], path: &Path) -> Result<Vec<u8>, DatasetError> {
    let mut out = Vec::new();
    lzfse_rust::decode_bytes(bytes, &mut out).map_err(|e| {
        DatasetError::invalid(
            path,
            format!("not a complete LZFSE stream ({} bytes): {e}", bytes.len()),
        )
    })?;
    Ok(out)
}

/// The size of a map of `len` values, `size` when given, else one of
/// [`KNOWN_DEPTH_SIZES`].
fn map_size(
    len: usize,
    bytes_per_value: usize,
    size: Option<(u32, u32)>,
    path: &Path,
) -> Result<(u32, u32), DatasetError> {
    let area = |(w, h): (u32, u32)| w as usize * h as usize * bytes_per_value;
    match size {
        Some(s) if area(s) == len => Ok(s),
        Some(s) => Err(DatasetError::invalid(
            path,
            format!(
                "decompressed map has {len} bytes, expected {} ({}x{} values of {bytes_per_value} \
                 bytes)",
                area(s),
                s.0,
                s.1
            ),
        )),
        None => KNOWN_DEPTH_SIZES
            .into_iter()
            .find(|&s| area(s) == len)
            .ok_or_else(|| {
                DatasetError::invalid(
                    path,
                    format!(
                        "decompressed map has {len} bytes, which is neither 256x192 nor 640x480 \
                         values of {bytes_per_value} bytes, and the metadata states no `dw`/`dh`"
                    ),
                )
            }),
    }
}

/// A map of little-endian float32 metres (`bytes`, decompressed, of
/// `path`), of `size` (inferred when `None`).
pub fn f32_depth(
    bytes: &[u8],
    size: Option<(u32, u32)>,
    path: &Path,
) -> Result<DepthImage, DatasetError> {
    let (width, height) = map_size(bytes.len(), 4, size, path)?;
    let data = bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(DepthImage {
        width,
        height,
        data: crate::scene::DepthData::F32(data),
    })
}

/// A map of u8 levels (`bytes`, decompressed, of `path`) that must have
/// `size`.
pub fn u8_levels(bytes: Vec<u8>, size: (u32, u32), path: &Path) -> Result<Vec<u8>, DatasetError> {
    map_size(bytes.len(), 1, Some(size), path)?;
    Ok(bytes)
}

/// Channel names taken as depth in a multi-channel EXR, in this order.
const DEPTH_CHANNELS: [&str; 4] = ["Z", "depth", "Y", "R"];

/// A single-channel (or `Z`, `depth`, `Y` or `R` channel) float EXR file in
/// metres.
pub fn exr_depth(path: &Path) -> Result<DepthImage, DatasetError> {
    use exr::prelude::{FlatSamples, ReadChannels, ReadLayers};
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| DatasetError::invalid(path, format!("cannot decode EXR: {e}")))?;
    let layer = image.layer_data;
    let channels = &layer.channel_data.list;
    let name = |c: &exr::prelude::AnyChannel<FlatSamples>| c.name.to_string();
    let channel = if channels.len() == 1 {
        channels.first()
    } else {
        DEPTH_CHANNELS
            .iter()
            .find_map(|&want| channels.iter().find(|c| name(c).eq_ignore_ascii_case(want)))
    };
    let Some(channel) = channel else {
        let names: Vec<String> = channels.iter().map(name).collect();
        return Err(DatasetError::invalid(
            path,
            format!("EXR has the channels {names:?}, none of them Z, depth, Y or R"),
        ));
    };
    let (width, height) = (layer.size.0, layer.size.1);
    let data: Vec<f32> = match &channel.sample_data {
        FlatSamples::F32(v) => v.clone(),
        FlatSamples::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
        FlatSamples::U32(_) => {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "EXR channel {} holds integers, not depth in metres",
                    name(channel)
                ),
            ));
        }
    };
    let (Ok(w), Ok(h)) = (u32::try_from(width), u32::try_from(height)) else {
        return Err(DatasetError::invalid(path, "EXR is too large"));
    };
    if data.len() != width * height {
        return Err(DatasetError::invalid(
            path,
            format!(
                "EXR channel {} has {} samples for {width}x{height} pixels (subsampled?)",
                name(channel),
                data.len()
            ),
        ));
    }
    Ok(DepthImage {
        width: w,
        height: h,
        data: crate::scene::DepthData::F32(data),
    })
}

/// Confidence `values` of `path` as levels 0, 1, 2: kept when all are
/// levels, mapped when they are the levels scaled to 0..255 (0, 127 or 128,
/// 255), refused otherwise.
pub fn unscaled_levels(values: Vec<u8>, path: &Path) -> Result<Vec<u8>, DatasetError> {
    if values.iter().all(|&v| v <= 2) {
        return Ok(values);
    }
    values
        .into_iter()
        .map(|v| match v {
            0 => Ok(0),
            127 | 128 => Ok(1),
            255 => Ok(2),
            other => Err(DatasetError::invalid(
                path,
                format!(
                    "confidence value {other} is neither a level 0, 1, 2 nor one scaled to \
                     0..255 (0, 127/128, 255)"
                ),
            )),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use exr::prelude::*;

    use super::*;

    fn write_exr(path: &Path, channels: Vec<AnyChannel<FlatSamples>>) {
        let layer = Layer::new(
            (2, 1),
            LayerAttributes::default(),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(SmallVec::from_vec(channels)),
        );
        Image::from_layer(layer).write().to_file(path).unwrap();
    }

    #[test]
    fn exr_depth_channel_is_chosen_by_name() {
        let tmp = tempfile::tempdir().unwrap();
        let p = tmp.path().join("d.exr");
        let f32s = |v: [f32; 2]| FlatSamples::F32(v.to_vec());
        write_exr(
            &p,
            vec![
                AnyChannel::new("B", f32s([5.0, 6.0])),
                AnyChannel::new("G", f32s([3.0, 4.0])),
                AnyChannel::new("R", f32s([1.0, 2.0])),
            ],
        );
        assert_eq!(*exr_depth(&p).unwrap().to_f32(), [1.0, 2.0]);
        let half = FlatSamples::F16(vec![f16::from_f32(0.5), f16::from_f32(2.25)]);
        write_exr(&p, vec![AnyChannel::new("Y", half)]);
        let d = exr_depth(&p).unwrap();
        assert_eq!(
            (d.width, d.height, d.to_f32().to_vec()),
            (2, 1, vec![0.5, 2.25])
        );
        write_exr(
            &p,
            vec![
                AnyChannel::new("A", f32s([1.0, 2.0])),
                AnyChannel::new("B", f32s([1.0, 2.0])),
            ],
        );
        let e = exr_depth(&p).unwrap_err().to_string();
        assert!(
            e.contains("d.exr: EXR has the channels") && e.contains("none of them"),
            "{e}"
        );
        std::fs::write(&p, b"not an exr").unwrap();
        let e = exr_depth(&p).unwrap_err().to_string();
        assert!(e.contains("d.exr: cannot decode EXR"), "{e}");
    }

    #[test]
    fn known_sizes_are_inferred() {
        let p = Path::new("0.depth");
        let d = f32_depth(&vec![0; 256 * 192 * 4], None, p).unwrap();
        assert_eq!((d.width, d.height), (256, 192));
        let d = f32_depth(&vec![0; 640 * 480 * 4], None, p).unwrap();
        assert_eq!((d.width, d.height), (640, 480));
        assert!(f32_depth(&[0; 12], None, p).is_err());
    }
}
