//! The COLMAP loader on a real reconstruction (skipped with a message when
//! the shared data is absent): binary and text models agree, the distorted
//! model's cameras, the scene frame, and a truncated `images.bin`. Run with
//! `--nocapture` to see the figures.

use std::path::{Path, PathBuf};

use datasets::colmap::{CameraModel, ColmapOptions, load_colmap, read_model};

/// The statue capture (see [`datasets::shared_dataset`]).
fn statue() -> Option<PathBuf> {
    datasets::shared_dataset("colmap_statue")
}

/// A little-endian reader over a file's bytes (the test's own, not the
/// loader's).
struct Bytes {
    data: Vec<u8>,
    pos: usize,
}

impl Bytes {
    fn open(path: &Path) -> Self {
        Self {
            data: std::fs::read(path).expect("read"),
            pos: 0,
        }
    }

    fn take<const N: usize>(&mut self) -> [u8; N] {
        let out = self.data[self.pos..self.pos + N].try_into().expect("slice");
        self.pos += N;
        out
    }

    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }

    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }

    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }

    fn name(&mut self) -> String {
        let end = self.pos
            + self.data[self.pos..]
                .iter()
                .position(|&b| b == 0)
                .expect("NUL");
        let s = String::from_utf8(self.data[self.pos..end].to_vec()).expect("utf8");
        self.pos = end + 1;
        s
    }
}

/// Converts the binary model in `sparse` to COLMAP's text format in `out`.
fn binary_to_text(sparse: &Path, out: &Path) {
    const MODELS: [(&str, usize); 5] = [
        ("SIMPLE_PINHOLE", 3),
        ("PINHOLE", 4),
        ("SIMPLE_RADIAL", 4),
        ("RADIAL", 5),
        ("OPENCV", 8),
    ];
    let mut b = Bytes::open(&sparse.join("cameras.bin"));
    let mut text = String::from("# Camera list\n");
    for _ in 0..b.u64() {
        let id = b.u32();
        let (name, n) = MODELS[b.u32() as usize];
        let (w, h) = (b.u64(), b.u64());
        let params: Vec<String> = (0..n).map(|_| b.f64().to_string()).collect();
        text += &format!("{id} {name} {w} {h} {}\n", params.join(" "));
    }
    std::fs::write(out.join("cameras.txt"), text).expect("write");

    let mut b = Bytes::open(&sparse.join("images.bin"));
    let mut text = String::from("# Image list with two lines of data per image\n");
    for _ in 0..b.u64() {
        let id = b.u32();
        let pose: Vec<String> = (0..7).map(|_| b.f64().to_string()).collect();
        let cam = b.u32();
        let name = b.name();
        let pts: Vec<String> = (0..b.u64())
            .map(|_| {
                let (x, y, p) = (b.f64(), b.f64(), b.u64());
                let p = if p == u64::MAX { -1 } else { p as i64 };
                format!("{x} {y} {p}")
            })
            .collect();
        text += &format!("{id} {} {cam} {name}\n{}\n", pose.join(" "), pts.join(" "));
    }
    std::fs::write(out.join("images.txt"), text).expect("write");

    let mut b = Bytes::open(&sparse.join("points3D.bin"));
    let mut text = String::from("# 3D point list\n");
    for _ in 0..b.u64() {
        let id = b.u64();
        let xyz = [b.f64(), b.f64(), b.f64()];
        let rgb: [u8; 3] = b.take();
        let err = b.f64();
        let track: Vec<String> = (0..b.u64())
            .map(|_| format!("{} {}", b.u32(), b.u32()))
            .collect();
        text += &format!(
            "{id} {} {} {} {} {} {} {err} {}\n",
            xyz[0],
            xyz[1],
            xyz[2],
            rgb[0],
            rgb[1],
            rgb[2],
            track.join(" ")
        );
    }
    std::fs::write(out.join("points3D.txt"), text).expect("write");
}

