//! Loaders on the real shared data (skipped with a message when absent).
//! Run with `--nocapture` to see the figures.

use datasets::blender::{BlenderOptions, load_blender};
use datasets::llff::{LlffOptions, load_llff};
use datasets::options::FrameSelection;
use datasets::points::{ClassMap, IGNORE_LABEL};
use datasets::replica::{ReplicaOptions, load_replica};
use datasets::text::TextEmbeddings;
use datasets::{Scene, shared_dataset};
use model::geometry::norm;

fn print_scene(label: &str, s: &Scene) {
    let k = &s.frames[0].camera.intrinsics;
    println!(
        "{label}: {} frames {}x{}, fx {:.4} fy {:.4} cx {:.4} cy {:.4}",
        s.frames.len(),
        k.width,
        k.height,
        k.fx,
        k.fy,
        k.cx,
        k.cy
    );
    let b = &s.scene_box;
    println!(
        "{label}: box min [{:.3}, {:.3}, {:.3}] max [{:.3}, {:.3}, {:.3}]",
        b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]
    );
}

#[test]
fn replica_room0_at_640x360() {
    let Some(dir) = shared_dataset("replica_room0_20f") else {
        return;
    };
    let opts = ReplicaOptions {
        selection: FrameSelection {
            resolution: Some((640, 360)),
            ..FrameSelection::default()
        },
        ..Default::default()
    };
    let s = load_replica(&dir, &opts).expect("replica loads");
    print_scene("replica", &s);
    assert_eq!(s.frames.len(), 20);
    let k = &s.frames[0].camera.intrinsics;
    // fx' = fx * 640/1200, cx' = (cx + 0.5) * 640/1200 - 0.5.
    assert!((k.fx - 320.0).abs() < 1e-9 && (k.fy - 600.0 * 360.0 / 680.0).abs() < 1e-9);
    assert!((k.cx - 319.5).abs() < 1e-9 && (k.cy - 179.5).abs() < 1e-9);
    let d = s.frames[0].depth.as_ref().expect("depth");
    let valid: Vec<f32> = d.to_f32().iter().copied().filter(|&v| v > 0.0).collect();
    let (lo, hi) = valid
        .iter()
        .fold((f32::MAX, 0f32), |(a, b), &v| (a.min(v), b.max(v)));
    println!(
        "replica: frame 0 depth range {lo:.4} .. {hi:.4} m ({} valid of {})",
        valid.len(),
        d.len()
    );
    assert!(lo > 0.1 && hi < 15.0 && hi > lo);
    for f in &s.frames {
        assert!(s.scene_box.contains(f.camera.pose.center()));
    }
}

#[test]
fn replica_poses_are_opencv_camera_to_world() {
    // Independent check of the pose convention: surface points seen by frame
    // 0 reproject into frame 3 at the depth frame 3 measures there.
    let Some(dir) = shared_dataset("replica_room0_20f") else {
        return;
    };
    let opts = ReplicaOptions {
        selection: FrameSelection {
            resolution: Some((300, 170)),
            max_frames: Some(4),
            ..FrameSelection::default()
        },
        ..Default::default()
    };
    let s = load_replica(&dir, &opts).expect("replica loads");
    let (a, b) = (&s.frames[0], &s.frames[3]);
    let (da, db) = (a.depth.as_ref().expect("d"), b.depth.as_ref().expect("d"));
    let mut errs = Vec::new();
    for y in (5..170).step_by(7) {
        for x in (5..300).step_by(7) {
            let d = da.get(x, y) as f64;
            if d <= 0.0 {
                continue;
            }
            let r = a.camera.ray(x as f64, y as f64);
            let p = model::geometry::add_scaled(r.origin, d, r.direction);
            let Some(pr) = b.camera.project(p) else {
                continue;
            };
            let (u, v) = (pr.u.round(), pr.v.round());
            if u < 0.0 || v < 0.0 || u >= 300.0 || v >= 170.0 {
                continue;
            }
            let dm = db.get(u as u32, v as u32) as f64;
            if dm > 0.0 {
                errs.push((dm - pr.z).abs());
            }
        }
    }
    errs.sort_by(f64::total_cmp);
    let median = errs[errs.len() / 2];
    println!(
        "replica: reprojection depth error median {median:.4} m over {} points",
        errs.len()
    );
    assert!(errs.len() > 300 && median < 0.03, "median {median}");
}

