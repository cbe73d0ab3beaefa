//! Depth targets from the sparse points: each image's 2D features that
//! observe a 3D point give that point's z-depth at the feature's pixel
//! (DS-NeRF's supervision, Deng et al., CVPR 2022). Every other pixel has
//! no target (0).
//!
//! A few hundred pixels of an image get a target, so uniform ray sampling
//! would almost never draw one: `SamplerConfig::depth_rays` draws rays
//! from the pixels with a target on purpose.

use std::collections::HashMap;

use ::model::geometry::{Pose, Vec3};

use super::model::{Image, Point3D};
use crate::scene::DepthImage;

/// Points whose mean reprojection error exceeds this many pixels give no
/// target (COLMAP keeps points up to 4 px by default; a badly placed point
/// would pull the field towards the wrong depth).
pub const MAX_REPROJECTION_ERROR: f64 = 2.0;

/// The sparse points by id, in the scene frame, with their mean
/// reprojection error.
pub fn points_by_id(points: &[Point3D], scene_xyz: &[Vec3]) -> HashMap<u64, (Vec3, f64)> {
    points
        .iter()
        .zip(scene_xyz)
        .map(|(p, &xyz)| (p.id, (xyz, p.error)))
        .collect()
}

/// The depth target of `image` at `(width, height)` pixels, whose camera
/// (full-size width `camera_width`, pose `pose` in the scene frame) sees
/// `points` (scene frame, [`points_by_id`]): at the pixel holding each of
/// its features that observes a point (reprojection error at most
/// [`MAX_REPROJECTION_ERROR`], in front of the camera), the point's
/// z-depth; where two features share a pixel, the nearer.
pub fn sparse_depth_target(
    image: &Image,
    pose: &Pose,
    points: &HashMap<u64, (Vec3, f64)>,
    camera_width: u32,
    (width, height): (u32, u32),
) -> DepthImage {
    let mut data = vec![0.0f32; width as usize * height as usize];
    let scale = width as f64 / camera_width.max(1) as f64;
    let r = &pose.rotation;
    let c = pose.translation;
    for p2 in &image.points2d {
        let Some(&(xyz, error)) = p2.point3d_id.and_then(|id| points.get(&id)) else {
            continue;
        };
        if error > MAX_REPROJECTION_ERROR {
            continue;
        }
        // The camera's optical axis is the rotation's third column.
        let z: f64 = (0..3).map(|i| (xyz[i] - c[i]) * r[i][2]).sum();
        // COLMAP's pixel coordinates count from the pixel's corner.
        let (x, y) = ((p2.xy[0] * scale).floor(), (p2.xy[1] * scale).floor());
        if !(z > 0.0 && z.is_finite()) || x < 0.0 || y < 0.0 {
            continue;
        }
        let (x, y) = (x as usize, y as usize);
        if x >= width as usize || y >= height as usize {
            continue;
        }
        let cell = &mut data[y * width as usize + x];
        if *cell == 0.0 || (z as f32) < *cell {
            *cell = z as f32;
        }
    }
    DepthImage {
        width,
        height,
        data: crate::scene::DepthData::F32(data),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colmap::Point2D;

    fn point(id: u64, error: f64) -> Point3D {
        Point3D {
            id,
            xyz: [0.0; 3],
            rgb: [0; 3],
            error,
            track: Vec::new(),
        }
    }

    #[test]
    fn targets_the_nearest_well_placed_point_in_front_at_its_feature_pixel() {
        // A camera at the origin looking down +z (identity rotation).
        let pose = Pose {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
        };
        let feature = |xy: [f64; 2], id: u64| Point2D {
            xy,
            point3d_id: Some(id),
        };
        let image = Image {
            id: 1,
            qvec: [1.0, 0.0, 0.0, 0.0],
            tvec: [0.0; 3],
            camera_id: 1,
            name: "a.jpg".into(),
            points2d: vec![
                feature([3.9, 1.2], 1),
                feature([3.1, 1.9], 2),
                feature([0.5, 0.5], 3),
                feature([1.5, 0.5], 4),
                feature([2.5, 0.5], 99),
                Point2D {
                    xy: [6.5, 1.5],
                    point3d_id: None,
                },
            ],
        };
        let xyz = [
            [0.0, 0.0, 4.0],
            [1.0, 1.0, 3.0],
            [0.0, 0.0, -1.0],
            [0.0, 0.0, 2.0],
        ];
        let pts = [point(1, 0.5), point(2, 1.0), point(3, 0.1), point(4, 3.0)];
        let points = points_by_id(&pts, &xyz);
        // The camera is 16 px wide, the image 8: features at half their xy.
        let d = sparse_depth_target(&image, &pose, &points, 16, (8, 4));
        let mut want = vec![0.0; 32];
        // Points 1 and 2 share pixel (1, 0); point 2 is nearer.
        want[1] = 3.0;
        assert_eq!(d.to_f32(), want);
    }
}
