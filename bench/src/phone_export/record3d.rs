//! Replica frames as Record3D exports: EXR + JPG (`metadata.json`,
//! `rgb/`, `depth/`, `conf/`) and R3D (a ZIP of `metadata` and `rgbd/`,
//! depth and confidence LZFSE-compressed).

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};

use super::{ReplicaFrames, confidence, copy};

/// The metadata both exports share.
fn metadata(frames: &ReplicaFrames) -> String {
    let k = frames.intrinsics;
    let (dw, dh) = frames.depth_size();
    let poses: Vec<[f64; 7]> = (0..frames.images.len())
        .map(|i| {
            let m = frames.arkit_pose(i);
            let q = datasets::writer::rotation_quaternion(std::array::from_fn(|r| {
                std::array::from_fn(|c| m[r][c])
            }));
            [q[0], q[1], q[2], q[3], m[0][3], m[1][3], m[2][3]]
        })
        .collect();
    serde_json::json!({
        "w": k.width, "h": k.height, "dw": dw, "dh": dh, "fps": 60,
        // Column-major: fx, 0, 0, 0, fy, 0, cx, cy, 1.
        "K": [k.fx, 0.0, 0.0, 0.0, k.fy, 0.0, k.cx, k.cy, 1.0],
        "poses": poses,
        "initPose": [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
    })
    .to_string()
}

/// Frame `i`'s depth as little-endian float32 bytes, and its confidence.
fn maps(frames: &ReplicaFrames, i: usize) -> Result<(Vec<f32>, Vec<u8>)> {
    let depth = frames.depth(i)?;
    let levels = confidence(i, &depth);
    Ok((depth.to_f32().into_owned(), levels))
}

fn lzfse(bytes: &[u8]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    lzfse_rust::encode_bytes(bytes, &mut out).context("LZFSE")?;
    Ok(out)
}

/// Writes the EXR + JPG export to `out`.
pub fn write_exr(frames: &ReplicaFrames, out: &Path) -> Result<()> {
    use exr::prelude::*;
    for sub in ["rgb", "depth", "conf"] {
        std::fs::create_dir_all(out.join(sub)).with_context(|| format!("{}", out.display()))?;
    }
    std::fs::write(out.join("metadata.json"), metadata(frames))?;
    let (dw, dh) = frames.depth_size();
    for i in 0..frames.images.len() {
        copy(&frames.images[i], &out.join("rgb").join(format!("{i}.jpg")))?;
        let (depth, levels) = maps(frames, i)?;
        let channel = AnyChannel::new("Z", FlatSamples::F32(depth));
        let layer = Layer::new(
            (dw as usize, dh as usize),
            LayerAttributes::default(),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![channel])),
        );
        let path = out.join("depth").join(format!("{i}.exr"));
        Image::from_layer(layer)
            .write()
            .to_file(&path)
            .with_context(|| format!("{}", path.display()))?;
        super::write_png8(&out.join("conf").join(format!("{i}.png")), (dw, dh), levels)?;
    }
    Ok(())
}

/// Writes the R3D export (one ZIP file) to `out`.
pub fn write_r3d(frames: &ReplicaFrames, out: &Path) -> Result<()> {
    use zip::write::SimpleFileOptions;
    let file = std::fs::File::create(out).with_context(|| format!("{}", out.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let stored = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    let mut entry = |name: String, bytes: &[u8]| -> Result<()> {
        zip.start_file(name.as_str(), stored)?;
        zip.write_all(bytes)?;
        Ok(())
    };
    entry("metadata".into(), metadata(frames).as_bytes())?;
    for i in 0..frames.images.len() {
        let jpeg = std::fs::read(&frames.images[i])?;
        entry(format!("rgbd/{i}.jpg"), &jpeg)?;
        let (depth, levels) = maps(frames, i)?;
        let bytes: Vec<u8> = depth.iter().flat_map(|d| d.to_le_bytes()).collect();
        entry(format!("rgbd/{i}.depth"), &lzfse(&bytes)?)?;
        entry(format!("rgbd/{i}.conf"), &lzfse(&levels)?)?;
    }
    zip.finish().context("finishing the archive")?;
    Ok(())
}
