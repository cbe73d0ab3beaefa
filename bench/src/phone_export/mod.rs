//! Replica frames written out as phone exports (3D Scanner App, Record3D,
//! Polycam), the way each app lays out its files and conventions: the
//! fixtures that check every phone loader against the Replica loader on
//! the same frames, and the training comparison of `docs/guide/phone.md`.
//!
//! The export's world is ARKit's, y up, reached from Replica's by a fixed
//! rigid map ([`ReplicaFrames::to_arkit`]); camera poses are written with
//! ARKit's camera axes (looking down -z). Colour images are the Replica
//! JPEGs, byte for byte. Depth is written at a quarter of the colour size
//! in each axis (Replica's 1200x680 frames give 300x170: the 256x192 of a
//! phone's LiDAR has another aspect ratio), each depth pixel the Replica
//! depth nearest to its centre, with a confidence map whose levels follow
//! a fixed pattern ([`confidence_level`]).

pub mod polycam;
pub mod record3d;
pub mod scanner;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use datasets::DepthImage;
use datasets::points::PointCloud;
use datasets::replica::{read_cam_params, read_trajectory};
use model::geometry::{Intrinsics, Pose, Similarity, Vec3};

/// Depth pixels per colour pixel along each axis.
pub const DEPTH_DIVISOR: u32 = 4;

/// The Replica frames an export is made from.
pub struct ReplicaFrames {
    /// Colour images, in frame order.
    pub images: Vec<PathBuf>,
    /// Depth images (16-bit, `1 / depth_scale` metres), in frame order.
    pub depths: Vec<PathBuf>,
    /// Camera-to-world, OpenCV axes, Replica's world.
    pub poses: Vec<Pose>,
    /// Intrinsics at the colour size.
    pub intrinsics: Intrinsics,
    /// Depth units per metre.
    pub depth_scale: f64,
}

impl ReplicaFrames {
    /// Reads a Nice-SLAM Replica directory (every frame).
    pub fn read(dir: &Path) -> Result<Self> {
        let cam = read_cam_params(&dir.join("cam_params.json"))?;
        let poses = read_trajectory(&dir.join("traj.txt"))?;
        let results = dir.join("results");
        let images: Vec<PathBuf> = (0..poses.len())
            .map(|i| results.join(format!("frame{i:06}.jpg")))
            .collect();
        let depths: Vec<PathBuf> = (0..poses.len())
            .map(|i| results.join(format!("depth{i:06}.png")))
            .collect();
        if let Some(missing) = images.iter().chain(&depths).find(|p| !p.is_file()) {
            bail!("{}: missing", missing.display());
        }
        Ok(Self {
            images,
            depths,
            poses,
            intrinsics: Intrinsics {
                width: cam.w,
                height: cam.h,
                fx: cam.fx,
                fy: cam.fy,
                cx: cam.cx,
                cy: cam.cy,
                distortion: model::geometry::Distortion::NONE,
            },
            depth_scale: cam.scale,
        })
    }

    /// The rigid map from Replica's world to the export's ARKit world: a
    /// turn of 30 degrees about Replica's z and a shift, then z up to y up.
    pub fn to_arkit() -> Similarity {
        let turn = Similarity {
            translation: [1.0, -2.0, 0.5],
            ..model::geometry::yaw_rotation(30f64.to_radians())
        };
        let z_up_to_y_up = Similarity {
            rotation: transpose(datasets::phone::ARKIT_TO_Z_UP),
            scale: 1.0,
            translation: [0.0; 3],
        };
        z_up_to_y_up.compose(&turn)
    }

    /// Frame `i`'s camera-to-world in the ARKit world with ARKit's camera
    /// axes, row-major.
    pub fn arkit_pose(&self, i: usize) -> [[f64; 4]; 4] {
        Self::to_arkit().apply_pose(&self.poses[i]).to_opengl()
    }

    /// The depth map's size.
    pub fn depth_size(&self) -> (u32, u32) {
        (
            self.intrinsics.width / DEPTH_DIVISOR,
            self.intrinsics.height / DEPTH_DIVISOR,
        )
    }

    /// Frame `i`'s depth in metres at [`Self::depth_size`]: each pixel the
    /// Replica depth nearest to its centre (the rule `load_depth16` resamples
    /// by, so the Replica loader at this size reads the same values).
    pub fn depth(&self, i: usize) -> Result<DepthImage> {
        let size = self.depth_size();
        Ok(datasets::imageio::load_depth16(
            &self.depths[i],
            self.depth_scale,
            Some(size),
        )?)
    }

    /// The Replica depth of frame `i` at full size.
    pub fn full_depth(&self, i: usize) -> Result<DepthImage> {
        Ok(datasets::imageio::load_depth16(
            &self.depths[i],
            self.depth_scale,
            None,
        )?)
    }
}

