//! Replica frames as a Polycam raw-data export.

use std::path::Path;

use anyhow::{Context, Result};

use super::{ReplicaFrames, confidence, copy, millimetres, write_png8, write_png16};

/// The stamp naming frame `i`'s files (Polycam names keyframes by time).
pub fn stamp(i: usize) -> u64 {
    1_000_000 + 33_333 * i as u64
}

/// Writes `frames` to `out/keyframes/` as Polycam does: `images/`,
/// `cameras/`, `depth/` (16-bit millimetres) and `confidence/` (levels
/// scaled to 0, 128, 255). With `corrected`, the exact poses go to
/// `corrected_images/` + `corrected_cameras/` and `cameras/` gets poses
/// 5 cm off, as a bundle adjustment would have corrected them.
pub fn write(frames: &ReplicaFrames, out: &Path, corrected: bool) -> Result<()> {
    let root = out.join("keyframes");
    let k = frames.intrinsics;
    let size = frames.depth_size();
    for sub in ["images", "cameras", "depth", "confidence"] {
        std::fs::create_dir_all(root.join(sub)).with_context(|| format!("{}", root.display()))?;
    }
    for i in 0..frames.images.len() {
        let s = stamp(i);
        let exact = frames.arkit_pose(i);
        let mut off = exact;
        off[0][3] += 0.05;
        let camera = |pose: [[f64; 4]; 4]| {
            let mut json = serde_json::json!({
                "fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy,
                "width": k.width, "height": k.height, "blur_score": 100.0 + i as f64,
            });
            for (r, row) in pose.iter().take(3).enumerate() {
                for (c, v) in row.iter().enumerate() {
                    json[format!("t_{r}{c}")] = serde_json::json!(v);
                }
            }
            json.to_string()
        };
        let write_json = |dir: &str, pose| {
            let p = root.join(dir).join(format!("{s}.json"));
            std::fs::write(&p, camera(pose)).with_context(|| format!("{}", p.display()))
        };
        copy(
            &frames.images[i],
            &root.join("images").join(format!("{s}.jpg")),
        )?;
        if corrected {
            copy(
                &frames.images[i],
                &root.join("corrected_images").join(format!("{s}.jpg")),
            )?;
            std::fs::create_dir_all(root.join("corrected_cameras"))?;
            write_json("corrected_cameras", exact)?;
            write_json("cameras", off)?;
        } else {
            write_json("cameras", exact)?;
        }
        let depth = frames.depth(i)?;
        write_png16(
            &root.join("depth").join(format!("{s}.png")),
            size,
            millimetres(&depth),
        )?;
        let levels = confidence(i, &depth)
            .into_iter()
            .map(|l| [0u8, 128, 255][l as usize])
            .collect();
        write_png8(
            &root.join("confidence").join(format!("{s}.png")),
            size,
            levels,
        )?;
    }
    Ok(())
}
