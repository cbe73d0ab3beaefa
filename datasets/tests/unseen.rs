//! Patches from viewpoints between the training cameras: the viewpoint's
//! interpolation, where its rays start, how many there are and their
//! determinism.

use datasets::synthetic::{SceneSize, generate};
use datasets::unseen::{PatchLayout, between, unseen_patch_rays};
use model::geometry::{Camera, Intrinsics, Vec3, look_at};

fn camera(position: Vec3, target: Vec3) -> Camera {
    Camera {
        intrinsics: Intrinsics::from_fov_x(64, 48, 1.0),
        pose: look_at(position, target, [0.0, 0.0, 1.0]).expect("pose"),
    }
}

fn close(a: Vec3, b: Vec3, tol: f64, what: &str) {
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() <= tol, "{what}: {a:?} vs {b:?}");
    }
}

/// At `t = 0` and `t = 1` the viewpoint is each end's camera (centre and
/// every axis); halfway, its centre is the midpoint and it looks along the
/// normalised mean of the two directions; the intrinsics are the first's.
#[test]
fn the_viewpoint_interpolates_between_two_cameras() {
    let a = camera([3.0, 0.0, 1.0], [0.0, 0.0, 0.0]);
    let b = camera([0.0, 3.0, 2.0], [0.0, 0.5, 0.0]);
    for (t, end) in [(0.0, &a), (1.0, &b)] {
        let v = between(&a, &b, t).expect("viewpoint");
        close(v.pose.center(), end.pose.center(), 1e-12, "centre");
        for k in 0..3 {
            let axis = |c: &Camera| [0, 1, 2].map(|r| c.pose.rotation[r][k]);
            close(axis(&v), axis(end), 1e-9, &format!("axis {k} at t = {t}"));
        }
        assert_eq!(v.intrinsics, a.intrinsics);
    }
    let mid = between(&a, &b, 0.5).expect("viewpoint");
    close(mid.pose.center(), [1.5, 1.5, 1.5], 1e-12, "midpoint");
    let (fa, fb) = (a.pose.forward(), b.pose.forward());
    let sum = [fa[0] + fb[0], fa[1] + fb[1], fa[2] + fb[2]];
    let len = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
    close(
        mid.pose.forward(),
        sum.map(|x| x / len),
        1e-9,
        "mean direction",
    );
    // Cameras facing each other head on have no mean direction.
    let c = camera([-3.0, 0.0, 1.0], [0.0, 0.0, 1.0]);
    let d = camera([3.0, 0.0, 1.0], [0.0, 0.0, 1.0]);
    assert!(between(&c, &d, 0.5).is_none());
}

/// `patches * side^2` rays, the same for one seed and others for another;
/// the rays of a patch share one origin, which lies between a training
/// camera and one of its two nearest training cameras (in the field's
/// normalised frame); fewer than two training cameras give none.
#[test]
fn patch_rays_start_between_neighbouring_training_cameras() {
    let scene = generate(0, SceneSize::Ci).expect("scene");
    let train: Vec<usize> = (0..scene.frames.len()).filter(|i| i % 4 != 0).collect();
    let layout = PatchLayout {
        patches: 6,
        side: 4,
        stride: 3,
    };
    let rays = unseen_patch_rays(&scene, &train, layout, 0.05, 7);
    assert_eq!(rays.len(), 6 * 16);
    assert_eq!(rays, unseen_patch_rays(&scene, &train, layout, 0.05, 7));
    assert_ne!(rays, unseen_patch_rays(&scene, &train, layout, 0.05, 8));
    let centre = |i: usize| {
        let p = scene
            .scene_box
            .normalize_point(scene.frames[i].camera.pose.center());
        [p[0], p[1], p[2]]
    };
    let dist = |p: Vec3, q: Vec3| {
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    };
    for patch in rays.chunks_exact(16) {
        assert!(patch.iter().all(|r| r.origin == patch[0].origin));
        let o = patch[0].origin.map(|x| x as f64);
        // On the segment from a to its neighbour b: |o - a| + |o - b| = |a - b|.
        let on_a_segment = train.iter().any(|&a| {
            let mut near: Vec<usize> = train.iter().copied().filter(|&i| i != a).collect();
            near.sort_by(|&i, &j| {
                dist(centre(i), centre(a)).total_cmp(&dist(centre(j), centre(a)))
            });
            near.iter().take(2).any(|&b| {
                (dist(o, centre(a)) + dist(o, centre(b)) - dist(centre(a), centre(b))).abs() < 1e-4
            })
        });
        assert!(
            on_a_segment,
            "origin {o:?} lies on no segment between neighbours"
        );
    }
    assert!(unseen_patch_rays(&scene, &train[..1], layout, 0.05, 7).is_empty());
}
