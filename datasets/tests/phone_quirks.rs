//! The phone loaders (and COLMAP's) on what real app exports hold, written
//! by the tests: a 3D Scanner App export with a pose for every ARKit frame
//! but images for its keyframes only, its mesh texture named as the app
//! names it, exports without a mesh and without depth; a Record3D export
//! of portrait frames with half-float `R` depth; a COLMAP model with a
//! camera per image.

use std::path::Path;

use datasets::colmap::ColmapOptions;
use datasets::detect::{Format, detect};
use datasets::phone::{assemble, record3d, scanner};
use datasets::{Frame, LoaderOptions, PhoneOptions, Scene, SceneSource, WorldFrame, load_disk};
use half::f16;
use model::geometry::{Pose, Vec3, look_at};

/// Colour size of the 3D Scanner App fixtures, and their intrinsics.
const W: u32 = 64;
const H: u32 = 48;
const F: f64 = 50.0;
/// Their depth maps' size (the colour's aspect ratio, as 256x192 is a
/// 1920x1440 image's).
const DW: u32 = 32;
const DH: u32 = 24;

fn write_jpg(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) {
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb(f(x, y)))
        .save(path)
        .expect("jpg");
}

fn write_png16(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> u16) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| image::Luma([f(x, y)]))
        .save(path)
        .expect("png16");
}

fn write_png8(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> u8) {
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([f(x, y)]))
        .save(path)
        .expect("png8");
}

