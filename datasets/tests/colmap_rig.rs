//! The COLMAP loader on a synthetic rig written by the tests as a text
//! model: every supported camera model, rays and projections equal to the
//! rig's, downscaled image folders, dense depth maps and bad input.

use std::path::Path;

use datasets::DatasetError;
use datasets::colmap::{ColmapOptions, load_colmap};
use datasets::options::FrameSelection;
use model::geometry::{
    Camera, Distortion, Intrinsics, Pose, Vec3, add_scaled, cross, dot, look_at, norm, sub,
};

fn unit(v: Vec3) -> Vec3 {
    let n = norm(v);
    v.map(|x| x / n)
}

/// The rig's world up, deliberately not an axis.
const UP: Vec3 = [0.3, -0.4, 0.866_025_403_784_438_6];
/// The point the cameras look at.
const TARGET: Vec3 = [2.0, -1.0, 3.0];

/// One rig camera: its COLMAP model and parameters (pixel-corner
/// principal point), the same camera in our convention, and its pose.
struct RigCam {
    model: &'static str,
    params: Vec<f64>,
    camera: Camera,
}

fn intrinsics(w: u32, h: u32, f: [f64; 2], c: [f64; 2], distortion: Distortion) -> Intrinsics {
    Intrinsics {
        width: w,
        height: h,
        fx: f[0],
        fy: f[1],
        cx: c[0] - 0.5,
        cy: c[1] - 0.5,
        distortion,
    }
}

fn rig() -> Vec<RigCam> {
    let d = |k1, k2, p1, p2| Distortion {
        k1,
        k2,
        p1,
        p2,
        ..Distortion::NONE
    };
    let cams: [(&str, Vec<f64>, Intrinsics); 5] = [
        (
            "SIMPLE_PINHOLE",
            vec![35.0, 20.5, 14.0],
            intrinsics(40, 30, [35.0; 2], [20.5, 14.0], Distortion::NONE),
        ),
        (
            "PINHOLE",
            vec![40.0, 42.0, 24.0, 18.5],
            intrinsics(48, 36, [40.0, 42.0], [24.0, 18.5], Distortion::NONE),
        ),
        (
            "SIMPLE_RADIAL",
            vec![36.0, 20.0, 15.0, 0.05],
            intrinsics(40, 30, [36.0; 2], [20.0, 15.0], d(0.05, 0.0, 0.0, 0.0)),
        ),
        (
            "RADIAL",
            vec![34.0, 19.5, 15.5, 0.04, -0.01],
            intrinsics(40, 30, [34.0; 2], [19.5, 15.5], d(0.04, -0.01, 0.0, 0.0)),
        ),
        (
            "OPENCV",
            vec![38.0, 37.0, 21.0, 14.5, -0.05, 0.01, 0.002, -0.001],
            intrinsics(
                40,
                30,
                [38.0, 37.0],
                [21.0, 14.5],
                d(-0.05, 0.01, 0.002, -0.001),
            ),
        ),
    ];
    // Cameras on a circle of radius 4 around the target, 2.5 above it.
    let a = unit(cross(UP, [1.0, 0.0, 0.0]));
    let b = cross(UP, a);
    cams.into_iter()
        .enumerate()
        .map(|(i, (model, params, k))| {
            let t = i as f64 * 1.1;
            let pos: Vec3 = std::array::from_fn(|j| {
                TARGET[j] + 4.0 * (t.cos() * a[j] + t.sin() * b[j]) + 2.5 * UP[j]
            });
            let pose = look_at(pos, TARGET, UP).expect("pose");
            RigCam {
                model,
                params,
                camera: Camera {
                    intrinsics: k,
                    pose,
                },
            }
        })
        .collect()
}

/// Points scattered around the target (a few dozen).
fn rig_points() -> Vec<Vec3> {
    (0..40)
        .map(|i| {
            let f = |k: u32| ((i * 7 + k * 13) % 17) as f64 / 16.0 - 0.5;
            [
                TARGET[0] + 2.0 * f(0),
                TARGET[1] + 1.5 * f(1),
                TARGET[2] + f(2),
            ]
        })
        .collect()
}

