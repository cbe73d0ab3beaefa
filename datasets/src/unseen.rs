//! Rays of small square patches seen from viewpoints between the training
//! cameras, where no photograph constrains the field: RegNeRF's unobserved
//! views (Niemeyer et al. 2022, section 4.1), on which a few-view field is
//! asked for smooth depth.
//!
//! A viewpoint lies on the segment between a training camera and one of its
//! two nearest training cameras, looking in the interpolated direction with
//! the interpolated up, with the first camera's intrinsics: the views a
//! capture's held-out photographs are taken from, for a capture walked
//! around an object or along a room.

use model::geometry::{Camera, NormalizedRay, Vec3, look_at, norm, sub};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::Scene;

/// How many patches, their side in rays and the pixels between neighbouring
/// rays of a patch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchLayout {
    /// Patches a batch (each from its own viewpoint).
    pub patches: usize,
    /// Rays along each side of a patch.
    pub side: usize,
    /// Pixels between neighbouring rays of a patch, at the first camera's
    /// resolution.
    pub stride: usize,
}

/// The rays of `layout.patches` patches, each `side x side` rays in
/// row-major order, patch after patch, from viewpoints between the cameras
/// of `train` (indices into `scene.frames`), drawn from `seed`. Empty when
/// `train` has fewer than two cameras (there is nothing between them).
pub fn unseen_patch_rays(
    scene: &Scene,
    train: &[usize],
    layout: PatchLayout,
    min_near: f64,
    seed: u64,
) -> Vec<NormalizedRay> {
    if train.len() < 2 || layout.side == 0 {
        return Vec::new();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut rays = Vec::with_capacity(layout.patches * layout.side * layout.side);
    for _ in 0..layout.patches {
        let a = train[rng.random_range(0..train.len())];
        let near = nearest_two(scene, train, a);
        let b = near[rng.random_range(0..near.len())];
        let t = rng.random_range(0.0..1.0);
        let Some(camera) = between(&scene.frames[a].camera, &scene.frames[b].camera, t) else {
            continue;
        };
        let span = (layout.side - 1) * layout.stride;
        let (w, h) = (
            camera.intrinsics.width as usize,
            camera.intrinsics.height as usize,
        );
        let x0 = rng.random_range(0..w.saturating_sub(span).max(1));
        let y0 = rng.random_range(0..h.saturating_sub(span).max(1));
        for j in 0..layout.side {
            for i in 0..layout.side {
                let (x, y) = (x0 + i * layout.stride, y0 + j * layout.stride);
                let ray = camera.ray(x as f64, y as f64);
                rays.push(scene.scene_box.normalize_ray(&ray, min_near));
            }
        }
    }
    rays
}

/// The (at most two) training cameras whose centres lie nearest camera
/// `a`'s, `a` excluded.
fn nearest_two(scene: &Scene, train: &[usize], a: usize) -> Vec<usize> {
    let centre = scene.frames[a].camera.pose.center();
    let mut others: Vec<(f64, usize)> = train
        .iter()
        .filter(|&&i| i != a)
        .map(|&i| {
            let c = scene.frames[i].camera.pose.center();
            (norm(sub(c, centre)), i)
        })
        .collect();
    others.sort_by(|x, y| x.0.total_cmp(&y.0));
    others.into_iter().take(2).map(|(_, i)| i).collect()
}

/// The camera a fraction `t` of the way from `a` to `b`: centre and viewing
/// direction interpolated linearly, up likewise, `a`'s intrinsics. `None`
/// when the interpolated direction or up vanishes (cameras facing each
/// other head on).
pub fn between(a: &Camera, b: &Camera, t: f64) -> Option<Camera> {
    let lerp = |p: Vec3, q: Vec3| -> Vec3 { std::array::from_fn(|k| p[k] + t * (q[k] - p[k])) };
    let centre = lerp(a.pose.center(), b.pose.center());
    let forward = lerp(a.pose.forward(), b.pose.forward());
    // OpenCV's y axis points down the image: up is its opposite.
    let up = lerp(down(a), down(b)).map(|v| -v);
    if norm(forward) < 1e-6 || norm(up) < 1e-6 {
        return None;
    }
    let target = std::array::from_fn(|k| centre[k] + forward[k]);
    let pose = look_at(centre, target, up).ok()?;
    Some(Camera {
        intrinsics: a.intrinsics,
        pose,
    })
}

/// A camera's image-down axis (OpenCV y) in world coordinates.
fn down(camera: &Camera) -> Vec3 {
    let r = &camera.pose.rotation;
    [r[0][1], r[1][1], r[2][1]]
}
