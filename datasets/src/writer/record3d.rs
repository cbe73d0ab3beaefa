//! A scene written as a Record3D "EXR + JPG" export, the files the app
//! itself writes (`metadata.json`, `rgb/<i>.jpg`, `depth/<i>.exr` as one
//! half-float channel `R`, `conf/<i>.png`), at any number of frames and any
//! size: the fixture of tests and measurements of captures at a phone's
//! own size (hundreds to thousands of frames at 1920 x 1440) without
//! shipping one.
//!
//! Frame `j` of `n` shows the scene's frame `j * m / n` (of `m`): a long
//! export repeats each view over a run of consecutive frames, as a video's
//! neighbouring frames nearly repeat. Its colour is the scene's image
//! resampled to the export's size (nearest pixel; intrinsics scaled per
//! axis), its depth the scene's depth at the depth map's size (nearest
//! pixel), its confidence high wherever there is depth.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::Path;

use model::geometry::{Pose, Similarity};

use crate::error::DatasetError;
use crate::phone::ARKIT_TO_Z_UP;
use crate::scene::{Frame, Scene};

/// What [`write_record3d`] writes.
#[derive(Debug, Clone, PartialEq)]
pub struct Record3dExport {
    /// Number of frames.
    pub frames: usize,
    /// Colour image size, width x height.
    pub size: (u32, u32),
    /// Depth map width; its height keeps the colour image's aspect ratio
    /// (256 at 4:3 gives a phone LiDAR's 256 x 192).
    pub depth_width: u32,
    /// When `Some(k)`: in each window of `k` consecutive frames (0..k,
    /// k..2k, ...) one frame is sharp and the others are blurred (a 9 x 9
    /// box), the sharp one at offset `window index mod k`, as a hand-held
    /// video blurs most frames of a fast move. Its sharp frames are
    /// [`sharp_frames`].
    pub blur_window: Option<usize>,
    /// Frames per second stated in the metadata.
    pub fps: f64,
    /// JPEG quality, 1 to 100.
    pub jpeg_quality: u8,
}

impl Default for Record3dExport {
    fn default() -> Self {
        Self {
            frames: 60,
            size: (1920, 1440),
            depth_width: 256,
            blur_window: None,
            fps: 60.0,
            jpeg_quality: 90,
        }
    }
}

/// The frames of an export of `frames` frames that [`write_record3d`]
/// leaves sharp with `blur_window: Some(k)`.
pub fn sharp_frames(frames: usize, k: usize) -> Vec<usize> {
    let k = k.max(1);
    (0..frames).filter(|&j| j % k == (j / k) % k).collect()
}

