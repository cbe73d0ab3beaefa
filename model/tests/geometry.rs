//! Cameras, poses, rays and the scene box against direct constructions.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

use model::geometry::{
    Camera, GeometryError, Intrinsics, Pose, SceneBox, cross, dot, look_at, norm, sub,
};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    [a[0] / n, a[1] / n, a[2] / n]
}

/// look_at gives an orthonormal right-handed frame, z towards the target and
/// y pointing away from `up`, also when the view is parallel to `up`.
#[test]
fn look_at_frame() {
    let cases = [
        ([1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, 0.0, 5.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, -4.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]),
        ([-3.0, 0.5, 2.0], [1.0, 1.0, 1.0], [0.0, -1.0, 0.0]),
    ];
    for (pos, target, up) in cases {
        let pose = look_at(pos, target, up).expect("valid");
        assert!(pose.orthonormality_error() < 1e-12);
        let r = pose.rotation;
        let x = [r[0][0], r[1][0], r[2][0]];
        let y = [r[0][1], r[1][1], r[2][1]];
        let z = pose.forward();
        // Right-handed: x cross y = z.
        let c = cross(x, y);
        assert!((0..3).all(|k| close(c[k], z[k], 1e-12)));
        let want_z = unit(sub(target, pos));
        assert!(
            (0..3).all(|k| close(z[k], want_z[k], 1e-12)),
            "z points at the target"
        );
        assert_eq!(pose.center(), pos);
        let parallel = norm(cross(want_z, up)) < 1e-9;
        if !parallel {
            // y is opposite to the component of up orthogonal to z.
            assert!(dot(y, up) < 0.0, "y must point away from up");
            assert!(close(dot(x, up), 0.0, 1e-12), "x is horizontal");
        }
        // The target projects to the principal point.
        let cam = Camera {
            intrinsics: Intrinsics::from_fov_x(64, 48, 1.0),
            pose,
        };
        let p = cam.project(target).expect("in front");
        assert!(close(p.u, 31.5, 1e-9) && close(p.v, 23.5, 1e-9));
    }
    assert_eq!(
        look_at([1.0; 3], [1.0; 3], [0.0, 0.0, 1.0]),
        Err(GeometryError::CoincidentPoints)
    );
    assert_eq!(
        look_at([f64::NAN, 0.0, 0.0], [1.0; 3], [0.0, 0.0, 1.0]),
        Err(GeometryError::NonFinite)
    );
}

/// OpenGL <-> OpenCV conversion round-trips, flips the camera y and z axes,
/// and non-rigid or non-finite matrices are rejected.
#[test]
fn opengl_opencv_round_trip() {
    let pose = look_at([1.0, -2.0, 0.5], [0.2, 0.3, 0.1], [0.0, 0.0, 1.0]).expect("valid");
    let gl = pose.to_opengl();
    let back = Pose::from_opengl(gl).expect("rigid");
    for i in 0..3 {
        for j in 0..3 {
            assert!(close(back.rotation[i][j], pose.rotation[i][j], 1e-12));
        }
        // OpenGL camera looks down -z: its third column is minus the OpenCV forward.
        assert!(close(gl[i][2], -pose.forward()[i], 1e-12));
        assert!(close(gl[i][1], -pose.rotation[i][1], 1e-12));
        assert!(close(gl[i][0], pose.rotation[i][0], 1e-12));
    }
    assert_eq!(back.translation, pose.translation);
    let mut bad = pose.to_matrix();
    bad[0][0] *= 1.5;
    assert!(matches!(
        Pose::from_matrix(bad),
        Err(GeometryError::NotRigid { .. })
    ));
    let mut bad = pose.to_matrix();
    bad[3][1] = 0.2;
    assert!(matches!(
        Pose::from_matrix(bad),
        Err(GeometryError::NotRigid { .. })
    ));
    let mut bad = pose.to_matrix();
    bad[1][3] = f64::INFINITY;
    assert_eq!(Pose::from_matrix(bad), Err(GeometryError::NonFinite));
}

