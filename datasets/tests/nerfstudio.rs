//! nerfstudio `transforms.json` captures: per-frame cameras with OpenCV
//! distortion, depth, masks, `applied_transform` and `ply_file_path`,
//! written by `write_nerfstudio` and read back by `load_blender`; bad files
//! refused naming the file.

use std::path::Path;

use datasets::blender::{BlenderOptions, load_blender, read_cameras, robust_points_box};
use datasets::points::PointCloud;
use datasets::writer::{ImageFormat, write_nerfstudio};
use datasets::{DepthImage, Frame, RgbImage, Scene, SceneSource, WorldFrame};
use model::geometry::{Camera, Distortion, Intrinsics, SceneBox, Similarity, look_at};
use serde_json::{Value, json};

fn frame(i: usize, k: Intrinsics) -> Frame {
    let (w, h) = (k.width, k.height);
    let mut rgb = Vec::new();
    let mut depth = Vec::new();
    let mut mask = Vec::new();
    for y in 0..h {
        for x in 0..w {
            rgb.extend([x as f32 / w as f32, y as f32 / h as f32, 0.3 * i as f32]);
            // Some pixels without depth; others at sub-millimetre values.
            let d = if (x + y) % 7 == 0 {
                0.0
            } else {
                1.0 + 0.01234 * x as f32 + 0.0077 * y as f32
            };
            depth.push(d);
            // Frame 0: left half masked out; frame 1: a block.
            mask.push(if i == 0 {
                x >= w / 2
            } else {
                !(x < 10 && y < 8)
            });
        }
    }
    let pos = [
        3.0 * (i as f64 + 0.5).cos(),
        3.0 * (i as f64 + 0.5).sin(),
        1.0,
    ];
    Frame {
        name: format!("view{i}"),
        camera: Camera {
            intrinsics: k,
            pose: look_at(pos, [0.0; 3], [0.0, 0.0, 1.0]).expect("pose"),
        },
        rgb: RgbImage {
            width: w,
            height: h,
            data: datasets::RgbData::F32(rgb),
        },
        depth: Some(DepthImage {
            width: w,
            height: h,
            data: datasets::DepthData::F32(depth),
        }),
        depth_weight: 1.0,
        color_weight: 1.0,
        labels: None,
        mask: Some(mask),
    }
}

/// nerfstudio's axis swap for COLMAP captures, with a scale and shift.
fn applied() -> Similarity {
    Similarity {
        rotation: [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]],
        scale: 0.5,
        translation: [0.1, -0.2, 0.3],
    }
}

fn points() -> PointCloud {
    // A 6x6x6 lattice over [-0.5, 0.5]^3 and two strays far away.
    let mut positions = Vec::new();
    for i in 0..216 {
        let c = |k: usize| -0.5 + (k % 6) as f64 / 5.0;
        positions.push([c(i), c(i / 6), c(i / 36)]);
    }
    positions.push([40.0, 0.0, 0.0]);
    positions.push([0.0, -30.0, 9.0]);
    PointCloud {
        positions,
        colors: None,
        labels: None,
    }
}

