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
    if let Some(points) = &scene.points {
        let keep = voxel_downsample(&points.positions, voxel);
        return Ok(CoarseCloud {
            positions: keep.iter().map(|&i| points.positions[i]).collect(),
            scene_indices: Some(keep),
        });
    }
    let mut all = Vec::new();
    for &i in train {
        let f = scene.frames.get(i).ok_or_else(|| {
            OpsError::Invalid(format!(
                "training frame {i} is not in scene {} ({} frames)",
                scene.name,
                scene.frames.len()
            ))
        })?;
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
