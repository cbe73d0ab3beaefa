//! Where novel cameras go: aimed at uncertain points, half-way along the
//! capture path, or at random in free space.

use burn::tensor::Device;
use datasets::Scene;
use model::OpenNerf;
use model::geometry::{Camera, Intrinsics, SceneBox, Vec3, add_scaled, look_at, norm, sub};
use rand::{Rng, SeedableRng};

use super::config::{NovelMode, NovelViewConfig};
use super::guided::{FieldProbe, ProposalOptions, gaussian, guided_proposals};
use crate::error::OpsError;
use crate::project::ProjectOptions;
use crate::uncertainty::coarse::coarse_points;
use crate::uncertainty::{UncertaintyOptions, uncertainty_map};

/// A camera to render, with the point it is aimed at (guided views).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AimedCamera {
    /// The camera.
    pub camera: Camera,
    /// Aim point.
    pub target: Option<Vec3>,
    /// Normalised uncertainty of the aim point.
    pub uncertainty: Option<f64>,
}

/// Cameras for `count` novel views chosen by `mode`, with the intrinsics of
/// the first training frame scaled by `config.scale`. `train` are the training frames' indices.
#[allow(clippy::too_many_arguments)]
pub fn choose_cameras(
    mode: NovelMode,
    count: usize,
    model: &OpenNerf,
    scene: &Scene,
    train: &[usize],
    config: &NovelViewConfig,
    seed: u64,
    device: &Device,
) -> Result<Vec<AimedCamera>, OpsError> {
    let first = *train
        .first()
        .ok_or_else(|| OpsError::Invalid("no training frames to place novel views by".into()))?;
    let intrinsics = scaled_intrinsics(scene.frames[first].camera.intrinsics, config.scale);
    let up = scene_up(scene, train);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let probe = FieldProbe {
        model,
        scene_box: &scene.scene_box,
        device,
        samples: 64,
        background: scene.background,
    };
    let opts = ProposalOptions {
        max_views: count,
        offset: config.offset,
        min_separation: config.min_separation,
        max_color_error: config.max_color_error.unwrap_or(f64::INFINITY),
        ..ProposalOptions::default()
    };
    Ok(match mode {
        NovelMode::None => Vec::new(),
        NovelMode::Trajectory => trajectory_cameras(scene, train, count, up)
            .into_iter()
            .map(|camera| AimedCamera {
                camera: Camera {
                    intrinsics,
                    ..camera
                },
                target: None,
                uncertainty: None,
            })
            .collect(),
        NovelMode::Random => random_cameras(
            &scene.scene_box,
            intrinsics,
            count,
            up,
            |p| probe.density(&[p])[0] <= opts.max_density,
            &mut rng,
        ),
        NovelMode::Guided => {
            let points = coarse_points(scene, train, config.voxel)?.positions;
            let map = uncertainty_map(
                scene,
                train,
                &points,
                &UncertaintyOptions {
                    normalisation: config.normalisation,
                    project: ProjectOptions::default(),
                    ..UncertaintyOptions::default()
                },
                |_, _| {},
            )?;
            if map.failed_factorisations > 0 {
                eprintln!(
                    "warning: the feature covariance of {} points could not be factorised; \
                     they count as the most uncertain",
                    map.failed_factorisations
                );
            }
            let centre = mean_centre(scene, train);
            guided_proposals(
                &map, &points, intrinsics, up, centre, &probe, &opts, &mut rng,
            )
            .proposals
            .into_iter()
            .take(count)
            .map(|p| AimedCamera {
                camera: p.camera,
                target: Some(points[p.target]),
                uncertainty: Some(map.normalised[p.target]),
            })
            .collect()
        }
    })
}

/// `k` resampled to `scale` times its size (at least one pixel a side).
pub fn scaled_intrinsics(k: Intrinsics, scale: f64) -> Intrinsics {
    let side = |n: u32| ((n as f64 * scale).round() as u32).max(1);
    k.scaled(side(k.width), side(k.height))
}

