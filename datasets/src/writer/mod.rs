//! Writes a scene to disk in the Nice-SLAM Replica layout, with its feature
//! maps, class embeddings and labelled point cloud, so the on-disk loaders
//! (and external tools) can read it back:
//!
//! ```text
//! <dir>/results/frameNNNNNN.{png,jpg}   colour
//! <dir>/results/depthNNNNNN.png         16-bit depth, metres * 6553.5
//! <dir>/traj.txt                        one row-major 4x4 camera-to-world (OpenCV) per line
//! <dir>/cam_params.json                 {"camera": {w, h, fx, fy, cx, cy, scale}}
//! <dir>/features/frameNNNNNN.npy        float16 H_f x W_f x C feature map per frame
//! <dir>/features/pca.json               the PCA basis (only with FeatureLayout::Coefficients)
//! <dir>/classes.npy, classes.txt        class text embeddings (C x D float32) and names
//! <dir>/points.ply                      binary PLY: x y z, colour, `label` = class index
//! ```
//!
//! [`write_nerfstudio`] writes a scene as a nerfstudio `transforms.json`
//! capture instead (per-frame intrinsics and distortion, depth, masks), and
//! [`write_colmap_text`] as a COLMAP text model without points, and
//! [`write_record3d`] as a Record3D phone export of any number of frames at
//! any size.

mod colmap;
mod nerfstudio;
mod record3d;

use std::io::Write;
use std::path::Path;

use half::f16;

use crate::error::DatasetError;
use crate::npy::write_npy_f16;
use crate::points::write_ply;
use crate::scene::{DepthImage, Frame, RgbImage, Scene};

pub use colmap::write_colmap_text;
pub use nerfstudio::{NERFSTUDIO_DEPTH_UNIT, write_depth_mm, write_nerfstudio};
pub use record3d::{Record3dExport, rotation_quaternion, sharp_frames, write_record3d};

/// Depth PNG scale of the Nice-SLAM layout (value = metres * scale).
pub const DEPTH_SCALE: f64 = 6553.5;

/// Colour image file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ImageFormat {
    /// Lossless 8-bit PNG.
    #[default]
    Png,
    /// JPEG at quality 95 (as the Replica captures are stored).
    Jpeg,
}

/// What the per-frame feature files hold when the scene's maps are
/// PCA-compressed (uncompressed maps are always written as they are).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FeatureLayout {
    /// Lifted back to the full dimension D, as a 2D extractor writes them.
    #[default]
    Full,
    /// The k PCA coefficients, with the basis in `features/pca.json`.
    Coefficients,
}

/// Options of [`write_scene`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WriteOptions {
    /// Colour file format.
    pub image_format: ImageFormat,
    /// Feature file content.
    pub features: FeatureLayout,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DatasetError + '_ {
    move |e| DatasetError::io(path, e)
}