/// The unit quaternion `[x, y, z, w]` (scalar last) of a rotation matrix,
/// as Record3D writes poses (Shepperd's method: the largest of the four
/// squared components first, so no division is by a small number).
pub fn rotation_quaternion(r: [[f64; 3]; 3]) -> [f64; 4] {
    let trace = r[0][0] + r[1][1] + r[2][2];
    let q = if trace > 0.0 {
        let s = 2.0 * (1.0 + trace).sqrt();
        [
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
            s / 4.0,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = 2.0 * (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt();
        [
            s / 4.0,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[2][1] - r[1][2]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = 2.0 * (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt();
        [
            (r[0][1] + r[1][0]) / s,
            s / 4.0,
            (r[1][2] + r[2][1]) / s,
            (r[0][2] - r[2][0]) / s,
        ]
    } else {
        let s = 2.0 * (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt();
        [
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            s / 4.0,
            (r[1][0] - r[0][1]) / s,
        ]
    };
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| v / n)
}

/// Writes `scene` as a Record3D EXR + JPG export into `dir` (created).
///
/// # Errors
/// When the scene has no frame, the export's sizes are zero, a frame lacks
/// depth, or a file cannot be written.
pub fn write_record3d(
    scene: &Scene,
    dir: &Path,
    export: &Record3dExport,
) -> Result<(), DatasetError> {
    let (w, h) = export.size;
    if scene.frames.is_empty() || export.frames == 0 || w == 0 || h == 0 {
        return Err(DatasetError::invalid(
            dir,
            "a Record3D export needs a frame, a frame count and a size",
        ));
    }
    let depth_size = (
        export.depth_width.max(1),
        ((export.depth_width as f64 * h as f64 / w as f64).round() as u32).max(1),
    );
    for sub in ["rgb", "depth", "conf"] {
        let d = dir.join(sub);
        std::fs::create_dir_all(&d).map_err(|e| DatasetError::io(&d, e))?;
    }
    let m = scene.frames.len();
    let source = |j: usize| j * m / export.frames;
    let first = &scene.frames[0];
    let poses: Vec<[f64; 7]> = (0..export.frames)
        .map(|j| arkit_pose(&scene.frames[source(j)].camera.pose))
        .collect();
    let k = first.camera.intrinsics.scaled(w, h);
    let meta = serde_json::json!({
        "w": w, "h": h, "dw": depth_size.0, "dh": depth_size.1, "fps": export.fps,
        // Column-major: fx, 0, 0, 0, fy, 0, cx, cy, 1.
        "K": [k.fx, 0.0, 0.0, 0.0, k.fy, 0.0, k.cx, k.cy, 1.0],
        "poses": poses,
        "initPose": [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
    });
    let meta_path = dir.join("metadata.json");
    std::fs::write(&meta_path, meta.to_string()).map_err(|e| DatasetError::io(&meta_path, e))?;
    let sharp: Vec<bool> = match export.blur_window {
        Some(window) => {
            let mut s = vec![false; export.frames];
            sharp_frames(export.frames, window)
                .into_iter()
                .for_each(|j| s[j] = true);
            s
        }
        None => vec![true; export.frames],
    };
    let mut jpegs: HashMap<(usize, bool), Vec<u8>> = HashMap::new();
    let mut maps: HashMap<usize, (Vec<u8>, Vec<u8>)> = HashMap::new();
    for (j, &is_sharp) in sharp.iter().enumerate() {
        let s = source(j);
        let frame = &scene.frames[s];
        if let std::collections::hash_map::Entry::Vacant(e) = jpegs.entry((s, is_sharp)) {
            e.insert(jpeg(frame, export, !is_sharp, dir)?);
        }
        if let std::collections::hash_map::Entry::Vacant(e) = maps.entry(s) {
            e.insert(depth_maps(frame, depth_size, dir)?);
        }
        let (exr, conf) = &maps[&s];
        for (name, bytes) in [
            (format!("rgb/{j}.jpg"), &jpegs[&(s, is_sharp)]),
            (format!("depth/{j}.exr"), exr),
            (format!("conf/{j}.png"), conf),
        ] {
            let p = dir.join(name);
            std::fs::write(&p, bytes).map_err(|e| DatasetError::io(&p, e))?;
        }
    }
    Ok(())
}

/// `[qx, qy, qz, qw, tx, ty, tz]` of a scene pose (z up, OpenCV camera
/// axes) in ARKit's world (y up) with ARKit's camera axes.
fn arkit_pose(pose: &Pose) -> [f64; 7] {
    let z_up_to_y_up = Similarity {
        rotation: std::array::from_fn(|r| std::array::from_fn(|c| ARKIT_TO_Z_UP[c][r])),
        scale: 1.0,
        translation: [0.0; 3],
    };
    let m = z_up_to_y_up.apply_pose(pose).to_opengl();
    let q = rotation_quaternion(std::array::from_fn(|r| std::array::from_fn(|c| m[r][c])));
    [q[0], q[1], q[2], q[3], m[0][3], m[1][3], m[2][3]]
}

/// The frame's colour at the export's size as JPEG bytes, blurred when
/// asked.
fn jpeg(
    frame: &Frame,
    export: &Record3dExport,
    blurred: bool,
    dir: &Path,
) -> Result<Vec<u8>, DatasetError> {
    let (w, h) = export.size;
    let (sw, sh) = (frame.rgb.width, frame.rgb.height);
    let mut bytes = Vec::with_capacity(3 * w as usize * h as usize);
    for y in 0..h {
        let sy = ((y as u64 * sh as u64) / h as u64) as u32;
        for x in 0..w {
            let sx = ((x as u64 * sw as u64) / w as u64) as u32;
            let c = frame.rgb.get(sx, sy);
            bytes.extend(c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8));
        }
    }
    if blurred {
        bytes = box_blur(&bytes, w as usize, h as usize, 4);
    }
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, export.jpeg_quality.clamp(1, 100))
        .encode(&bytes, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| DatasetError::invalid(dir, format!("cannot encode JPEG: {e}")))?;
    Ok(out)
}

/// An 8-bit RGB image blurred by a `(2r + 1)`-wide box, each axis in turn
/// (edges clamped).
fn box_blur(src: &[u8], w: usize, h: usize, r: usize) -> Vec<u8> {
    let pass = |src: &[u8], along_x: bool| -> Vec<u8> {
        let mut out = vec![0u8; src.len()];
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let mut sum = 0u32;
                    for d in 0..=2 * r {
                        let (xx, yy) = if along_x {
                            ((x + d).saturating_sub(r).min(w - 1), y)
                        } else {
                            (x, (y + d).saturating_sub(r).min(h - 1))
                        };
                        sum += u32::from(src[3 * (yy * w + xx) + c]);
                    }
                    out[3 * (y * w + x) + c] = (sum / (2 * r as u32 + 1)) as u8;
                }
            }
        }
        out
    };
    pass(&pass(src, true), false)
}