/// A copy of the statue's images next to `sparse` written by `model`.
fn statue_copy(dir: &Path, model: impl Fn(&Path)) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().expect("tmp");
    let sparse = tmp.path().join("sparse");
    std::fs::create_dir_all(&sparse).expect("mkdir");
    model(&sparse);
    let images = tmp.path().join("images");
    std::fs::create_dir(&images).expect("mkdir");
    for e in std::fs::read_dir(dir.join("images")).expect("ls").flatten() {
        std::fs::copy(e.path(), images.join(e.file_name())).expect("copy");
    }
    tmp
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn binary_and_text_models_give_the_same_scene() {
    let Some(dir) = statue() else {
        return;
    };
    let tmp = statue_copy(&dir, |sparse| binary_to_text(&dir.join("sparse"), sparse));
    let bin = load_colmap(&dir, &ColmapOptions::default()).expect("binary loads");
    let txt = load_colmap(tmp.path(), &ColmapOptions::default()).expect("text loads");
    assert_eq!(bin.frames.len(), 23);
    assert_eq!(bin.frames.len(), txt.frames.len());
    for (a, b) in bin.frames.iter().zip(&txt.frames) {
        assert_eq!(a.name, b.name);
        let (ka, kb) = (&a.camera.intrinsics, &b.camera.intrinsics);
        assert_eq!((ka.width, ka.height), (kb.width, kb.height));
        let flat = |k: &model::geometry::Intrinsics| [k.fx, k.fy, k.cx, k.cy];
        assert!(max_diff(&flat(ka), &flat(kb)) < 1e-9);
        let m = |f: &datasets::Frame| f.camera.pose.to_matrix().concat();
        assert!(max_diff(&m(a), &m(b)) < 1e-9, "{}", a.name);
        assert_eq!(a.rgb, b.rgb);
    }
    let (pa, pb) = (bin.points.expect("points"), txt.points.expect("points"));
    assert_eq!(pa.positions.len(), pb.positions.len());
    assert!(
        pa.positions
            .iter()
            .zip(&pb.positions)
            .all(|(x, y)| max_diff(x, y) < 1e-9)
    );
    assert_eq!(pa.colors, pb.colors);
    let (wa, wb) = (bin.world.expect("world"), txt.world.expect("world"));
    assert!(
        max_diff(
            &wa.to_scene.to_matrix().concat(),
            &wb.to_scene.to_matrix().concat()
        ) < 1e-9
    );
    assert!(max_diff(&bin.scene_box.min, &txt.scene_box.min) < 1e-9);
    // The models themselves agree record by record.
    let (ma, mb) = (
        read_model(&dir.join("sparse")).expect("binary"),
        read_model(&tmp.path().join("sparse")).expect("text"),
    );
    assert_eq!(ma.cameras, mb.cameras);
    assert_eq!(ma.images, mb.images);
    assert_eq!(ma.points, mb.points);
}

#[test]
fn distorted_model_cameras_are_simple_radial() {
    let Some(dir) = statue() else {
        return;
    };
    let model = read_model(&dir.join("distorted").join("sparse")).expect("reads");
    assert_eq!(model.cameras.len(), 23);
    assert_eq!(model.images.len(), 23);
    for cam in model.cameras.values() {
        assert_eq!(cam.model, CameraModel::SimpleRadial);
        assert_eq!((cam.width, cam.height), (3031, 2006));
        let p = &cam.params;
        assert!(p[3] != 0.0, "k1 {}", p[3]);
        let k = cam.intrinsics().expect("supported");
        assert_eq!((k.fx, k.fy), (p[0], p[0]));
        assert_eq!((k.cx, k.cy), (p[1] - 0.5, p[2] - 0.5));
        assert_eq!(k.distortion.k1, p[3]);
        assert_eq!(
            (k.distortion.k2, k.distortion.p1, k.distortion.p2),
            (0.0, 0.0, 0.0)
        );
    }
    let first = model.cameras.values().next().expect("camera");
    println!("statue distorted: camera 1 params {:?}", first.params);
}

/// The `q`-quantile of `values` (the test's own, interpolating linearly
/// between ranks, as the loader documents).
fn quantile(values: &mut [f64], q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    let x = q * (values.len() - 1) as f64;
    let i = x.floor() as usize;
    let j = (i + 1).min(values.len() - 1);
    values[i] + (x - i as f64) * (values[j] - values[i])
}

