//! Writes a scene as a COLMAP text model without points (COLMAP's
//! known-poses workflow, or poses exported from another system), which
//! [`load_colmap`](crate::colmap::load_colmap) reads back:
//!
//! ```text
//! <dir>/images/<name>.{png,jpg}   colour
//! <dir>/sparse/0/cameras.txt      one PINHOLE camera per image (pixel-corner principal point: ours + 0.5)
//! <dir>/sparse/0/images.txt       world-to-camera quaternion and translation per image
//! <dir>/sparse/0/points3D.txt     empty
//! ```

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use super::{ImageFormat, io_err, write_rgb};
use crate::error::DatasetError;
use crate::scene::Scene;

/// Writes `scene` under `dir` (created if needed) in the layout above.
///
/// # Errors
/// When a frame's lens is distorted (a PINHOLE model cannot say so), the
/// scene has no frames, or a file cannot be written.
pub fn write_colmap_text(
    scene: &Scene,
    dir: &Path,
    format: ImageFormat,
) -> Result<(), DatasetError> {
    if scene.frames.is_empty() {
        return Err(DatasetError::invalid(dir, "scene has no frames to write"));
    }
    let (images, sparse) = (dir.join("images"), dir.join("sparse").join("0"));
    for d in [&images, &sparse] {
        std::fs::create_dir_all(d).map_err(io_err(d))?;
    }
    let ext = match format {
        ImageFormat::Png => "png",
        ImageFormat::Jpeg => "jpg",
    };
    let mut cameras = String::from("# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
    let mut poses = String::from("# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n");
    for (i, frame) in scene.frames.iter().enumerate() {
        let k = &frame.camera.intrinsics;
        if !k.distortion.is_none() {
            return Err(DatasetError::invalid(
                dir,
                format!(
                    "frame {} has a distorted lens: a PINHOLE model cannot hold it",
                    frame.name
                ),
            ));
        }
        let name = format!("{}.{ext}", frame.name);
        write_rgb(&images.join(&name), &frame.rgb, format)?;
        let id = i + 1;
        // Infallible: writing to a String.
        let _ = writeln!(
            cameras,
            "{id} PINHOLE {} {} {} {} {} {}",
            k.width,
            k.height,
            k.fx,
            k.fy,
            k.cx + 0.5,
            k.cy + 0.5
        );
        let pose = &frame.camera.pose;
        let c2w = Matrix3::from_fn(|r, c| pose.rotation[r][c]);
        let w2c = c2w.transpose();
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(w2c));
        let t = -(w2c * Vector3::from(pose.translation));
        let _ = writeln!(
            poses,
            "{id} {} {} {} {} {} {} {} {id} {name}\n",
            q.w, q.i, q.j, q.k, t.x, t.y, t.z
        );
    }
    for (file, body) in [
        ("cameras.txt", cameras),
        ("images.txt", poses),
        (
            "points3D.txt",
            "# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]\n".into(),
        ),
    ] {
        let path = sparse.join(file);
        std::fs::write(&path, body).map_err(io_err(&path))?;
    }
    Ok(())
}
