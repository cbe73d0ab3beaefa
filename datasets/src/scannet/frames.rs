//! The frames of a ScanNet export: the colour camera they are loaded into,
//! the colour images with a valid pose, and each frame's colour and depth,
//! the depth read in the depth camera and carried into the colour one.

use std::path::{Path, PathBuf};

use model::geometry::{Camera, Intrinsics, Pose};

use super::{
    DEPTH_UNITS_PER_METRE, ScannetOptions, ScannetReport, check_principal_point, read_intrinsics,
    read_pose, reproject_depth,
};
use crate::error::DatasetError;
use crate::imageio;
use crate::scene::{DepthImage, Frame};

/// The camera the frames are loaded into: the colour camera's intrinsics
/// (checked against the first colour image) scaled to `resolution`.
pub(super) struct ColourCamera {
    /// Size of the colour images, which every one must have.
    pub(super) size: (u32, u32),
    /// The intrinsics at the loaded resolution.
    target: Intrinsics,
}

impl ColourCamera {
    /// Reads `intrinsic_color.txt` at the size of `first_image`.
    pub(super) fn read(
        dir: &Path,
        first_image: &Path,
        options: &ScannetOptions,
    ) -> Result<ColourCamera, DatasetError> {
        let size = imageio::dimensions(first_image)?;
        let kc_path = dir.join("intrinsic").join("intrinsic_color.txt");
        let colour_k = read_intrinsics(&kc_path, size)?;
        check_principal_point(&kc_path, first_image, &colour_k)?;
        let (tw, th) = options.selection.size(size);
        if tw == 0 || th == 0 {
            return Err(DatasetError::invalid(dir, "resolution is zero"));
        }
        Ok(ColourCamera {
            size,
            target: colour_k.scaled(tw, th),
        })
    }
}

/// A colour image with a valid pose.
pub(super) struct PosedImage {
    /// Its number `<i>`.
    index: u64,
    /// The colour image.
    pub(super) path: PathBuf,
    /// Its camera-to-world pose.
    pose: Pose,
}

/// The colour images whose pose is valid, in order; the others are listed
/// in the report.
pub(super) fn posed_images(
    dir: &Path,
    colour: Vec<(u64, PathBuf)>,
) -> Result<(Vec<PosedImage>, ScannetReport), DatasetError> {
    let mut report = ScannetReport::default();
    let mut valid = Vec::new();
    for (index, path) in colour {
        let pose_path = dir.join("pose").join(format!("{index}.txt"));
        match read_pose(&pose_path)? {
            Some(pose) => valid.push(PosedImage { index, path, pose }),
            None => report.skipped.push(pose_path),
        }
    }
    Ok((valid, report))
}

/// The depth camera, whose intrinsics are read with the first depth map
/// (they carry no size: that of the first map is theirs, and every other
/// map must have it).
pub(super) struct DepthCamera {
    /// `intrinsic_depth.txt`.
    intrinsics_path: PathBuf,
    /// The intrinsics, once the first depth map is read.
    intrinsics: Option<Intrinsics>,
}

impl DepthCamera {
    /// The depth camera of the export in `dir`, its intrinsics not yet read.
    pub(super) fn new(dir: &Path) -> DepthCamera {
        DepthCamera {
            intrinsics_path: dir.join("intrinsic").join("intrinsic_depth.txt"),
            intrinsics: None,
        }
    }

    /// The depth map `depth/<i>.png` of colour image `image` (as stored)
    /// and the intrinsics it was taken with.
    fn read(
        &mut self,
        dir: &Path,
        i: u64,
        image: &Path,
    ) -> Result<(DepthImage, Intrinsics), DatasetError> {
        let depth_path = dir.join("depth").join(format!("{i}.png"));
        if !depth_path.is_file() {
            return Err(DatasetError::invalid(
                &depth_path,
                format!("missing depth for colour image {}", image.display()),
            ));
        }
        let raw = imageio::load_depth16(&depth_path, DEPTH_UNITS_PER_METRE, None)?;
        let dk = match self.intrinsics {
            Some(k) if (k.width, k.height) == (raw.width, raw.height) => k,
            Some(k) => {
                return Err(DatasetError::invalid(
                    &depth_path,
                    format!(
                        "depth is {}x{}, the first depth image {}x{}",
                        raw.width, raw.height, k.width, k.height
                    ),
                ));
            }
            None => {
                let k = read_intrinsics(&self.intrinsics_path, (raw.width, raw.height))?;
                check_principal_point(&self.intrinsics_path, &depth_path, &k)?;
                self.intrinsics = Some(k);
                k
            }
        };
        Ok((raw, dk))
    }
}

/// One frame in the colour camera, its depth carried into it
/// ([`reproject_depth`]).
pub(super) fn load_frame(
    dir: &Path,
    image: PosedImage,
    colour: &ColourCamera,
    depth_camera: &mut DepthCamera,
) -> Result<Frame, DatasetError> {
    let PosedImage {
        index: i,
        path: img_path,
        pose,
    } = image;
    let size = imageio::dimensions(&img_path)?;
    if size != colour.size {
        return Err(DatasetError::invalid(
            &img_path,
            format!(
                "image is {}x{}, the first colour image {}x{}",
                size.0, size.1, colour.size.0, colour.size.1
            ),
        ));
    }
    let resolution = (colour.target.width, colour.target.height);
    let rgb = imageio::load_rgb(&img_path, None, Some(resolution))?;
    let (raw, dk) = depth_camera.read(dir, i, &img_path)?;
    let depth = reproject_depth(&raw, &dk, &colour.target);
    Ok(Frame::captured(
        format!("frame{i:06}"),
        Camera {
            intrinsics: colour.target,
            pose,
        },
        rgb,
        Some(depth),
    ))
}