#[test]
fn statue_scene_frame_is_up_z_and_holds_what_the_cameras_see() {
    let Some(dir) = statue() else {
        return;
    };
    let s = load_colmap(&dir, &ColmapOptions::default()).expect("loads");
    let world = s.world.as_ref().expect("world").to_scene;
    let mut up = [0.0; 3];
    for f in &s.frames {
        for (i, u) in up.iter_mut().enumerate() {
            *u -= f.camera.pose.rotation[i][1];
        }
    }
    let n = model::geometry::norm(up);
    let angle = (up[2] / n).acos().to_degrees();
    let pts = &s.points.as_ref().expect("points").positions;
    let mut sides = [0.0; 3];
    for (k, side) in sides.iter_mut().enumerate() {
        let mut v: Vec<f64> = pts.iter().map(|p| p[k]).collect();
        *side = quantile(&mut v, 0.98) - quantile(&mut v, 0.02);
    }
    let inside = pts.iter().filter(|p| s.scene_box.contains(**p)).count();
    let b = &s.scene_box;
    println!(
        "statue: scale {:.6}, mean camera up {:.3} deg from +z, robust box sides {sides:.4?}, \
         scene box [{:.3?} .. {:.3?}], {inside} of {} points inside, camera centres {:?}",
        world.scale,
        angle,
        b.min,
        b.max,
        pts.len(),
        s.frames
            .iter()
            .take(3)
            .map(|f| f
                .camera
                .pose
                .center()
                .map(|v| (v * 1000.0).round() / 1000.0))
            .collect::<Vec<_>>()
    );
    assert!(angle < 1.0, "mean up is {angle} degrees from +z");
    // The region the frame is fitted to: the points' robust box grown to
    // what the cameras see at their points' depth, side 3, centred.
    let cameras: Vec<_> = s.frames.iter().map(|f| f.camera).collect();
    let (lo, hi) = datasets::colmap::frame::seen_region(&cameras, pts).expect("region");
    let largest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    assert!((largest - 3.0).abs() < 1e-6, "{lo:?} {hi:?}");
    assert!(
        (0..3).all(|k| (lo[k] + hi[k]).abs() < 1e-6),
        "{lo:?} {hi:?}"
    );
    assert!(sides.iter().all(|&side| side <= 3.0 + 1e-9), "{sides:?}");
    // Every image's corners, at the depth of what it sees, are in the box:
    // the desk around the statue is inside the field.
    for (f, cam) in s.frames.iter().zip(&cameras) {
        let mut d: Vec<f64> = pts
            .iter()
            .filter_map(|&p| cam.project(p))
            .map(|q| q.z)
            .collect();
        let depth = quantile(&mut d, 0.5);
        let (w, h) = (f.rgb.width as f64, f.rgb.height as f64);
        for (u, v) in [(0.0, 0.0), (w - 1.0, h - 1.0)] {
            let r = cam.ray(u, v);
            let p: [f64; 3] = std::array::from_fn(|i| r.origin[i] + depth * r.direction[i]);
            let m = 0.2;
            assert!(
                (0..3).all(|k| p[k] > b.min[k] - m && p[k] < b.max[k] + m),
                "{}: corner {p:?} outside {b:?}",
                f.name
            );
        }
    }
    assert!(inside * 10 >= pts.len() * 9, "{inside} of {}", pts.len());
    assert_eq!(s.name, "colmap_statue");
    assert!(s.features.is_none() && s.classes.is_none() && s.background.is_none());
}

#[test]
fn truncated_images_bin_is_named() {
    let Some(dir) = statue() else {
        return;
    };
    let tmp = statue_copy(&dir, |sparse| {
        for f in ["cameras.bin", "points3D.bin"] {
            std::fs::copy(dir.join("sparse").join(f), sparse.join(f)).expect("copy");
        }
        let bytes = std::fs::read(dir.join("sparse").join("images.bin")).expect("read");
        std::fs::write(sparse.join("images.bin"), &bytes[..bytes.len() / 2]).expect("write");
    });
    let msg = match load_colmap(tmp.path(), &ColmapOptions::default()) {
        Ok(_) => panic!("a truncated images.bin loads"),
        Err(e) => e.to_string(),
    };
    println!("{msg}");
    assert!(msg.contains("images.bin"), "{msg}");
    assert!(
        msg.contains("truncated: image") && msg.contains("of 23"),
        "{msg}"
    );
}