/// Writes `scene` under `dir` (created if needed) in the layout above.
///
/// # Errors
/// When the frames do not share one set of intrinsics (the layout stores
/// one), a frame lacks depth, or a file cannot be written.
pub fn write_scene(scene: &Scene, dir: &Path, options: &WriteOptions) -> Result<(), DatasetError> {
    let results = dir.join("results");
    std::fs::create_dir_all(&results).map_err(io_err(&results))?;
    let first = scene
        .frames
        .first()
        .ok_or_else(|| DatasetError::invalid(dir, "scene has no frames to write"))?;
    let k = first.camera.intrinsics;
    if let Some(f) = scene.frames.iter().find(|f| f.camera.intrinsics != k) {
        return Err(DatasetError::invalid(
            dir,
            format!("frame {} has other intrinsics than the first frame", f.name),
        ));
    }
    let mut traj = String::new();
    for (i, frame) in scene.frames.iter().enumerate() {
        write_frame(&results, i, frame, options.image_format)?;
        let m = frame.camera.pose.to_matrix();
        let row: Vec<String> = m.iter().flatten().map(|v| format!("{v}")).collect();
        traj.push_str(&row.join(" "));
        traj.push('\n');
    }
    let traj_path = dir.join("traj.txt");
    std::fs::write(&traj_path, traj).map_err(io_err(&traj_path))?;
    let params = serde_json::json!({"camera": {
        "w": k.width, "h": k.height, "fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy,
        "scale": DEPTH_SCALE,
    }});
    let params_path = dir.join("cam_params.json");
    let text = serde_json::to_string_pretty(&params)
        .map_err(|e| DatasetError::invalid(&params_path, e.to_string()))?;
    std::fs::write(&params_path, text).map_err(io_err(&params_path))?;
    if let Some(features) = &scene.features {
        let fdir = dir.join("features");
        std::fs::create_dir_all(&fdir).map_err(io_err(&fdir))?;
        let lift = options.features == FeatureLayout::Full;
        for (frame, map) in scene.frames.iter().zip(&features.maps) {
            let path = fdir.join(format!("{}.npy", frame.name));
            let shape = |d: usize| [map.height as usize, map.width as usize, d];
            match (&features.pca, lift) {
                (Some(pca), true) => {
                    let coeffs: Vec<f32> = map.data.iter().map(|h| h.to_f32()).collect();
                    let full: Vec<f16> = pca.lift(&coeffs).into_iter().map(f16::from_f32).collect();
                    write_npy_f16(&path, &shape(pca.dim), &full)?;
                }
                _ => write_npy_f16(&path, &shape(map.dim), &map.data)?,
            }
        }
        if let (Some(pca), false) = (&features.pca, lift) {
            let path = fdir.join("pca.json");
            let text = serde_json::to_string(pca)
                .map_err(|e| DatasetError::invalid(&path, e.to_string()))?;
            std::fs::write(&path, text).map_err(io_err(&path))?;
        }
    }
    if let Some(classes) = &scene.classes {
        classes.save(&dir.join("classes.npy"), &dir.join("classes.txt"))?;
    }
    if let Some(points) = &scene.points {
        write_ply(&dir.join("points.ply"), points, &[])?;
    }
    Ok(())
}

/// Writes one frame's colour and depth files.
fn write_frame(
    results: &Path,
    i: usize,
    frame: &Frame,
    format: ImageFormat,
) -> Result<(), DatasetError> {
    let ext = match format {
        ImageFormat::Png => "png",
        ImageFormat::Jpeg => "jpg",
    };
    write_rgb(
        &results.join(format!("frame{i:06}.{ext}")),
        &frame.rgb,
        format,
    )?;
    let depth = frame.depth.as_ref().ok_or_else(|| {
        DatasetError::invalid(results, format!("frame {} has no depth", frame.name))
    })?;
    write_depth(&results.join(format!("depth{i:06}.png")), depth)
}

/// Writes an RGB image in `[0, 1]` as 8-bit PNG or JPEG.
pub fn write_rgb(path: &Path, image: &RgbImage, format: ImageFormat) -> Result<(), DatasetError> {
    let bytes = image.to_u8();
    let bad =
        |e: image::ImageError| DatasetError::invalid(path, format!("cannot write image: {e}"));
    match format {
        ImageFormat::Png => image::save_buffer(
            path,
            &bytes,
            image.width,
            image.height,
            image::ColorType::Rgb8,
        )
        .map_err(bad),
        ImageFormat::Jpeg => {
            let file = std::fs::File::create(path).map_err(io_err(path))?;
            let mut w = std::io::BufWriter::new(file);
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut w, 95)
                .encode(
                    &bytes,
                    image.width,
                    image.height,
                    image::ExtendedColorType::Rgb8,
                )
                .map_err(bad)?;
            w.flush().map_err(io_err(path))
        }
    }
}

/// Writes a depth map as a 16-bit PNG (metres * [`DEPTH_SCALE`], rounded;
/// depths beyond 10 m are clipped).
pub fn write_depth(path: &Path, depth: &DepthImage) -> Result<(), DatasetError> {
    let values: Vec<u16> = depth
        .to_f32()
        .iter()
        .map(|&d| (d as f64 * DEPTH_SCALE).round().clamp(0.0, u16::MAX as f64) as u16)
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
