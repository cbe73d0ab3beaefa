//! Writes a scene as a nerfstudio capture, which
//! [`load_blender`](crate::blender::load_blender) reads back:
//!
//! ```text
//! <dir>/transforms.json        per-frame intrinsics, distortion, OpenGL poses
//! <dir>/images/<name>.{png,jpg} colour
//! <dir>/depth/<name>.png       16-bit z-depth, millimetres (depth_unit_scale_factor 0.001)
//! <dir>/masks/<name>.png       8-bit, 0 = never a target, 255 = keep
//! <dir>/sparse_pc.ply          the scene's points (ply_file_path)
//! ```
//!
//! Every frame carries its own `fl_x`, `fl_y`, `cx`, `cy` (nerfstudio's
//! pixel-corner convention: ours + 0.5), `w`, `h`, and, when any frame is
//! distorted, `camera_model: OPENCV` at the top level with `k1..k4`, `p1`,
//! `p2` per frame. A scene with a [`WorldFrame`](crate::WorldFrame) gets its
//! map as `applied_transform` (3x4).

use std::path::Path;

use serde_json::{Value, json};

use super::{ImageFormat, io_err, write_rgb};
use crate::error::DatasetError;
use crate::points::write_ply;
use crate::scene::{DepthImage, Frame, Scene};

/// Depth unit of the written depth files (metres per unit).
pub const NERFSTUDIO_DEPTH_UNIT: f64 = 1e-3;

/// Writes `scene` under `dir` (created if needed) in the layout above.
///
/// # Errors
/// When two frames share a name (their files would collide), a mask does
/// not match its image's size, or a file cannot be written.
pub fn write_nerfstudio(
    scene: &Scene,
    dir: &Path,
    format: ImageFormat,
) -> Result<(), DatasetError> {
    if scene.frames.is_empty() {
        return Err(DatasetError::invalid(dir, "scene has no frames to write"));
    }
    let mut names: Vec<&str> = scene.frames.iter().map(|f| f.name.as_str()).collect();
    names.sort_unstable();
    if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
        return Err(DatasetError::invalid(
            dir,
            format!("two frames are named {}: their files would collide", w[0]),
        ));
    }
    for sub in ["images", "depth", "masks"] {
        let d = dir.join(sub);
        std::fs::create_dir_all(&d).map_err(io_err(&d))?;
    }
    let distorted = scene
        .frames
        .iter()
        .any(|f| !f.camera.intrinsics.distortion.is_none());
    let mut frames = Vec::with_capacity(scene.frames.len());
    for frame in &scene.frames {
        frames.push(write_frame(dir, frame, format, distorted)?);
    }
    let mut top = serde_json::Map::new();
    top.insert(
        "camera_model".into(),
        json!(if distorted { "OPENCV" } else { "PINHOLE" }),
    );
    if scene.frames.iter().any(|f| f.depth.is_some()) {
        top.insert(
            "depth_unit_scale_factor".into(),
            json!(NERFSTUDIO_DEPTH_UNIT),
        );
    }
    if let Some(world) = &scene.world {
        let m = world.to_scene.to_matrix();
        top.insert("applied_transform".into(), json!(m[..3].to_vec()));
    }
    if let Some(points) = &scene.points {
        write_ply(&dir.join("sparse_pc.ply"), points, &[])?;
        top.insert("ply_file_path".into(), json!("sparse_pc.ply"));
    }
    top.insert("frames".into(), Value::Array(frames));
    let path = dir.join("transforms.json");
    let text = serde_json::to_string_pretty(&Value::Object(top))
        .map_err(|e| DatasetError::invalid(&path, e.to_string()))?;
    std::fs::write(&path, text).map_err(io_err(&path))
}

/// Writes one frame's files and returns its `frames[]` entry.
fn write_frame(
    dir: &Path,
    frame: &Frame,
    format: ImageFormat,
    distorted: bool,
) -> Result<Value, DatasetError> {
    let ext = match format {
        ImageFormat::Png => "png",
        ImageFormat::Jpeg => "jpg",
    };
    let image = format!("images/{}.{ext}", frame.name);
    write_rgb(&dir.join(&image), &frame.rgb, format)?;
    let k = &frame.camera.intrinsics;
    let mut entry = json!({
        "file_path": image,
        "transform_matrix": frame.camera.pose.to_opengl(),
        "fl_x": k.fx, "fl_y": k.fy, "cx": k.cx + 0.5, "cy": k.cy + 0.5,
        "w": k.width, "h": k.height,
    });
    let obj = entry
        .as_object_mut()
        .ok_or_else(|| DatasetError::invalid(dir, "frame entry is not an object"))?;
    if distorted {
        let d = &k.distortion;
        for (key, v) in [
            ("k1", d.k1),
            ("k2", d.k2),
            ("k3", d.k3),
            ("k4", d.k4),
            ("p1", d.p1),
            ("p2", d.p2),
        ] {
            obj.insert(key.into(), json!(v));
        }
    }
    if let Some(depth) = &frame.depth {
        let rel = format!("depth/{}.png", frame.name);
        write_depth_mm(&dir.join(&rel), depth)?;
        obj.insert("depth_file_path".into(), json!(rel));
    }
    if let Some(mask) = &frame.mask {
        let rel = format!("masks/{}.png", frame.name);
        write_mask(&dir.join(&rel), mask, (frame.rgb.width, frame.rgb.height))?;
        obj.insert("mask_path".into(), json!(rel));
    }
    Ok(entry)
}

/// Writes a depth map as a 16-bit PNG of millimetres (rounded; beyond
/// 65.535 m clipped; invalid depths 0).
pub fn write_depth_mm(path: &Path, depth: &DepthImage) -> Result<(), DatasetError> {
    let values: Vec<u16> = depth
        .to_f32()
        .iter()
        .map(|&d| {
            let mm = d as f64 / NERFSTUDIO_DEPTH_UNIT;
            if mm.is_finite() && mm > 0.0 {
                mm.round().min(u16::MAX as f64) as u16
            } else {
                0
            }
        })
        .collect();
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(
        depth.width,
        depth.height,
        values,
    )
    .ok_or_else(|| DatasetError::invalid(path, "depth buffer does not match its size"))?;
    img.save(path)
        .map_err(|e| DatasetError::invalid(path, format!("cannot write depth image: {e}")))
}

/// Writes a mask as an 8-bit PNG (255 = keep, 0 = masked out).
fn write_mask(path: &Path, mask: &[bool], (w, h): (u32, u32)) -> Result<(), DatasetError> {
    if mask.len() != w as usize * h as usize {
        return Err(DatasetError::invalid(
            path,
            format!("mask has {} pixels, its image {w}x{h}", mask.len()),
        ));
    }
    let bytes: Vec<u8> = mask.iter().map(|&m| if m { 255 } else { 0 }).collect();
    let img = image::GrayImage::from_raw(w, h, bytes)
        .ok_or_else(|| DatasetError::invalid(path, "mask does not match its image's size"))?;
    img.save(path)
        .map_err(|e| DatasetError::invalid(path, format!("cannot write mask: {e}")))
}