#[test]
fn lego_downscaled_by_8() {
    let Some(dir) = shared_dataset("lego_train") else {
        return;
    };
    let opts = BlenderOptions {
        downscale: 8,
        ..Default::default()
    };
    let s = load_blender(&dir, &opts).expect("lego loads");
    print_scene("lego", &s);
    assert_eq!(s.frames.len(), 100);
    let k = &s.frames[0].camera.intrinsics;
    let f = 400.0 / (0.5f64 * 0.6911112070083618).tan() / 8.0;
    assert_eq!((k.width, k.height), (100, 100));
    assert!((k.fx - f).abs() < 1e-9 && (k.cx - 49.5).abs() < 1e-9);
    // The object at the origin is in front of every camera, near the image centre.
    for fr in &s.frames {
        let p = fr.camera.project([0.0, 0.0, 0.0]).expect("in front");
        assert!(
            (p.u - 49.5).abs() < 10.0 && (p.v - 49.5).abs() < 10.0,
            "{p:?}"
        );
        assert!(norm(fr.camera.pose.center()) > 3.5);
    }
    // The box covers the object's [-1.5, 1.5]^3 region closely.
    for (lo, hi) in s.scene_box.min.iter().zip(&s.scene_box.max) {
        assert!(*lo < -1.3 && *lo > -1.8 && *hi > 1.3 && *hi < 1.8);
    }
    // Transparent corners composite to the white background.
    assert_eq!(s.background, Some([1.0; 3]));
    assert!(s.frames[0].rgb.get(0, 0).iter().all(|&v| v > 0.99));
}

#[test]
fn fern_at_images_8() {
    let Some(dir) = shared_dataset("llff_fern") else {
        return;
    };
    let s = load_llff(&dir, &LlffOptions::default()).expect("fern loads");
    print_scene("fern", &s);
    assert_eq!(s.frames.len(), 20);
    let k = &s.frames[0].camera.intrinsics;
    assert_eq!((k.width, k.height), (504, 378));
    // Forward-facing capture: every camera looks the same way (+z of the
    // first camera) and the scene centre is in front of all of them.
    let fwd0 = s.frames[0].camera.pose.forward();
    let centre = s.scene_box.center();
    for fr in &s.frames {
        let f = fr.camera.pose.forward();
        assert!(model::geometry::dot(f, fwd0) > 0.9);
        assert!(fr.camera.project(centre).is_some());
        assert!(s.scene_box.contains(fr.camera.pose.center()));
    }
}

#[test]
fn clip_text_embeddings() {
    let Some(dir) = shared_dataset("clip_text") else {
        return;
    };
    let t = TextEmbeddings::load(
        &dir.join("scannet200_vitb_512.npy"),
        &dir.join("scannet200_labels.txt"),
    )
    .expect("embeddings load");
    assert_eq!((t.len(), t.dim), (200, 512));
    assert_eq!(t.index_of("wall"), Some(0));
    assert!(t.index_of("chair").is_some());
    for i in 0..t.len() {
        let n: f32 = t.row(i).iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((n - 1.0).abs() < 5e-3, "row {i} norm {n}");
    }
}

#[test]
fn replica_class_map() {
    let Some(dir) = shared_dataset("replica_classes") else {
        return;
    };
    let m = ClassMap::load_replica(&dir.join("replica_class_id_to_names.txt")).expect("loads");
    assert_eq!(m.names.len(), 51);
    let mapped = m.map(&[93, -1, 20, 1000]);
    assert_eq!(m.names[mapped[0] as usize], "wall");
    assert_eq!(mapped[1], IGNORE_LABEL);
    assert_eq!(m.names[mapped[2] as usize], "chair");
    assert_eq!(mapped[3], IGNORE_LABEL);
}