/// A point on the ray through (u, v) projects back to (u, v) at depth t (the
/// ray parameter is z-depth), and world <-> camera maps are inverse.
#[test]
fn ray_projection_round_trip() {
    let pose = look_at([0.5, 1.0, -2.0], [0.0, 0.0, 0.0], [0.0, -1.0, 0.0]).expect("valid");
    let cam = Camera {
        intrinsics: Intrinsics {
            width: 640,
            height: 360,
            fx: 300.0,
            fy: 310.0,
            cx: 319.5,
            cy: 170.0,
            distortion: model::geometry::Distortion::NONE,
        },
        pose,
    };
    for (u, v, t) in [(0.0, 0.0, 1.0), (639.0, 359.0, 3.5), (100.25, 200.75, 0.1)] {
        let ray = cam.ray(u, v);
        let p = [
            ray.origin[0] + t * ray.direction[0],
            ray.origin[1] + t * ray.direction[1],
            ray.origin[2] + t * ray.direction[2],
        ];
        let proj = cam.project(p).expect("in front");
        assert!(close(proj.u, u, 1e-9) && close(proj.v, v, 1e-9) && close(proj.z, t, 1e-12));
        let q = cam.pose.camera_to_world(cam.pose.world_to_camera(p));
        assert!((0..3).all(|k| close(q[k], p[k], 1e-12)));
    }
    // Behind the camera.
    let behind = cam.pose.camera_to_world([0.0, 0.0, -1.0]);
    assert!(cam.project(behind).is_none());
    // Base radius: dx 2 / sqrt(12) with dx the mean pixel pitch at z = 1.
    let want = 0.5 * (1.0 / 300.0 + 1.0 / 310.0) * 2.0 / 12f64.sqrt();
    assert!(close(cam.intrinsics.base_radius(), want, 1e-15));
}

/// Resampling intrinsics maps pixel edges to pixel edges: the image-plane
/// point under a given direction keeps its relative position.
#[test]
fn intrinsics_scaled() {
    let k = Intrinsics {
        width: 1200,
        height: 680,
        fx: 600.0,
        fy: 600.0,
        cx: 599.5,
        cy: 339.5,
        distortion: model::geometry::Distortion::NONE,
    };
    let s = k.scaled(640, 360);
    assert!(close(s.fx, 320.0, 1e-12) && close(s.fy, 600.0 * 360.0 / 680.0, 1e-12));
    assert!(close(s.cx, 319.5, 1e-12) && close(s.cy, 179.5, 1e-12));
    // The left edge of pixel 0 (u = -0.5) sees the same direction at both sizes.
    let d0 = k.camera_direction(-0.5, -0.5);
    let d1 = s.camera_direction(-0.5, -0.5);
    assert!(close(d0[0], d1[0], 1e-12) && close(d0[1], d1[1], 1e-12));
    let round = s.scaled(1200, 680);
    assert!(close(round.cx, k.cx, 1e-9) && close(round.fy, k.fy, 1e-9));
    let fov = Intrinsics::from_fov_x(800, 800, 0.6911112070083618);
    assert!(close(
        fov.fx,
        400.0 / (0.5f64 * 0.6911112070083618).tan(),
        1e-9
    ));
    assert!(close(fov.cx, 399.5, 1e-12));
}