/// The transpose of a 3x3 matrix (the inverse of a rotation).
pub fn transpose(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[c][r]))
}

/// ARKit's confidence level (0, 1, 2) written for depth pixel `(x, y)` of
/// frame `frame`: 0 where there is no depth, otherwise mostly 2, with about
/// one pixel in eight at 1 and one in sixteen at 0, in a fixed scattered
/// pattern.
pub fn confidence_level(frame: usize, x: u32, y: u32, depth: f32) -> u8 {
    if depth <= 0.0 {
        return 0;
    }
    let h = (x as u64)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
        .wrapping_add((frame as u64).wrapping_mul(0x1656_67B1_9E37_79F9));
    match (h >> 40) % 16 {
        0 => 0,
        1 | 2 => 1,
        _ => 2,
    }
}

/// Depth as 16-bit millimetres (0 = none).
pub fn millimetres(depth: &DepthImage) -> Vec<u16> {
    depth
        .to_f32()
        .iter()
        .map(|&d| (d as f64 * 1000.0).round().clamp(0.0, 65535.0) as u16)
        .collect()
}

/// Writes a 16-bit single-channel PNG.
pub fn write_png16(path: &Path, (w, h): (u32, u32), values: Vec<u16>) -> Result<()> {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, values)
        .context("size")?
        .save(path)
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// Writes an 8-bit single-channel PNG.
pub fn write_png8(path: &Path, (w, h): (u32, u32), values: Vec<u8>) -> Result<()> {
    image::ImageBuffer::<image::Luma<u8>, Vec<u8>>::from_raw(w, h, values)
        .context("size")?
        .save(path)
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// Frame `i`'s confidence levels for its depth map `depth`.
pub fn confidence(i: usize, depth: &DepthImage) -> Vec<u8> {
    (0..depth.height)
        .flat_map(|y| (0..depth.width).map(move |x| (x, y)))
        .map(|(x, y)| confidence_level(i, x, y, depth.get(x, y)))
        .collect()
}

/// Copies a file, creating its directory.
pub fn copy(from: &Path, to: &Path) -> Result<()> {
    if let Some(dir) = to.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    }
    std::fs::copy(from, to).with_context(|| format!("{} -> {}", from.display(), to.display()))?;
    Ok(())
}

/// Ground-truth points of the Replica frames for scoring segmentation:
/// every `step`-th depth pixel of every frame, back-projected, labelled by
/// the class whose colour is nearest to the pixel's (the classes the
/// simulated VLM is given), in Replica's world.
pub fn labelled_points(
    frames: &ReplicaFrames,
    colours: &[[f32; 3]],
    step: u32,
) -> Result<PointCloud> {
    let mut cloud = PointCloud {
        positions: Vec::new(),
        colors: Some(Vec::new()),
        labels: Some(Vec::new()),
    };
    let k = frames.intrinsics;
    for (i, pose) in frames.poses.iter().enumerate() {
        let depth = frames.full_depth(i)?;
        let rgb = datasets::imageio::load_rgb(&frames.images[i], None, None)?;
        let camera = model::geometry::Camera {
            intrinsics: k,
            pose: *pose,
        };
        for y in (0..depth.height).step_by(step as usize) {
            for x in (0..depth.width).step_by(step as usize) {
                let d = depth.get(x, y) as f64;
                if d <= 0.0 {
                    continue;
                }
                let r = camera.ray(x as f64, y as f64);
                let p: Vec3 = std::array::from_fn(|a| r.origin[a] + d * r.direction[a]);
                let c = rgb.get(x, y);
                let label = nearest_colour(c, colours);
                cloud.positions.push(p);
                if let Some(cs) = cloud.colors.as_mut() {
                    cs.push(c.map(|v| (v * 255.0).round() as u8));
                }
                if let Some(ls) = cloud.labels.as_mut() {
                    ls.push(label as i64);
                }
            }
        }
    }
    Ok(cloud)
}

/// Index of the colour of `colours` nearest to `c`.
fn nearest_colour(c: [f32; 3], colours: &[[f32; 3]]) -> usize {
    let d = |a: &[f32; 3]| (0..3).map(|i| (a[i] - c[i]).powi(2)).sum::<f32>();
    (0..colours.len())
        .min_by(|&a, &b| d(&colours[a]).total_cmp(&d(&colours[b])))
        .unwrap_or(0)
}

/// `cloud` with its positions mapped by `s`.
pub fn mapped(cloud: &PointCloud, s: &Similarity) -> PointCloud {
    PointCloud {
        positions: cloud.positions.iter().map(|&p| s.apply_point(p)).collect(),
        ..cloud.clone()
    }
}