/// Unit quaternion `(w, x, y, z)` of a rotation matrix (the test's own).
fn quaternion(r: [[f64; 3]; 3]) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    if tr > 0.0 {
        let s = 2.0 * (tr + 1.0).sqrt();
        [
            0.25 * s,
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = 2.0 * (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt();
        [
            (r[2][1] - r[1][2]) / s,
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = 2.0 * (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt();
        [
            (r[0][2] - r[2][0]) / s,
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
        ]
    } else {
        let s = 2.0 * (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt();
        [
            (r[1][0] - r[0][1]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
        ]
    }
}

/// World-to-camera rotation and translation of a camera-to-world pose.
fn world_to_camera(pose: &Pose) -> ([[f64; 3]; 3], Vec3) {
    let r = pose.rotation;
    let rt: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| r[j][i]));
    let c = pose.translation;
    let t = std::array::from_fn(|i| -(0..3).map(|k| rt[i][k] * c[k]).sum::<f64>());
    (rt, t)
}

fn image_name(i: usize) -> String {
    format!("cam{i}.png")
}

/// `cameras.txt`, `images.txt` and `points3D.txt` of the rig (image ids
/// in reverse name order, one camera per image).
fn rig_text(cams: &[RigCam], points: &[Vec3]) -> [String; 3] {
    let mut cameras = String::from("# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
    let mut images = String::from("# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n");
    for (i, c) in cams.iter().enumerate() {
        let k = &c.camera.intrinsics;
        let params: Vec<String> = c.params.iter().map(|p| p.to_string()).collect();
        cameras += &format!(
            "{} {} {} {} {}\n",
            i + 1,
            c.model,
            k.width,
            k.height,
            params.join(" ")
        );
        let (r, t) = world_to_camera(&c.camera.pose);
        let q = quaternion(r);
        let id = cams.len() - i;
        images += &format!(
            "{id} {} {} {} {} {} {} {} {} {}\n{}\n",
            q[0],
            q[1],
            q[2],
            q[3],
            t[0],
            t[1],
            t[2],
            i + 1,
            image_name(i),
            if i % 2 == 0 {
                ""
            } else {
                "10.5 3.25 -1 4.0 5.0 0"
            }
        );
    }
    let mut pts = String::from("# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]\n");
    for (i, p) in points.iter().enumerate() {
        pts += &format!(
            "{} {} {} {} 200 {} 30 0.5 1 {}\n",
            i,
            p[0],
            p[1],
            p[2],
            i * 5,
            i % 3
        );
    }
    [cameras, images, pts]
}

fn write_model(dir: &Path, [cameras, images, points]: &[String; 3]) {
    let sparse = dir.join("sparse").join("0");
    std::fs::create_dir_all(&sparse).expect("mkdir");
    for (name, text) in [
        ("cameras.txt", cameras),
        ("images.txt", images),
        ("points3D.txt", points),
    ] {
        std::fs::write(sparse.join(name), text).expect("write");
    }
}

/// Solid-colour PNGs at `1 / divisor` of each camera's size in `folder`.
fn write_images(dir: &Path, folder: &str, cams: &[RigCam], divisor: u32) {
    let d = dir.join(folder);
    std::fs::create_dir_all(&d).expect("mkdir");
    for (i, c) in cams.iter().enumerate() {
        let k = &c.camera.intrinsics;
        image::RgbImage::from_pixel(
            k.width / divisor,
            k.height / divisor,
            image::Rgb([40 * i as u8, 100, 200]),
        )
        .save(d.join(image_name(i)))
        .expect("png");
    }
}

/// A temp directory holding the rig's model and images.
fn rig_dir(cams: &[RigCam]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("tmp");
    write_model(dir.path(), &rig_text(cams, &rig_points()));
    write_images(dir.path(), "images", cams, 1);
    dir
}

fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() < tol)
}

#[test]
fn rays_and_projections_equal_the_rigs() {
    let cams = rig();
    let dir = rig_dir(&cams);
    let scene = load_colmap(dir.path(), &ColmapOptions::default()).expect("loads");
    let world = scene.world.as_ref().expect("world frame");
    assert_eq!(world.name, "colmap");
    let back = world.to_scene.inverse();
    assert_eq!(scene.frames.len(), cams.len());
    for (i, (frame, rig)) in scene.frames.iter().zip(&cams).enumerate() {
        assert_eq!(frame.name, format!("cam{i}"));
        let k = &frame.camera.intrinsics;
        assert_eq!(k, &rig.camera.intrinsics, "{}", rig.model);
        for (u, v) in [(0.0, 0.0), (39.0, 29.0), (17.0, 11.0), (3.5, 25.0)] {
            let r = frame.camera.ray(u, v);
            let want = rig.camera.ray(u, v);
            let o = back.apply_point(r.origin);
            let d = unit(back.apply_vector(r.direction));
            assert!(close(o, want.origin, 1e-6), "{} origin {o:?}", rig.model);
            assert!(
                close(d, unit(want.direction), 1e-6),
                "{} dir {d:?}",
                rig.model
            );
        }
        // Independently: COLMAP's own projection formulas.
        for p in rig_points() {
            let (u, v) = colmap_project(rig, p);
            let got = frame
                .camera
                .project(world.to_scene.apply_point(p))
                .expect("in front");
            assert!(
                (got.u - (u - 0.5)).abs() < 1e-6 && (got.v - (v - 0.5)).abs() < 1e-6,
                "{}: ({}, {}) vs COLMAP ({u}, {v})",
                rig.model,
                got.u,
                got.v
            );
        }
    }
}

/// COLMAP's projection (`colmap/sensor/models.h`) of a world point, in
/// COLMAP's pixel-corner convention.
fn colmap_project(cam: &RigCam, p: Vec3) -> (f64, f64) {
    let (r, t) = world_to_camera(&cam.camera.pose);
    let c: Vec3 = std::array::from_fn(|i| (0..3).map(|k| r[i][k] * p[k]).sum::<f64>() + t[i]);
    let (x, y) = (c[0] / c[2], c[1] / c[2]);
    let q = &cam.params;
    let (fx, fy, cx, cy, k1, k2, p1, p2) = match cam.model {
        "SIMPLE_PINHOLE" => (q[0], q[0], q[1], q[2], 0.0, 0.0, 0.0, 0.0),
        "PINHOLE" => (q[0], q[1], q[2], q[3], 0.0, 0.0, 0.0, 0.0),
        "SIMPLE_RADIAL" => (q[0], q[0], q[1], q[2], q[3], 0.0, 0.0, 0.0),
        "RADIAL" => (q[0], q[0], q[1], q[2], q[3], q[4], 0.0, 0.0),
        _ => (q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7]),
    };
    let (u2, v2, uv) = (x * x, y * y, x * y);
    let r2 = u2 + v2;
    let radial = k1 * r2 + k2 * r2 * r2;
    let du = x * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2);
    let dv = y * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2);
    (fx * (x + du) + cx, fy * (y + dv) + cy)
}