/// A camera-to-world in ARKit's conventions: turned by `yaw` about the
/// vertical (y), at `t`, looking down its -z.
fn arkit_pose(yaw: f64, t: Vec3) -> [[f64; 4]; 4] {
    let (s, c) = yaw.sin_cos();
    [
        [c, 0.0, s, t[0]],
        [0.0, 1.0, 0.0, t[1]],
        [-s, 0.0, c, t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// `frame_NNNNN.json` as the app writes it: the pose and intrinsics read,
/// and the keys that are not.
fn write_frame_json(dir: &Path, i: usize, pose: [[f64; 4]; 4]) {
    let json = serde_json::json!({
        "cameraPoseARFrame": pose.iter().flatten().collect::<Vec<_>>(),
        "intrinsics": [F, 0.0, 31.5, 0.0, F, 23.5, 0.0, 0.0, 1.0],
        "projectionMatrix": [1.56, 0.0, 0.0, 0.0, 0.0, 2.08, 0.0, 0.0,
                             0.0, 0.0, -1.0, -0.001, 0.0, 0.0, -1.0, 0.0],
        "motionQuality": 0.93,
        "averageAngularVelocity": 0.12,
        "averageVelocity": 0.08,
        "exposureDuration": 0.016,
        "time": 1234.5 + i as f64 / 60.0,
        "frame_index": i,
    });
    std::fs::write(dir.join(format!("frame_{i:05}.json")), json.to_string()).expect("json");
}

/// A keyframe's image (a solid colour), depth (`mm` everywhere but pixel
/// (0, 0), which has none) and confidence (high everywhere), the maps only
/// when `depth`.
fn write_keyframe(dir: &Path, i: usize, colour: [u8; 3], depth: Option<u16>) {
    write_jpg(&dir.join(format!("frame_{i:05}.jpg")), W, H, |_, _| colour);
    if let Some(mm) = depth {
        write_png16(&dir.join(format!("depth_{i:05}.png")), DW, DH, |x, y| {
            if (x, y) == (0, 0) { 0 } else { mm }
        });
        write_png8(&dir.join(format!("conf_{i:05}.png")), DW, DH, |_, _| 2);
    }
}

/// The scene's frame `frame`'s pose, taken back to the capture's frame,
/// is the ARKit camera-to-world `arkit`.
fn assert_arkit_pose(frame: &Frame, world: &WorldFrame, arkit: [[f64; 4]; 4]) {
    let back = world.to_scene.inverse().apply_pose(&frame.camera.pose);
    let want = Pose::from_opengl(arkit).expect("rigid");
    for r in 0..3 {
        for c in 0..3 {
            assert!(
                (back.rotation[r][c] - want.rotation[r][c]).abs() < 1e-9,
                "{}: rotation {:?}, expected {:?}",
                frame.name,
                back.rotation,
                want.rotation
            );
        }
        assert!(
            (back.translation[r] - want.translation[r]).abs() < 1e-9,
            "{}: centre {:?}, expected {:?}",
            frame.name,
            back.translation,
            want.translation
        );
    }
}

/// Reads and assembles a phone export as `load_disk` does, with the
/// notes it prints.
fn assembled(dir: &Path, loader: &LoaderOptions) -> (Scene, Vec<String>) {
    let (capture, options) = match loader {
        LoaderOptions::ScannerApp(o) => (scanner::read_capture(dir).expect("reads"), o),
        LoaderOptions::Record3d(o) => (record3d::read_capture(dir).expect("reads"), o),
        other => panic!("not a phone loader: {other:?}"),
    };
    let a = assemble(dir, options, capture, loader).expect("assembles");
    (a.scene, a.notes)
}

fn has_note(notes: &[String], words: &[&str]) -> bool {
    notes.iter().any(|n| words.iter().all(|w| n.contains(w)))
}

fn scanner_loader() -> LoaderOptions {
    LoaderOptions::ScannerApp(PhoneOptions::default())
}

/// Frames 0 to 11 of an ARKit session, with images for the keyframes 0,
/// 3, 7 and 11 only.
const KEYFRAMES: [usize; 4] = [0, 3, 7, 11];

fn keyframe_pose(i: usize) -> [[f64; 4]; 4] {
    arkit_pose(0.15 * i as f64, [0.1 * i as f64, 1.4, -0.05 * i as f64])
}

/// An export with a pose for each of frames `first..12` and an image, a
/// depth and a confidence map for each of `keyframes`.
fn keyframe_export(dir: &Path, first: usize, keyframes: &[usize]) {
    std::fs::create_dir_all(dir).expect("mkdir");
    for i in first..12 {
        write_frame_json(dir, i, keyframe_pose(i));
    }
    for &i in keyframes {
        write_keyframe(dir, i, [20 * i as u8, 100, 200], Some(1500));
    }
    // The app's own summary file, not a frame.
    std::fs::write(dir.join("info.json"), r#"{"title": "scan"}"#).expect("info");
}

#[test]
fn scanner_app_keyframe_images_only_keep_the_frames_with_an_image() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("scan");
    keyframe_export(&dir, 0, &KEYFRAMES);
    assert_eq!(detect(&dir).expect("detected").format, Format::ScannerApp);
    let scene = load_disk(&dir, &scanner_loader()).expect("loads");
    let names: Vec<&str> = scene.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(
        names,
        ["frame_00000", "frame_00003", "frame_00007", "frame_00011"]
    );
    let world = scene.world.as_ref().expect("arkit frame");
    assert_eq!(world.name, "arkit");
    for (frame, &i) in scene.frames.iter().zip(&KEYFRAMES) {
        // Each keyframe has its own JSON's pose, not a neighbour's.
        assert_arkit_pose(frame, world, keyframe_pose(i));
        let k = frame.camera.intrinsics;
        assert_eq!((k.width, k.height, k.fx, k.cx), (W, H, F, 31.5));
        assert_eq!((frame.rgb.width, frame.rgb.height), (W, H));
        // The image is this keyframe's (its blue channel codes `i`).
        let c = frame.rgb.get(W / 2, H / 2);
        assert!(
            (c[0] * 255.0 - 20.0 * i as f32).abs() < 6.0,
            "{}: {c:?}",
            frame.name
        );
        let d = frame.depth.as_ref().expect("depth");
        assert!((d.get(W / 2, H / 2) - 1.5).abs() < 1e-6);
    }
    let (_, notes) = assembled(&dir, &scanner_loader());
    assert!(
        has_note(&notes, &["8 poses without an image skipped"]),
        "{notes:?}"
    );
}

/// A real export's numbering need not start with a keyframe: the first
/// pose (in name order) may have no image, and the export is still told
/// by its poses with images.
#[test]
fn scanner_app_export_whose_first_pose_has_no_image_is_detected() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("scan");
    keyframe_export(&dir, 0, &[2, 5, 9]);
    // The loader itself reads it (`--dataset scanner-app`).
    let scene = load_disk(&dir, &scanner_loader()).expect("loads");
    assert_eq!(scene.frames.len(), 3);
    assert_eq!(scene.frames[0].name, "frame_00002");
    let found = detect(&dir).map(|d| d.format).map_err(|e| e.to_string());
    assert_eq!(found, Ok(Format::ScannerApp));
}

/// Two keyframes (solid `colours`) of cameras at x = -0.2 and 0.2 m,
/// 0 m high, looking down ARKit's -z (towards a wall at z = -3 m).
const CAMERA_X: [f64; 2] = [-0.2, 0.2];
const COLOURS: [[u8; 3]; 2] = [[200, 40, 40], [40, 40, 200]];

fn two_keyframes(dir: &Path, depth: Option<u16>) {
    std::fs::create_dir_all(dir).expect("mkdir");
    for (i, x) in CAMERA_X.into_iter().enumerate() {
        write_frame_json(dir, i, arkit_pose(0.0, [x, 0.0, 0.0]));
        write_keyframe(dir, i, COLOURS[i], depth);
    }
}

/// The wall's corners (ARKit, metres) and the colour of the texture
/// under each.
const WALL: [(Vec3, [u8; 3]); 4] = [
    ([-2.0, -1.5, -3.0], [0, 0, 255]),
    ([2.0, -1.5, -3.0], [255, 255, 255]),
    ([2.0, 1.5, -3.0], [0, 255, 0]),
    ([-2.0, 1.5, -3.0], [255, 0, 0]),
];

/// The mesh as the app writes it: `textured_output.obj` naming
/// `textured_output.mtl`, whose `map_Kd` is `textured_output.jpg`; faces
/// `v/vt/vn`, the texture coordinates in another order than the vertices.
fn write_textured_mesh(dir: &Path) {
    let obj = "# Generated by 3D Scanner App\n\
               mtllib textured_output.mtl\n\
               o textured_output\n\
               v -2 -1.5 -3\nv 2 -1.5 -3\nv 2 1.5 -3\nv -2 1.5 -3\n\
               vt 0.75 0.75\nvt 0.25 0.25\nvt 0.25 0.75\nvt 0.75 0.25\n\
               vn 0 0 1\n\
               usemtl material0\n\
               f 1/2/1 2/4/1 3/1/1\n\
               f 1/2/1 3/1/1 4/3/1\n";
    std::fs::write(dir.join("textured_output.obj"), obj).expect("obj");
    let mtl = "newmtl material0\nKa 1.000000 1.000000 1.000000\nKd 1.000000 1.000000 1.000000\n\
               Ks 0.000000 0.000000 0.000000\nTr 1.000000\nillum 1\nNs 0.000000\n\
               map_Kd textured_output.jpg\n";
    std::fs::write(dir.join("textured_output.mtl"), mtl).expect("mtl");
    // Quadrants: red top left, green top right, blue bottom left, white
    // bottom right (v = 1 is the top row).
    write_jpg(&dir.join("textured_output.jpg"), 64, 64, |x, y| {
        match (x < 32, y < 32) {
            (true, true) => [255, 0, 0],
            (false, true) => [0, 255, 0],
            (true, false) => [0, 0, 255],
            (false, false) => [255, 255, 255],
        }
    });
}

#[test]
fn scanner_app_mesh_texture_named_textured_output_jpg_colours_the_points() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("scan");
    two_keyframes(&dir, None);
    write_textured_mesh(&dir);
    let (scene, notes) = assembled(&dir, &scanner_loader());
    let world = scene.world.as_ref().expect("arkit frame");
    let back = world.to_scene.inverse();
    let cloud = scene.points.as_ref().expect("the mesh is the point cloud");
    assert_eq!(cloud.positions.len(), 4, "one point per vertex");
    let colours = cloud.colors.as_ref().expect("colours from the texture");
    for (p, c) in cloud.positions.iter().zip(colours) {
        let q = back.apply_point(*p);
        let (_, want) = WALL
            .iter()
            .find(|(v, _)| (0..3).all(|k| (v[k] - q[k]).abs() < 1e-9))
            .unwrap_or_else(|| panic!("point {q:?} is no vertex of the mesh"));
        assert!(
            (0..3).all(|k| (i32::from(c[k]) - i32::from(want[k])).abs() <= 12),
            "vertex {q:?}: colour {c:?}, the texture has {want:?} there"
        );
    }
    // Without depth maps, depth is ray-cast from the mesh: the wall is 3 m
    // in front of both cameras.
    assert!(has_note(&notes, &["ray-cast from the mesh"]), "{notes:?}");
    for f in &scene.frames {
        let d = f.depth.as_ref().expect("ray-cast depth");
        assert!((d.get(W / 2, H / 2) - 3.0).abs() < 1e-4, "{}", f.name);
        assert!(
            d.to_f32()
                .iter()
                .all(|&z| z == 0.0 || (z - 3.0).abs() < 1e-4)
        );
    }
    // The same through `load_disk`.
    let disk = load_disk(&dir, &scanner_loader()).expect("loads");
    assert_eq!(disk.points.as_ref().map(|p| p.positions.len()), Some(4));

    // Without the texture the cloud has no colour, and a note names it.
    std::fs::remove_file(dir.join("textured_output.jpg")).expect("rm");
    let (scene, notes) = assembled(&dir, &scanner_loader());
    let cloud = scene.points.as_ref().expect("points");
    assert_eq!(cloud.positions.len(), 4);
    assert!(cloud.colors.is_none());
    assert!(
        has_note(&notes, &["textured_output.jpg", "not found"]),
        "{notes:?}"
    );
}

#[test]
fn scanner_app_without_a_mesh_takes_its_points_from_the_depth_maps() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("scan");
    two_keyframes(&dir, Some(2000));
    let (scene, notes) = assembled(&dir, &scanner_loader());
    assert!(
        has_note(
            &notes,
            &[
                "no textured_output.obj",
                "point cloud is made from the depth maps"
            ]
        ),
        "{notes:?}"
    );
    assert_eq!(scene.frames.len(), 2);
    for f in &scene.frames {
        let d = f.depth.as_ref().expect("depth");
        // Depth pixel (0, 0) has none: colour pixels 0..2 of rows 0..2.
        assert_eq!(d.get(0, 0), 0.0);
        assert_eq!(d.get(1, 1), 0.0);
        assert!((d.get(2, 2) - 2.0).abs() < 1e-6);
        assert!((d.get(W - 1, H - 1) - 2.0).abs() < 1e-6);
    }
    // Every 8th pixel of each 64x48 frame in each axis (8 x 6), but (0, 0).
    let cloud = scene.points.as_ref().expect("points from the depth maps");
    assert_eq!(cloud.positions.len(), 2 * 47);
    let colours = cloud.colors.as_ref().expect("coloured by the images");
    let back = scene.world.as_ref().expect("arkit").to_scene.inverse();
    for (n, (p, c)) in cloud.positions.iter().zip(colours).enumerate() {
        // 2 m in front of the cameras (ARKit z = -2), in their view.
        let q = back.apply_point(*p);
        assert!((q[2] + 2.0).abs() < 1e-5, "point {n}: {q:?}");
        assert!(q[0].abs() < 0.2 + 2.0 * 32.0 / F + 1e-6, "point {n}: {q:?}");
        let want = COLOURS[n / 47];
        assert!(
            (0..3).all(|k| (i32::from(c[k]) - i32::from(want[k])).abs() <= 8),
            "point {n}: colour {c:?}, its image is {want:?}"
        );
    }
    let disk = load_disk(&dir, &scanner_loader()).expect("loads");
    assert_eq!(disk.points.map(|p| p.positions.len()), Some(2 * 47));
}