/// Slab intersection against brute-force marching, including axis-parallel
/// rays, rays starting inside, and misses; normalisation maps the box into
/// [-pi, pi]^3 and keeps t metric.
#[test]
fn scene_box_intersection() {
    let b = SceneBox {
        min: [-1.0, -2.0, 0.0],
        max: [3.0, 2.0, 1.0],
    };
    let cases: [([f64; 3], [f64; 3]); 7] = [
        ([-5.0, 0.0, 0.5], [1.0, 0.0, 0.0]),
        ([0.0, 5.0, 0.5], [0.0, -2.0, 0.0]),
        ([0.0, 0.0, 0.5], [0.3, 0.2, 0.1]),
        ([-5.0, 3.0, 0.5], [1.0, 0.0, 0.0]),
        ([-5.0, -5.0, -5.0], [1.0, 1.0, 1.0]),
        ([5.0, 0.0, 0.5], [1.0, 0.0, 0.0]),
        ([0.0, 0.0, 5.0], [0.0, 0.0, -0.5]),
    ];
    for (o, d) in cases {
        let got = b.intersect(o, d);
        // Brute force: inside-ness on a fine t grid.
        let mut inside = Vec::new();
        let steps = 200_000;
        for i in 0..=steps {
            let t = 20.0 * i as f64 / steps as f64;
            let p = [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
            if b.contains(p) {
                inside.push(t);
            }
        }
        match got {
            None => assert!(inside.is_empty(), "missed {o:?} {d:?}"),
            Some((t0, t1)) => {
                let (a, z) = (inside[0], inside[inside.len() - 1]);
                assert!(
                    close(t0, a, 2e-4) && close(t1, z, 2e-4),
                    "{o:?} {d:?}: {t0} {t1} vs {a} {z}"
                );
            }
        }
    }
    assert!(close(b.scale(), std::f64::consts::PI / 2.0, 1e-12));
    let corner = b.normalize_point([3.0, 2.0, 1.0]);
    assert!(close(corner[0], std::f64::consts::PI, 1e-12));
    let back = b.denormalize_point(corner);
    assert!(close(back[1], 2.0, 1e-12));
    let pts = [[0.0, 0.0, 0.0], [2.0, 1.0, -1.0], [f64::NAN, 0.0, 0.0]];
    let fit = SceneBox::from_points(pts, 0.1).expect("finite points");
    assert!(fit.contains([0.0, 0.0, 0.0]) && fit.contains([2.0, 1.0, -1.0]));
    assert!(close(fit.min[0], -0.2, 1e-12) && close(fit.max[2], 0.2, 1e-12));
    assert!(SceneBox::from_points([[f64::NAN; 3]], 0.1).is_none());
}

/// Distorted cameras: projecting the ray of every pixel (a grid over the
/// whole image, corners included) returns that pixel to 1e-6 px, for
/// COLMAP's SIMPLE_RADIAL / RADIAL / OPENCV and nerfstudio's OPENCV with
/// k3, k4 at strengths real lenses have (barrel and pincushion).
#[test]
fn distorted_rays_project_back_to_their_pixels() {
    use model::geometry::Distortion;
    let lenses = [
        Distortion {
            k1: -0.12,
            ..Distortion::NONE
        },
        Distortion {
            k1: 0.08,
            k2: -0.02,
            ..Distortion::NONE
        },
        Distortion {
            k1: -0.28,
            k2: 0.07,
            p1: 1.2e-3,
            p2: -8e-4,
            ..Distortion::NONE
        },
        Distortion {
            k1: -0.25,
            k2: 0.06,
            k3: -0.006,
            k4: 4e-4,
            p1: -5e-4,
            p2: 9e-4,
        },
    ];
    for distortion in lenses {
        let cam = Camera {
            intrinsics: Intrinsics {
                width: 3031,
                height: 2006,
                fx: 2500.0,
                fy: 2480.0,
                cx: 1515.0,
                cy: 1002.5,
                distortion,
            },
            pose: model::geometry::look_at([0.5, -1.0, 2.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
                .expect("pose"),
        };
        let mut worst: f64 = 0.0;
        for j in (0..=2005).step_by(59).chain([2005]) {
            for i in (0..=3030).step_by(61).chain([3030]) {
                let (u, v) = (i as f64, j as f64);
                let ray = cam.ray(u, v);
                let p = cam
                    .project(model::geometry::add_scaled(ray.origin, 3.0, ray.direction))
                    .expect("in front");
                worst = worst.max((p.u - u).abs()).max((p.v - v).abs());
            }
        }
        assert!(
            worst < 1e-6,
            "{distortion:?}: worst round trip {worst:e} px"
        );
        // And the distortion is real: a corner ray is not the pinhole one.
        let pin = Intrinsics {
            distortion: Distortion::NONE,
            ..cam.intrinsics
        };
        let d = cam.intrinsics.camera_direction(0.0, 0.0);
        let q = pin.camera_direction(0.0, 0.0);
        assert!(
            (d[0] - q[0]).abs() > 1e-3,
            "{distortion:?} moves the corner ray"
        );
    }
}
