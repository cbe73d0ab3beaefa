//! The coarse point cloud the uncertainty map is computed on.

use datasets::Scene;
use model::geometry::Vec3;

use super::voxel_downsample;
use crate::error::OpsError;

/// Points of the coarse cloud and where they came from.
#[derive(Debug, Clone, PartialEq)]
pub struct CoarseCloud {
    /// Positions, thinned to one point per voxel.
    pub positions: Vec<Vec3>,
    /// For a cloud taken from the scene's point cloud, the index of each
    /// position in it (to look up its label); `None` for back-projected depth.
    pub scene_indices: Option<Vec<usize>>,
}

/// The coarse cloud: the scene's point cloud when it has one, else the
/// training frames' depth back-projected; thinned to `voxel` metres.
/// `train` are the training frames' indices (checked against the scene).
pub fn coarse_points(scene: &Scene, train: &[usize], voxel: f64) -> Result<CoarseCloud, OpsError> {
    // Checked whether or not depth is used: the uncertainty map indexes the
    // frames with the same list.
    if let Some(&i) = train.iter().find(|&&i| i >= scene.frames.len()) {
        return Err(OpsError::Invalid(format!(
            "training frame {i} is not in scene {} ({} frames)",
            scene.name,
            scene.frames.len()
        )));
    }
    if let Some(points) = &scene.points {
        let keep = voxel_downsample(&points.positions, voxel);
        return Ok(CoarseCloud {
            positions: keep.iter().map(|&i| points.positions[i]).collect(),
            scene_indices: Some(keep),
        });
    }
    let mut all = Vec::new();
    for &i in train {
        let f = &scene.frames[i];
        if let Some(d) = &f.depth {
            let step = (d.width.max(d.height) / 64).max(1);
            all.extend(datasets::poses::backproject(&f.camera, d, step));
        }
    }
    if all.is_empty() {
        return Err(OpsError::Invalid(format!(
            "scene {} has no point cloud and no depth to back-project",
            scene.name
        )));
    }
    let keep = voxel_downsample(&all, voxel);
    Ok(CoarseCloud {
        positions: keep.iter().map(|&i| all[i]).collect(),
        scene_indices: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use datasets::synthetic::{SceneSize, generate};

    #[test]
    fn training_frames_outside_the_scene_are_refused_with_or_without_a_point_cloud() {
        let mut scene = generate(0, SceneSize::Ci).expect("CI scene");
        let n = scene.frames.len();
        assert!(scene.points.is_some());
        coarse_points(&scene, &[0, n - 1], 0.05).expect("all in the scene");
        for _ in 0..2 {
            let e = coarse_points(&scene, &[0, n], 0.05)
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("training frame {n}")), "{e}");
            // The same without the point cloud (depth is back-projected).
            scene.points = None;
        }
    }
}