#[test]
fn scanner_app_without_mesh_or_depth_trains_on_colour_alone() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("scan");
    two_keyframes(&dir, None);
    assert_eq!(detect(&dir).expect("detected").format, Format::ScannerApp);
    let (scene, notes) = assembled(&dir, &scanner_loader());
    for words in [
        &["no depth maps in the export"][..],
        &["no textured_output.obj"],
        &["no depth maps and no mesh", "colour alone"],
    ] {
        assert!(has_note(&notes, words), "{words:?} not in {notes:?}");
    }
    assert_eq!(scene.frames.len(), 2);
    assert!(scene.frames.iter().all(|f| f.depth.is_none()));
    assert!(scene.points.is_none());
    let world = scene.world.as_ref().expect("arkit frame");
    for ((f, x), want) in scene.frames.iter().zip(CAMERA_X).zip(COLOURS) {
        assert_arkit_pose(f, world, arkit_pose(0.0, [x, 0.0, 0.0]));
        assert!(scene.scene_box.contains(f.camera.pose.center()));
        let c = f.rgb.get(5, 5);
        assert!(
            (0..3).all(|k| (c[k] * 255.0 - f32::from(want[k])).abs() <= 8.0),
            "{}: {c:?}, its image is {want:?}",
            f.name
        );
    }
    // The box holds the cameras only: nothing else bounds the scene.
    let b = &scene.scene_box;
    let sides: Vec<f64> = (0..3).map(|k| b.max[k] - b.min[k]).collect();
    assert!(
        sides.iter().all(|&s| s < 0.5),
        "box {sides:?} is more than the cameras' 0.4 m"
    );
    let disk = load_disk(&dir, &scanner_loader()).expect("loads");
    assert_eq!(disk.frames.len(), 2);
}