/// The scene's up direction: the mean of the training cameras' up axes
/// (OpenCV cameras have y pointing down).
pub fn scene_up(scene: &Scene, frames: &[usize]) -> Vec3 {
    let mut up = [0.0; 3];
    for &i in frames {
        let r = scene.frames[i].camera.pose.rotate([0.0, -1.0, 0.0]);
        (0..3).for_each(|a| up[a] += r[a]);
    }
    let n = norm(up);
    if n > 1e-9 {
        up.map(|v| v / n)
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// The mean position of the cameras of `frames`.
pub fn mean_centre(scene: &Scene, frames: &[usize]) -> Vec3 {
    let mut c = [0.0; 3];
    for &i in frames {
        let p = scene.frames[i].camera.pose.center();
        (0..3).for_each(|a| c[a] += p[a] / frames.len() as f64);
    }
    c
}

/// `count` cameras half-way between consecutive training cameras (in
/// capture order), spread evenly over the path: the position is the
/// midpoint, the view direction the normalised mean of the two.
pub fn trajectory_cameras(scene: &Scene, train: &[usize], count: usize, up: Vec3) -> Vec<Camera> {
    let mut order = train.to_vec();
    order.sort_unstable();
    if order.len() < 2 {
        return Vec::new();
    }
    let segments = order.len() - 1;
    let mut out = Vec::new();
    for j in 0..count.min(segments) {
        // Segment j * segments / count, evenly spaced over the path.
        let s = j * segments / count.min(segments);
        let (a, b) = (
            &scene.frames[order[s]].camera,
            &scene.frames[order[s + 1]].camera,
        );
        let (ca, cb) = (a.pose.center(), b.pose.center());
        let p = add_scaled(ca, 0.5, sub(cb, ca));
        let f = add_scaled(a.pose.forward(), 1.0, b.pose.forward());
        if norm(f) < 1e-9 {
            continue;
        }
        if let Ok(pose) = look_at(p, add_scaled(p, 1.0, f), up) {
            out.push(Camera {
                intrinsics: a.intrinsics,
                pose,
            });
        }
    }
    out
}

/// `count` cameras at positions uniform in the inner 80% of `scene_box`
/// where `free(p)` holds, looking in directions uniform on the sphere.
/// Gives up after `50 * count` draws.
pub fn random_cameras(
    scene_box: &SceneBox,
    intrinsics: Intrinsics,
    count: usize,
    up: Vec3,
    mut free: impl FnMut(Vec3) -> bool,
    rng: &mut impl Rng,
) -> Vec<AimedCamera> {
    let mut out = Vec::new();
    for _ in 0..50 * count {
        if out.len() == count {
            break;
        }
        let p: Vec3 = std::array::from_fn(|a| {
            let (lo, hi) = (scene_box.min[a], scene_box.max[a]);
            lo + (0.1 + 0.8 * rng.random::<f64>()) * (hi - lo)
        });
        // A uniform direction: a normalised Gaussian vector.
        let d: Vec3 = std::array::from_fn(|_| gaussian(rng));
        if norm(d) < 1e-9 || !free(p) {
            continue;
        }
        if let Ok(pose) = look_at(p, add_scaled(p, 1.0, d), up) {
            out.push(AimedCamera {
                camera: Camera { intrinsics, pose },
                target: None,
                uncertainty: None,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_cameras_stay_inside_the_box_and_where_free() {
        let b = SceneBox {
            min: [-1.0, -2.0, 0.0],
            max: [1.0, 2.0, 3.0],
        };
        let k = Intrinsics::from_fov_x(32, 24, 1.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        // Only the half x < 0 is free.
        let cams = random_cameras(&b, k, 12, [0.0, 0.0, 1.0], |p| p[0] < 0.0, &mut rng);
        assert_eq!(cams.len(), 12);
        for c in &cams {
            let p = c.camera.pose.center();
            assert!(p[0] < 0.0 && p[0] >= -0.8, "{p:?}");
            assert!(p[1].abs() <= 1.6 && (0.3..=2.7).contains(&p[2]), "{p:?}");
            assert!(c.camera.pose.orthonormality_error() < 1e-9);
        }
        // Nowhere free: bounded, empty.
        assert!(random_cameras(&b, k, 5, [0.0, 0.0, 1.0], |_| false, &mut rng).is_empty());
    }

    #[test]
    fn scaled_intrinsics_keep_the_field_of_view() {
        let k = Intrinsics::from_fov_x(320, 180, 1.2);
        let h = scaled_intrinsics(k, 0.5);
        assert_eq!((h.width, h.height), (160, 90));
        // The same ray through the image centre and through a corner edge.
        assert!((h.fx * 2.0 - k.fx).abs() < 1e-9);
        assert!(((h.cx + 0.5) * 2.0 - (k.cx + 0.5)).abs() < 1e-9);
        assert_eq!(scaled_intrinsics(k, 1.0), k);
        let tiny = scaled_intrinsics(k, 1e-6);
        assert_eq!((tiny.width, tiny.height), (1, 1));
    }
}