/// The frame's depth at `size` as an EXR of one half-float channel `R`,
/// and its confidence (2 where there is depth, 0 elsewhere) as an 8-bit
/// PNG.
fn depth_maps(
    frame: &Frame,
    (dw, dh): (u32, u32),
    dir: &Path,
) -> Result<(Vec<u8>, Vec<u8>), DatasetError> {
    use exr::prelude::*;
    use image::ImageEncoder;
    let depth = frame.depth.as_ref().ok_or_else(|| {
        DatasetError::invalid(dir, format!("frame {} has no depth to write", frame.name))
    })?;
    let mut values = Vec::with_capacity(dw as usize * dh as usize);
    for y in 0..dh {
        let sy =
            (((y as f64 + 0.5) * depth.height as f64 / dh as f64) as u32).min(depth.height - 1);
        for x in 0..dw {
            let sx =
                (((x as f64 + 0.5) * depth.width as f64 / dw as f64) as u32).min(depth.width - 1);
            values.push(depth.get(sx, sy));
        }
    }
    let levels: Vec<u8> = values
        .iter()
        .map(|&d| if d > 0.0 { 2 } else { 0 })
        .collect();
    let channel = AnyChannel::new(
        "R",
        FlatSamples::F16(values.into_iter().map(f16::from_f32).collect()),
    );
    let layer = Layer::new(
        (dw as usize, dh as usize),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let mut exr_bytes = Vec::new();
    Image::from_layer(layer)
        .write()
        .to_buffered(Cursor::new(&mut exr_bytes))
        .map_err(|e| DatasetError::invalid(dir, format!("cannot encode EXR: {e}")))?;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&levels, dw, dh, image::ExtendedColorType::L8)
        .map_err(|e| DatasetError::invalid(dir, format!("cannot encode PNG: {e}")))?;
    Ok((exr_bytes, png))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rotation by `a` about the unit `axis` (Rodrigues).
    fn rotation(axis: [f64; 3], a: f64) -> [[f64; 3]; 3] {
        let (s, c) = a.sin_cos();
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let k = [
                    [0.0, -axis[2], axis[1]],
                    [axis[2], 0.0, -axis[0]],
                    [-axis[1], axis[0], 0.0],
                ];
                let kk: f64 = (0..3).map(|m| k[i][m] * k[m][j]).sum();
                f64::from(u8::from(i == j)) + s * k[i][j] + (1.0 - c) * kk
            })
        })
    }

    /// Every branch of Shepperd's method gives back the axis and angle.
    #[test]
    fn quaternions_recover_axis_and_angle() {
        for (axis, a) in [
            ([0.0, 0.0, 1.0], 0.3),
            ([1.0, 0.0, 0.0], 3.0),
            ([0.0, 1.0, 0.0], 2.9),
            ([0.0, 0.0, 1.0], 3.1),
            ([0.6, 0.0, 0.8], 1.7),
        ] {
            let q = rotation_quaternion(rotation(axis, a));
            let (s, c) = (a / 2.0).sin_cos();
            let want = [axis[0] * s, axis[1] * s, axis[2] * s, c];
            let sign = if q[3] * want[3] < 0.0 { -1.0 } else { 1.0 };
            for i in 0..4 {
                assert!((sign * q[i] - want[i]).abs() < 1e-12, "{axis:?} {a}: {q:?}");
            }
        }
    }

    #[test]
    fn one_frame_in_each_window_is_sharp_at_a_moving_offset() {
        assert_eq!(sharp_frames(12, 4), vec![0, 5, 10]);
        assert_eq!(sharp_frames(7, 3), vec![0, 4]);
        assert_eq!(sharp_frames(3, 1), vec![0, 1, 2]);
    }

    #[test]
    fn a_box_blur_keeps_flat_images_and_averages_edges() {
        let flat = vec![77u8; 3 * 5 * 4];
        assert_eq!(box_blur(&flat, 5, 4, 2), flat);
        // A vertical edge: after a 3-wide box along x, the two columns next
        // to it hold a third and two thirds of the step.
        let (w, h) = (6usize, 3usize);
        let edge: Vec<u8> = (0..w * h)
            .flat_map(|p| [if p % w >= 3 { 255u8 } else { 0 }; 3])
            .collect();
        let b = box_blur(&edge, w, h, 1);
        let row: Vec<u8> = (0..w).map(|x| b[3 * (w + x)]).collect();
        assert_eq!(row, vec![0, 0, 85, 170, 255, 255]);
    }
}