#[test]
fn load_scene_dispatches_on_the_source() {
    let Some(dir) = shared_dataset("lego_train") else {
        return;
    };
    // A source as `scene.json` records it, options as JSON.
    let source: datasets::SceneSource = serde_json::from_value(serde_json::json!({
        "kind": "disk",
        "format": "blender",
        "path": dir.clone(),
        "options": {"downscale": 16, "max_frames": 3},
    }))
    .expect("source");
    let s = datasets::load_scene(&source).expect("loads");
    let opts = BlenderOptions {
        downscale: 16,
        selection: FrameSelection {
            max_frames: Some(3),
            ..FrameSelection::default()
        },
        ..Default::default()
    };
    let direct = load_blender(&dir, &opts).expect("loads");
    assert_eq!(s.frames, direct.frames);
    assert_eq!(s.scene_box, direct.scene_box);
    assert_eq!(
        s.source,
        datasets::SceneSource::Disk {
            loader: datasets::LoaderOptions::Blender(opts),
            path: dir.clone(),
        }
    );
    // The recorded source rebuilds the same scene.
    let again = datasets::load_scene(&s.source).expect("reloads");
    assert_eq!(again.frames, s.frames);
    // A format no loader reads is refused when the source is read.
    let err = serde_json::from_value::<datasets::SceneSource>(serde_json::json!({
        "kind": "disk",
        "format": "photogrammetry",
        "path": dir,
        "options": null,
    }))
    .expect_err("unknown format");
    assert!(
        err.to_string().contains("unknown variant `photogrammetry`"),
        "{err}"
    );
}

/// Format detection on every directory of the shared data: each scene is
/// recognised as its format, the directories that hold no scene (text
/// embeddings, a class list) are refused with what each format needs.
#[test]
fn detection_recognises_every_shared_scene() {
    use datasets::detect::{Format, detect};
    let Some(root) = shared_dataset("") else {
        return;
    };
    let want = [
        ("colmap_statue", Some(Format::Colmap)),
        ("colmap_cup", Some(Format::Colmap)),
        ("lego_train", Some(Format::Blender)),
        ("llff_fern", Some(Format::Llff)),
        ("replica_room0_20f", Some(Format::Replica)),
        ("clip_text", None),
        ("replica_classes", None),
    ];
    let mut seen = 0;
    for (name, format) in want {
        let dir = root.join(name);
        assert!(
            dir.is_dir(),
            "{}: missing from the shared data",
            dir.display()
        );
        seen += 1;
        match (detect(&dir), format) {
            (Ok(d), Some(f)) => assert_eq!(d.format, f, "{name}: {}", d.evidence),
            (Err(e), None) => assert!(e.to_string().contains("no scene format"), "{e}"),
            (got, want) => panic!("{name}: detected {got:?}, expected {want:?}"),
        }
    }
    // Every directory of the shared data is covered by the table above.
    let listed = std::fs::read_dir(&root)
        .expect("data dir")
        .filter(|e| e.as_ref().is_ok_and(|e| e.path().is_dir()))
        .count();
    assert_eq!(
        listed, seen,
        "a shared data directory is missing from the table"
    );
}

/// The shared captures' photographs, loaded at their own size as 8-bit
/// colour, read back exactly the floats the decoder gives them (`v / 255`
/// of each byte): their scenes, and the runs trained on them, are those of
/// the float storage they replaced.
#[test]
fn eight_bit_photographs_read_back_the_decoders_floats() {
    let mut checked = 0;
    for (name, folder) in [
        ("colmap_statue", "images"),
        ("colmap_cup", "images"),
        ("llff_fern", "images_8"),
        ("replica_room0_20f", "results"),
    ] {
        let Some(dir) = shared_dataset(name) else {
            continue;
        };
        let mut files: Vec<_> = std::fs::read_dir(dir.join(folder))
            .expect("images")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension()
                    .is_some_and(|x| ["jpg", "JPG", "png"].contains(&x.to_str().unwrap_or("")))
                    && !p
                        .file_name()
                        .is_some_and(|n| n.to_string_lossy().starts_with("depth"))
            })
            .collect();
        files.sort();
        let path = &files[0];
        let stored = datasets::imageio::load_rgb(path, None, None).expect("load");
        assert!(
            matches!(stored.data, datasets::RgbData::U8(_)),
            "{}: kept as bytes",
            path.display()
        );
        let floats = image::open(path).expect("decode").into_rgb32f();
        let want: Vec<u32> = floats.into_raw().iter().map(|v| v.to_bits()).collect();
        let got: Vec<u32> = stored.to_f32().iter().map(|v| v.to_bits()).collect();
        assert_eq!(got, want, "{}", path.display());
        checked += 1;
    }
    println!("{checked} captures' photographs read back bit for bit");
}