fn scene() -> Scene {
    let a = Intrinsics {
        width: 48,
        height: 36,
        fx: 40.0,
        fy: 42.0,
        cx: 23.2,
        cy: 17.9,
        distortion: Distortion {
            k1: -0.1,
            k2: 0.02,
            k3: -0.003,
            k4: 0.0005,
            p1: 1e-3,
            p2: -5e-4,
        },
    };
    let b = Intrinsics {
        width: 40,
        height: 30,
        fx: 35.0,
        fy: 35.5,
        cx: 19.5,
        cy: 14.0,
        distortion: Distortion {
            k1: 0.05,
            k2: -0.01,
            k3: 0.002,
            k4: -0.0001,
            p1: -2e-4,
            p2: 3e-4,
        },
    };
    Scene {
        name: "capture".into(),
        frames: vec![frame(0, a), frame(1, b)],
        features: None,
        scene_box: SceneBox {
            min: [-1.0; 3],
            max: [1.0; 3],
        },
        background: None,
        points: Some(points()),
        classes: None,
        source: SceneSource::Synthetic {
            seed: 0,
            size: "ci".into(),
            pca: None,
        },
        world: Some(WorldFrame {
            name: "colmap".into(),
            to_scene: applied(),
            fitted_to: String::new(),
        }),
    }
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn a_capture_round_trips_through_writer_and_loader() {
    let tmp = tempfile::tempdir().expect("tmp");
    let s = scene();
    write_nerfstudio(&s, tmp.path(), ImageFormat::Png).expect("write");
    let loaded = load_blender(tmp.path(), &BlenderOptions::default()).expect("load");
    assert_eq!(loaded.frames.len(), 2);
    for (a, b) in s.frames.iter().zip(&loaded.frames) {
        assert_eq!(a.name, b.name);
        let (ka, kb) = (a.camera.intrinsics, b.camera.intrinsics);
        assert_eq!((ka.width, ka.height), (kb.width, kb.height));
        assert!(
            close(
                &[ka.fx, ka.fy, ka.cx, ka.cy],
                &[kb.fx, kb.fy, kb.cx, kb.cy],
                1e-12
            ),
            "{ka:?} vs {kb:?}"
        );
        assert_eq!(ka.distortion, kb.distortion);
        let (ma, mb) = (a.camera.pose.to_matrix(), b.camera.pose.to_matrix());
        assert!(close(ma.as_flattened(), mb.as_flattened(), 1e-12));
        for (x, y) in a.rgb.to_f32().iter().zip(b.rgb.to_f32().iter()) {
            assert!((x - y).abs() <= 0.5 / 255.0 + 1e-6, "colour {x} vs {y}");
        }
        let (da, db) = (a.depth.as_ref().expect("d"), b.depth.as_ref().expect("d"));
        assert_eq!((da.width, da.height), (db.width, db.height));
        for (x, y) in da.to_f32().iter().zip(db.to_f32().iter()) {
            assert!((x - y).abs() <= 0.5e-3 + 1e-6, "depth {x} vs {y}");
            assert_eq!(*x == 0.0, *y == 0.0);
        }
        assert_eq!(a.mask, b.mask);
        assert_eq!(b.depth_weight, 1.0);
    }
    // The recorded world frame maps a known COLMAP point to the poses'
    // frame, and its inverse maps it back.
    let world = loaded.world.as_ref().expect("world");
    assert_eq!(world.name, "colmap");
    let p = [1.0, 2.0, 3.0];
    let in_scene = applied().apply_point(p);
    assert!(close(&in_scene, &[1.1, 0.3, -1.2], 1e-12), "{in_scene:?}");
    let back = world.to_scene.inverse().apply_point(in_scene);
    assert!(close(&back, &p, 1e-12), "{back:?}");
    // The point cloud, and the box: the lattice's, the strays left out.
    let pts = loaded.points.as_ref().expect("points");
    assert_eq!(pts.positions.len(), 218);
    assert!(close(
        pts.positions.as_flattened(),
        points().positions.as_flattened(),
        1e-6
    ));
    let want = robust_points_box(&pts.positions, 0.0).expect("box");
    assert!(close(&want.min, &[-0.502; 3], 1e-6), "{want:?}");
    assert!(close(&want.max, &[0.502; 3], 1e-6), "{want:?}");
    // The scene box holds the points' robust box and what the cameras see
    // at the points' depth.
    let cameras: Vec<_> = loaded.frames.iter().map(|f| f.camera).collect();
    let b = &loaded.scene_box;
    assert_eq!(
        *b,
        datasets::blender::seen_points_box(&pts.positions, &cameras, 0.05).expect("box")
    );
    let corners = datasets::colmap::frame::seen_corners(&cameras, &pts.positions);
    assert!(!corners.is_empty());
    let (clo, chi) = datasets::colmap::frame::robust_box(&corners).expect("corners");
    for p in [want.min, want.max, clo, chi].iter() {
        assert!(
            (0..3).all(|k| p[k] >= b.min[k] - 1e-9 && p[k] <= b.max[k] + 1e-9),
            "{p:?}"
        );
    }
    // read_cameras sees the same cameras.
    let cams = read_cameras(&tmp.path().join("transforms.json")).expect("cameras");
    assert_eq!(cams[1].0, "view1");
    assert_eq!(
        cams[1].1.intrinsics.distortion,
        s.frames[1].camera.intrinsics.distortion
    );
}

/// A one-frame capture: an 8x6 image, depth and mask at half size, a
/// second frame with `.npy` depth, as a json Value to edit.
fn small_capture(dir: &Path) -> Value {
    let rgb = image::RgbImage::from_fn(8, 6, |x, y| image::Rgb([x as u8 * 30, y as u8 * 40, 7]));
    rgb.save(dir.join("a.png")).expect("png");
    rgb.save(dir.join("b.png")).expect("png");
    let depth = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(4, 3, |x, y| {
        image::Luma([1000 + 250 * x as u16 + 2000 * y as u16])
    });
    depth.save(dir.join("a_depth.png")).expect("depth");
    let mask = image::GrayImage::from_fn(4, 3, |x, _| image::Luma([if x < 2 { 0 } else { 9 }]));
    mask.save(dir.join("a_mask.png")).expect("mask");
    let npy: Vec<f32> = (0..48).map(|i| 0.5 + i as f32 / 100.0).collect();
    datasets::npy::write_npy_f32(&dir.join("b_depth.npy"), &[6, 8], &npy).expect("npy");
    // Two cameras looking at the origin.
    let pose = |x: f64| {
        let p = look_at([x, -4.0, 1.0], [0.0; 3], [0.0, 0.0, 1.0]).expect("pose");
        json!(p.to_opengl())
    };
    json!({
        "camera_model": "OPENCV",
        "fl_x": 10.0, "fl_y": 10.0, "cx": 4.0, "cy": 3.0, "w": 8, "h": 6,
        "k1": 0.01,
        "depth_unit_scale_factor": 0.002,
        "frames": [
            {"file_path": "a.png", "transform_matrix": pose(0.0),
             "depth_file_path": "a_depth.png", "mask_path": "a_mask.png", "k1": -0.02},
            {"file_path": "b.png", "transform_matrix": pose(2.0),
             "depth_file_path": "b_depth.npy"},
        ],
    })
}

fn write_json(dir: &Path, v: &Value) {
    std::fs::write(dir.join("transforms.json"), v.to_string()).expect("json");
}

#[test]
fn depth_and_masks_of_another_resolution_are_resampled_nearest() {
    let tmp = tempfile::tempdir().expect("tmp");
    let t = small_capture(tmp.path());
    write_json(tmp.path(), &t);
    let s = load_blender(tmp.path(), &BlenderOptions::default()).expect("load");
    let a = &s.frames[0];
    let d = a.depth.as_ref().expect("depth");
    assert_eq!((d.width, d.height), (8, 6));
    // Pixel (x, y) reads depth pixel (x / 2, y / 2), times 0.002 m.
    for y in 0..6u32 {
        for x in 0..8u32 {
            let raw = 1000.0 + 250.0 * (x / 2) as f32 + 2000.0 * (y / 2) as f32;
            assert!((d.get(x, y) - raw * 0.002).abs() < 1e-5);
            assert_eq!(a.is_target_pixel(x, y), x >= 4, "({x}, {y})");
        }
    }
    // The frame's k1 overrides the top-level one; k2.. default to 0.
    assert_eq!(a.camera.intrinsics.distortion.k1, -0.02);
    assert_eq!(s.frames[1].camera.intrinsics.distortion.k1, 0.01);
    assert_eq!(a.camera.intrinsics.distortion.k2, 0.0);
    let b = s.frames[1].depth.as_ref().expect("npy depth");
    assert!((b.get(3, 2) - (0.5 + 19.0 / 100.0) * 0.002).abs() < 1e-7);
    assert!(s.frames[1].mask.is_none());
    assert!(s.world.is_none() && s.points.is_none());
}

/// Loads after `edit` and returns the error message.
fn refused(edit: impl FnOnce(&Path, &mut Value)) -> String {
    let tmp = tempfile::tempdir().expect("tmp");
    let mut t = small_capture(tmp.path());
    edit(tmp.path(), &mut t);
    write_json(tmp.path(), &t);
    let Err(err) = load_blender(tmp.path(), &BlenderOptions::default()) else {
        panic!("loaded a bad capture");
    };
    let msg = err.to_string();
    eprintln!("refused: {msg}");
    msg
}

#[test]
fn bad_captures_are_refused_naming_the_file() {
    let msg = refused(|_, t| t["camera_model"] = json!("OPENCV_FISHEYE"));
    assert!(
        msg.contains("transforms.json") && msg.contains("\"OPENCV_FISHEYE\""),
        "{msg}"
    );
    let msg = refused(|_, t| t["frames"][1]["camera_model"] = json!("EQUIRECTANGULAR"));
    assert!(
        msg.contains("frames[1]") && msg.contains("EQUIRECTANGULAR"),
        "{msg}"
    );
    let msg = refused(|dir, _| {
        let d = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(4, 4);
        d.save(dir.join("a_depth.png")).expect("depth");
    });
    assert!(
        msg.contains("a_depth.png") && msg.contains("aspect"),
        "{msg}"
    );
    let msg = refused(|dir, _| {
        image::GrayImage::new(8, 3)
            .save(dir.join("a_mask.png"))
            .expect("mask");
    });
    assert!(
        msg.contains("a_mask.png") && msg.contains("aspect"),
        "{msg}"
    );
    let msg = refused(|_, t| t["frames"][0]["depth_file_path"] = json!("gone.png"));
    assert!(
        msg.contains("gone.png") && msg.contains("missing depth"),
        "{msg}"
    );
    let msg = refused(|_, t| t["frames"][0]["mask_path"] = json!("gone.png"));
    assert!(
        msg.contains("gone.png") && msg.contains("missing mask"),
        "{msg}"
    );
    let msg = refused(|_, t| {
        t["applied_transform"] = json!([
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 2.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0]
        ])
    });
    assert!(
        msg.contains("transforms.json") && msg.contains("not a similarity"),
        "{msg}"
    );
    let msg = refused(|_, t| {
        t["applied_transform"] = json!([
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0]
        ])
    });
    assert!(
        msg.contains("applied_transform") && msg.contains("reflection"),
        "{msg}"
    );
    let msg = refused(|_, t| t["ply_file_path"] = json!("sparse.ply"));
    assert!(
        msg.contains("sparse.ply") && msg.contains("missing point cloud"),
        "{msg}"
    );
    let msg = refused(|_, t| t["depth_unit_scale_factor"] = json!(-1.0));
    assert!(msg.contains("depth_unit_scale_factor"), "{msg}");
}