#[test]
fn sparse_points_reproject_onto_their_features_through_the_loaded_cameras() {
    // The loaded cameras (scene frame, pixel-centre principal point, each
    // image's own intrinsics) and the mapped points must reproduce COLMAP's
    // own observations to about its reprojection error, and each
    // observation's pixel ray must pass through its point.
    let Some(dir) = statue() else {
        return;
    };
    let s = load_colmap(&dir, &ColmapOptions::default()).expect("loads");
    let model = read_model(&dir.join("sparse")).expect("model");
    let ids: std::collections::HashMap<u64, usize> = model
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (p.id, i))
        .collect();
    let pts = &s.points.as_ref().expect("points").positions;
    let (mut errs, mut ray_errs) = (Vec::new(), Vec::new());
    for f in &s.frames {
        let image = model
            .images
            .iter()
            .find(|im| im.name.starts_with(&f.name))
            .expect("image of frame");
        for p2 in &image.points2d {
            let Some(i) = p2.point3d_id.and_then(|id| ids.get(&id)) else {
                continue;
            };
            let p = pts[*i];
            let q = f.camera.project(p).expect("in front");
            let (u, v) = (p2.xy[0] - 0.5, p2.xy[1] - 0.5);
            errs.push(((q.u - u).powi(2) + (q.v - v).powi(2)).sqrt());
            let r = f.camera.ray(u, v);
            let dir = r.direction.map(|c| c / model::geometry::norm(r.direction));
            let d: [f64; 3] = std::array::from_fn(|k| p[k] - r.origin[k]);
            let t = (0..3).map(|k| d[k] * dir[k]).sum::<f64>();
            let miss = (0..3)
                .map(|k| (d[k] - t * dir[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            ray_errs.push(miss / t * f.camera.intrinsics.fx);
        }
    }
    let median = quantile(&mut errs.clone(), 0.5);
    let p90 = quantile(&mut errs, 0.9);
    let ray_median = quantile(&mut ray_errs, 0.5);
    println!(
        "statue: reprojection through the loaded cameras, median {median:.3} px, 90th percentile \
         {p90:.3} px; ray miss median {ray_median:.3} px"
    );
    assert!(median < 1.0 && p90 < 2.0, "{median} {p90}");
    assert!(ray_median < 1.0, "{ray_median}");
}

/// The cup capture: 77 photographs at 800 x 600, each with a camera of its
/// own (SIMPLE_PINHOLE), the model in `sparse/0`: every photograph loads
/// with its own focal length, and the cameras look at what the sparse
/// points hold.
#[test]
fn the_cup_loads_with_a_camera_per_photograph() {
    let Some(dir) = datasets::shared_dataset("colmap_cup") else {
        return;
    };
    let s = load_colmap(&dir, &ColmapOptions::default()).expect("the cup loads");
    assert_eq!(s.frames.len(), 77);
    let model = read_model(&dir.join("sparse/0")).expect("model");
    assert_eq!(model.cameras.len(), 77, "one camera per image");
    let mut focals: Vec<f64> = s.frames.iter().map(|f| f.camera.intrinsics.fx).collect();
    for f in &s.frames {
        let k = f.camera.intrinsics;
        assert_eq!((k.width, k.height), (800, 600), "{}", f.name);
        assert_eq!(
            k.fx, k.fy,
            "{}: SIMPLE_PINHOLE has one focal length",
            f.name
        );
        assert_eq!((f.rgb.width, f.rgb.height), (800, 600));
    }
    focals.sort_by(f64::total_cmp);
    focals.dedup();
    assert!(
        focals.len() > 1,
        "the per-image cameras' focal lengths were merged: {focals:?}"
    );
    let points = s.points.as_ref().expect("sparse points");
    assert!(points.positions.len() > 100, "{}", points.positions.len());
}