/// A model without sparse points (COLMAP's known-poses workflow, poses
/// from another system): the frame is fitted to the cameras, centred on
/// the point they look at, and says so; the same rig with its points is
/// fitted to them.
#[test]
fn without_sparse_points_the_frame_is_centred_where_the_cameras_look() {
    let cams = rig();
    let dir = tempfile::tempdir().expect("tmp");
    write_model(dir.path(), &rig_text(&cams, &[]));
    write_images(dir.path(), "images", &cams, 1);
    let scene = load_colmap(dir.path(), &ColmapOptions::default()).expect("loads");
    let world = scene.world.as_ref().expect("colmap frame");
    assert!(
        world.fitted_to.contains("0 points") && world.fitted_to.contains("optical axes"),
        "{}",
        world.fitted_to
    );
    let target = world.to_scene.apply_point(TARGET);
    assert!(norm(target) < 1e-9, "the target maps to {target:?}");
    let b = &scene.scene_box;
    let centre: Vec3 = std::array::from_fn(|k| 0.5 * (b.min[k] + b.max[k]));
    assert!(norm(centre) < 1e-9, "box centre {centre:?}");
    // What the cameras look at is inside the box (what they all see around
    // the spot they look at), and the cameras stand outside it, looking in.
    for p in rig_points() {
        assert!(b.contains(world.to_scene.apply_point(p)), "{p:?}");
    }
    for f in &scene.frames {
        let c = f.camera.pose.center();
        assert!(!b.contains(c), "camera {c:?} inside {b:?}");
    }
    let with_points = load_colmap(rig_dir(&cams).path(), &ColmapOptions::default())
        .expect("loads")
        .world
        .expect("colmap frame");
    assert!(
        with_points.fitted_to.contains("40 sparse points"),
        "{}",
        with_points.fitted_to
    );
}