/// A portrait Record3D frame: colour 192x256, depth 48x64.
const PW: u32 = 192;
const PH: u32 = 256;
const PDW: u32 = 48;
const PDH: u32 = 64;

/// Depth (metres) of depth pixel (x, y) of frame `i`: a slope from 0.8 m,
/// values f16 cannot hold exactly.
fn portrait_depth(i: usize, x: u32, y: u32) -> f32 {
    0.8 + 0.013 * x as f32 + 0.021 * y as f32 + 0.1 * i as f32
}

/// Writes a single half-float channel `R` EXR, as Record3D does.
fn write_half_r_exr(path: &Path, w: u32, h: u32, values: Vec<f32>) {
    use exr::prelude::*;
    let channel = AnyChannel::new(
        "R",
        FlatSamples::F16(values.into_iter().map(f16::from_f32).collect()),
    );
    let layer = Layer::new(
        (w as usize, h as usize),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    Image::from_layer(layer).write().to_file(path).expect("exr");
}

/// Record3D's pose of frame `i`: `[qx, qy, qz, qw, tx, ty, tz]`, a turn
/// about the vertical.
fn record3d_pose(i: usize) -> [f64; 7] {
    let half = 0.1 * i as f64;
    [0.0, half.sin(), 0.0, half.cos(), 0.3 * i as f64, 1.2, -0.1]
}

#[test]
fn record3d_portrait_frames_with_half_float_r_depth_load_in_metres() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("exr");
    for sub in ["rgb", "depth", "conf"] {
        std::fs::create_dir_all(dir.join(sub)).expect("mkdir");
    }
    let frames = 3;
    let meta = serde_json::json!({
        "w": PW, "h": PH, "dw": PDW, "dh": PDH, "fps": 60, "cameraType": 1,
        "K": [200.0, 0.0, 0.0, 0.0, 201.0, 0.0, 96.0, 128.0, 1.0],
        "poses": (0..frames).map(record3d_pose).collect::<Vec<_>>(),
        "initPose": [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
    });
    std::fs::write(dir.join("metadata.json"), meta.to_string()).expect("meta");
    for i in 0..frames {
        write_jpg(&dir.join(format!("rgb/{i}.jpg")), PW, PH, |x, y| {
            [x as u8, (y / 2) as u8, 60 * i as u8]
        });
        let values = (0..PDH)
            .flat_map(|y| (0..PDW).map(move |x| portrait_depth(i, x, y)))
            .collect();
        write_half_r_exr(&dir.join(format!("depth/{i}.exr")), PDW, PDH, values);
        // Depth pixel (5, 7) is of medium confidence.
        write_png8(&dir.join(format!("conf/{i}.png")), PDW, PDH, |x, y| {
            if (x, y) == (5, 7) { 1 } else { 2 }
        });
    }
    assert_eq!(detect(&dir).expect("detected").format, Format::Record3d);

    // The maps as read: portrait, f16 values in metres.
    let capture = record3d::read_capture(&dir).expect("reads");
    assert_eq!(capture.frames.len(), frames);
    for (i, f) in capture.frames.iter().enumerate() {
        let d = f.depth.as_ref().expect("depth").load().expect("exr");
        assert_eq!((d.width, d.height), (PDW, PDH));
        for y in 0..PDH {
            for x in 0..PDW {
                let exact = portrait_depth(i, x, y);
                let got = d.get(x, y);
                assert_eq!(got, f16::from_f32(exact).to_f32(), "({x}, {y})");
                assert!((got - exact).abs() <= exact / 1024.0, "({x}, {y})");
            }
        }
    }

    let scene = load_disk(&dir, &LoaderOptions::Record3d(PhoneOptions::default())).expect("loads");
    assert_eq!(scene.frames.len(), frames);
    let world = scene.world.as_ref().expect("arkit frame");
    for (i, f) in scene.frames.iter().enumerate() {
        assert_eq!(f.name, format!("frame_{i:05}"));
        assert_eq!((f.rgb.width, f.rgb.height), (PW, PH), "portrait colour");
        let k = f.camera.intrinsics;
        assert_eq!(
            (k.width, k.height, k.fx, k.fy, k.cx, k.cy),
            (PW, PH, 200.0, 201.0, 96.0, 128.0)
        );
        // The camera centre is the pose's.
        let p = record3d_pose(i);
        let c = world.to_scene.inverse().apply_point(f.camera.pose.center());
        assert!((0..3).all(|k| (c[k] - p[4 + k]).abs() < 1e-9), "{c:?}");
        // Depth at the colour size: depth pixel (x, y) covers colour pixels
        // 4x..4x+4 and 4y..4y+4; the medium-confidence one is no target.
        let d = f.depth.as_ref().expect("depth");
        assert_eq!((d.width, d.height), (PW, PH));
        for (x, y) in [(0, 0), (47, 63), (10, 20), (30, 5), (6, 7)] {
            let want = f16::from_f32(portrait_depth(i, x, y)).to_f32();
            for (cx, cy) in [(4 * x, 4 * y), (4 * x + 3, 4 * y + 3)] {
                assert!((d.get(cx, cy) - want).abs() < 1e-6, "({cx}, {cy})");
            }
        }
        assert_eq!(d.get(4 * 5 + 1, 4 * 7 + 2), 0.0);
    }
}

/// The crate's own Record3D writer at a portrait size loads back at that
/// size, with the scene's depth (to f16) and its cameras' relative poses.
#[test]
fn record3d_writer_portrait_export_round_trips() {
    let source = datasets::load_scene(&SceneSource::Synthetic {
        seed: 0,
        size: "ci".into(),
        pca: None,
    })
    .expect("synthetic scene");
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("r3d");
    let export = datasets::writer::Record3dExport {
        frames: 4,
        size: (48, 64),
        depth_width: 24,
        ..Default::default()
    };
    datasets::writer::write_record3d(&source, &dir, &export).expect("writes");
    let options = PhoneOptions {
        max_depth: 1e3,
        ..PhoneOptions::default()
    };
    let scene = load_disk(&dir, &LoaderOptions::Record3d(options)).expect("loads");
    assert_eq!(scene.frames.len(), 4);
    let m = source.frames.len();
    for (j, f) in scene.frames.iter().enumerate() {
        let src = &source.frames[j * m / 4];
        assert_eq!((f.rgb.width, f.rgb.height), (48, 64));
        let d = f.depth.as_ref().expect("depth");
        assert_eq!((d.width, d.height), (48, 64));
        let sd = src.depth.as_ref().expect("source depth");
        // Depth map 24x32: pixel (x, y) is the source's nearest to its
        // centre, and covers colour pixels 2x, 2x + 1.
        for y in 0..32u32 {
            for x in 0..24u32 {
                let sx = (((x as f64 + 0.5) * sd.width as f64 / 24.0) as u32).min(sd.width - 1);
                let sy = (((y as f64 + 0.5) * sd.height as f64 / 32.0) as u32).min(sd.height - 1);
                let want = f16::from_f32(sd.get(sx, sy)).to_f32();
                let got = d.get(2 * x + 1, 2 * y + 1);
                assert!(
                    (got - want).abs() <= 1e-6 * want.max(1.0),
                    "frame {j} ({x}, {y}): {got} vs {want}"
                );
            }
        }
    }
    // Relative poses are kept: distances between camera centres and
    // angles between viewing directions.
    let dot = |a: Vec3, b: Vec3| (0..3).map(|k| a[k] * b[k]).sum::<f64>();
    let dist = |a: Vec3, b: Vec3| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
    for (a, b) in [(0, 1), (1, 3), (0, 2)] {
        let (la, lb) = (&scene.frames[a].camera.pose, &scene.frames[b].camera.pose);
        let (sa, sb) = (
            &source.frames[a * m / 4].camera.pose,
            &source.frames[b * m / 4].camera.pose,
        );
        assert!(
            (dist(la.center(), lb.center()) - dist(sa.center(), sb.center())).abs() < 1e-9,
            "frames {a} and {b}"
        );
        assert!(
            (dot(la.forward(), lb.forward()) - dot(sa.forward(), sb.forward())).abs() < 1e-9,
            "frames {a} and {b}"
        );
    }
}

/// Quaternion `(w, x, y, z)` of a rotation matrix whose trace is above
/// -1 (the cameras below turn less than 180 degrees).
fn colmap_quaternion(r: [[f64; 3]; 3]) -> [f64; 4] {
    let w = 0.5 * (1.0 + r[0][0] + r[1][1] + r[2][2]).sqrt();
    [
        w,
        (r[2][1] - r[1][2]) / (4.0 * w),
        (r[0][2] - r[2][0]) / (4.0 * w),
        (r[1][0] - r[0][1]) / (4.0 * w),
    ]
}

/// A COLMAP text model as `colmap feature_extractor` leaves it by default
/// (`--ImageReader.single_camera 0`): a SIMPLE_RADIAL camera per image,
/// each with its own focal length; camera ids in another order than image
/// ids and names.
#[test]
fn colmap_camera_per_image_keeps_each_focal_length() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path();
    let sparse = dir.join("sparse/0");
    std::fs::create_dir_all(&sparse).expect("mkdir");
    std::fs::create_dir_all(dir.join("images")).expect("mkdir");
    // (name, image id, camera id, f, k).
    let images = [
        ("IMG_0001.jpg", 3, 2, 30.0, 0.010),
        ("IMG_0002.jpg", 1, 4, 30.6, -0.020),
        ("IMG_0003.jpg", 4, 1, 31.3, 0.000),
        ("IMG_0004.jpg", 2, 3, 29.2, 0.031),
    ];
    let target: Vec3 = [0.0, 0.0, 0.0];
    let mut cameras = String::from("# Camera list with one line of data per camera:\n");
    cameras += &format!("# Number of cameras: {}\n", images.len());
    let mut by_camera: Vec<_> = images.iter().collect();
    by_camera.sort_by_key(|i| i.2);
    for (_, _, cam, f, k) in by_camera {
        cameras += &format!("{cam} SIMPLE_RADIAL 40 30 {f} 20 15 {k}\n");
    }
    let mut text = String::from("# Image list with two lines of data per image:\n");
    for (n, (name, id, cam, _, _)) in images.iter().enumerate() {
        let a = n as f64 * 0.7;
        let pose =
            look_at([4.0 * a.cos(), 4.0 * a.sin(), 1.5], target, [0.0, 0.0, 1.0]).expect("pose");
        let r = pose.rotation;
        let rt: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| r[j][i]));
        let t: Vec3 =
            std::array::from_fn(|i| -(0..3).map(|k| rt[i][k] * pose.translation[k]).sum::<f64>());
        let q = colmap_quaternion(rt);
        text += &format!(
            "{id} {} {} {} {} {} {} {} {cam} {name}\n12.5 8.5 -1\n",
            q[0], q[1], q[2], q[3], t[0], t[1], t[2]
        );
        write_jpg(&dir.join("images").join(name), 40, 30, |_, _| [90, 90, 90]);
    }
    let mut points = String::from("# 3D point list\n");
    for p in 0..12 {
        let v = p as f64;
        points += &format!(
            "{} {} {} {} 128 128 128 0.5\n",
            p + 1,
            (v * 0.37).sin(),
            (v * 0.61).cos(),
            0.1 * v - 0.5
        );
    }
    for (name, body) in [
        ("cameras.txt", cameras),
        ("images.txt", text),
        ("points3D.txt", points),
    ] {
        std::fs::write(sparse.join(name), body).expect("write");
    }
    assert_eq!(detect(dir).expect("detected").format, Format::Colmap);
    let scene = load_disk(dir, &LoaderOptions::Colmap(ColmapOptions::default())).expect("loads");
    let names: Vec<&str> = scene.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["IMG_0001", "IMG_0002", "IMG_0003", "IMG_0004"]);
    for (f, (name, _, cam, focal, k1)) in scene.frames.iter().zip(&images) {
        let k = f.camera.intrinsics;
        assert_eq!(
            (k.fx, k.fy, k.distortion.k1),
            (*focal, *focal, *k1),
            "{name} (camera {cam})"
        );
        // COLMAP's principal point is at pixel corners, ours at centres.
        assert_eq!((k.width, k.height, k.cx, k.cy), (40, 30, 19.5, 14.5));
    }
}