#[test]
fn downscaled_images_scale_the_intrinsics() {
    let cams = rig();
    let dir = rig_dir(&cams);
    write_images(dir.path(), "images_2", &cams, 2);
    let opts = ColmapOptions {
        images: "images_2".into(),
        ..Default::default()
    };
    let scene = load_colmap(dir.path(), &opts).expect("loads");
    for (frame, rig) in scene.frames.iter().zip(&cams) {
        let (k, full) = (&frame.camera.intrinsics, &rig.camera.intrinsics);
        assert_eq!((k.width, k.height), (full.width / 2, full.height / 2));
        assert!((k.fx - full.fx / 2.0).abs() < 1e-12 && (k.fy - full.fy / 2.0).abs() < 1e-12);
        assert!((k.cx - ((full.cx + 0.5) / 2.0 - 0.5)).abs() < 1e-12);
        assert!((k.cy - ((full.cy + 0.5) / 2.0 - 0.5)).abs() < 1e-12);
        assert_eq!(k.distortion, full.distortion);
        assert_eq!((frame.rgb.width, frame.rgb.height), (k.width, k.height));
    }
    // An image of another aspect ratio is refused.
    image::RgbImage::new(20, 20)
        .save(dir.path().join("images_2").join(image_name(0)))
        .expect("png");
    let msg = load_colmap(dir.path(), &opts)
        .err()
        .expect("aspect")
        .to_string();
    assert!(
        msg.contains("cam0.png") && msg.contains("aspect ratio"),
        "{msg}"
    );
}

#[test]
fn stride_and_max_frames_apply_in_name_order() {
    let cams = rig();
    let dir = rig_dir(&cams);
    let opts = ColmapOptions {
        selection: FrameSelection {
            stride: 2,
            max_frames: Some(2),
            ..FrameSelection::default()
        },
        ..Default::default()
    };
    let scene = load_colmap(dir.path(), &opts).expect("loads");
    let names: Vec<&str> = scene.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["cam0", "cam2"]);
    // The frame does not depend on the frames kept; the source rebuilds it.
    let all = load_colmap(dir.path(), &ColmapOptions::default()).expect("loads");
    assert_eq!(all.world, scene.world);
    assert_eq!(all.frames[2], scene.frames[1]);
    let again = datasets::load_scene(&scene.source).expect("reloads");
    assert_eq!(again.frames, scene.frames);
    let pts = scene.points.as_ref().expect("points");
    assert_eq!(pts.positions.len(), 40);
    assert_eq!(pts.colors.as_ref().expect("colours")[3], [200, 15, 30]);
}

#[path = "colmap_rig/bad.rs"]
mod bad;
#[path = "colmap_rig/depth.rs"]
mod depth;
#[path = "colmap_rig/sparse_depth.rs"]
mod sparse_depth;
