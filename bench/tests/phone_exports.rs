//! The Replica frames written out as each phone export load back through
//! their loaders with the Replica loader's rays (to 1e-6, after undoing
//! the export's world map and the loader's frame) and its depth targets
//! where both have depth; depth below the confidence threshold or beyond
//! the range is never a target; the mesh's ray-cast depth agrees with the
//! Replica depth where an export has no depth maps.

use std::path::Path;

use bench::phone_export::{self, ReplicaFrames, confidence_level, scanner};
use datasets::options::{DepthConfidence, FrameSelection};
use datasets::replica::{ReplicaOptions, load_replica};
use datasets::{LoaderOptions, PhoneOptions, Scene, SceneSource, shared_dataset};
use model::geometry::{Camera, Similarity};

/// The loaded size: the depth maps' (a quarter of Replica's 1200x680), so
/// that each target pixel is one depth pixel.
const SIZE: (u32, u32) = (300, 170);

fn replica(dir: &Path) -> Scene {
    load_replica(
        dir,
        &ReplicaOptions {
            selection: FrameSelection {
                resolution: Some(SIZE),
                ..FrameSelection::default()
            },
            ..Default::default()
        },
    )
    .expect("replica loads")
}

/// A phone format's loader options from its options.
type Loader = fn(PhoneOptions) -> LoaderOptions;

fn phone(dir: &Path, loader: Loader, o: PhoneOptions) -> Scene {
    let source = SceneSource::Disk {
        loader: loader(PhoneOptions {
            selection: FrameSelection {
                resolution: Some(SIZE),
                ..FrameSelection::default()
            },
            ..o
        }),
        path: dir.to_path_buf(),
    };
    datasets::load_scene(&source).expect("phone export loads")
}

/// The map from the phone scene's frame back to Replica's.
fn to_replica(scene: &Scene) -> Similarity {
    let world = scene
        .world
        .as_ref()
        .expect("a phone scene records its frame");
    assert_eq!(world.name, "arkit");
    ReplicaFrames::to_arkit()
        .inverse()
        .compose(&world.to_scene.inverse())
}

/// Rays of every 7th pixel agree to 1e-6 once mapped back.
fn assert_same_rays(got: &Scene, want: &Scene) {
    assert_eq!(got.frames.len(), want.frames.len());
    let back = to_replica(got);
    for (g, w) in got.frames.iter().zip(&want.frames) {
        let k = (g.camera.intrinsics, w.camera.intrinsics);
        assert!(
            (k.0.fx - k.1.fx).abs() < 1e-9 && (k.0.cy - k.1.cy).abs() < 1e-9,
            "{k:?}"
        );
        let cam = Camera {
            intrinsics: g.camera.intrinsics,
            pose: back.apply_pose(&g.camera.pose),
        };
        for y in (0..SIZE.1).step_by(7) {
            for x in (0..SIZE.0).step_by(7) {
                let (a, b) = (
                    cam.ray(x as f64, y as f64),
                    w.camera.ray(x as f64, y as f64),
                );
                for i in 0..3 {
                    assert!(
                        (a.origin[i] - b.origin[i]).abs() < 1e-6,
                        "{}: origin",
                        g.name
                    );
                    assert!(
                        (a.direction[i] - b.direction[i]).abs() < 1e-6,
                        "{}: direction {:?} vs {:?}",
                        g.name,
                        a.direction,
                        b.direction
                    );
                }
            }
        }
        assert_eq!(g.rgb, w.rgb, "{}: the same image bytes", g.name);
    }
}

/// Depth targets: equal to `tol` where confidence is at least `min` and the
/// depth within `max_depth`, and never a target elsewhere. A phone's depth
/// is kept in half floats: `tol` more the half float's rounding (half a
/// unit in the last place, at most `b / 2048`).
fn assert_same_depth(got: &Scene, want: &Scene, min: u8, max_depth: f32, tol: f32) -> usize {
    let mut compared = 0;
    for (i, (g, w)) in got.frames.iter().zip(&want.frames).enumerate() {
        let (gd, wd) = (
            g.depth.as_ref().expect("phone depth"),
            w.depth.as_ref().expect("replica depth"),
        );
        for y in 0..SIZE.1 {
            for x in 0..SIZE.0 {
                let (a, b) = (gd.get(x, y), wd.get(x, y));
                // Rounded to millimetres, a depth at the range's edge may
                // fall on either side of it.
                if (b - max_depth).abs() <= tol {
                    continue;
                }
                let kept = b > 0.0 && confidence_level(i, x, y, b) >= min && b <= max_depth;
                if kept {
                    let allowed = tol + b / 2048.0;
                    assert!(
                        (a - b).abs() <= allowed,
                        "{}: ({x}, {y}) {a} vs {b}",
                        g.name
                    );
                    compared += 1;
                } else {
                    assert_eq!(a, 0.0, "{}: ({x}, {y}) is no target", g.name);
                }
            }
        }
    }
    compared
}

/// The export's world is turned 30 degrees from the room's walls; the
/// loader turns it back, so its box is the Replica loader's size (not a
/// third wider, which would coarsen the field).
fn assert_as_tight_a_box(got: &Scene, want: &Scene) {
    let size = |s: &Scene| -> Vec<f64> {
        (0..3)
            .map(|i| s.scene_box.max[i] - s.scene_box.min[i])
            .collect()
    };
    let (g, w) = (size(got), size(want));
    println!("box {g:.3?} vs Replica's {w:.3?}");
    // Every side, the height included: the 3D Scanner App export's mesh is
    // made from four frames' depth and covers less height than the depth
    // maps, which the box holds as well.
    for i in 0..3 {
        assert!((g[i] - w[i]).abs() < 0.02 * w[i], "box {g:?} vs {w:?}");
    }
    assert!((got.scene_box.scale() - want.scene_box.scale()).abs() < 0.02 * want.scene_box.scale());
}

#[test]
fn each_phone_export_of_the_replica_frames_loads_back_as_replica() {
    let Some(dir) = shared_dataset("replica_room0_20f") else {
        return;
    };
    let frames = ReplicaFrames::read(&dir).expect("frames");
    let want = replica(&dir);
    let tmp = tempfile::tempdir().expect("tmp");
    // Millimetre PNGs round to 0.5 mm; float maps are exact.
    let mm = 0.5e-3 + 1e-6;
    let scan = tmp.path().join("scanner");
    scanner::write(
        &frames,
        &scan,
        scanner::ScannerExport {
            depth: true,
            mesh: true,
        },
    )
    .expect("write");
    let poly = tmp.path().join("polycam");
    phone_export::polycam::write(&frames, &poly, true).expect("write");
    let r3d_dir = tmp.path().join("record3d-exr");
    phone_export::record3d::write_exr(&frames, &r3d_dir).expect("write");
    let r3d = tmp.path().join("capture.r3d");
    phone_export::record3d::write_r3d(&frames, &r3d).expect("write");
    let cases: [(&Path, Loader, f32); 4] = [
        (&scan, LoaderOptions::ScannerApp, mm),
        (&poly, LoaderOptions::Polycam, mm),
        (&r3d_dir, LoaderOptions::Record3d, 1e-6),
        (&r3d, LoaderOptions::Record3d, 1e-6),
    ];
    for (path, loader, tol) in cases {
        let got = phone(path, loader, PhoneOptions::default());
        assert_same_rays(&got, &want);
        assert_as_tight_a_box(&got, &want);
        let n = assert_same_depth(&got, &want, 2, 5.0, tol);
        println!("{}: {n} depth targets equal", path.display());
        assert!(n > 500_000, "{n}");
        // Lower thresholds keep more; a shorter range keeps less.
        let low = phone(
            path,
            loader,
            PhoneOptions {
                min_depth_confidence: DepthConfidence::Low,
                max_depth: 2.0,
                ..Default::default()
            },
        );
        assert_same_depth(&low, &want, 0, 2.0, tol);
    }
    // The scan's cloud is the mesh's vertices, with the texture's colours.
    let got = phone(&scan, LoaderOptions::ScannerApp, PhoneOptions::default());
    let cloud = got.points.expect("mesh cloud");
    assert!(cloud.colors.is_some() && cloud.positions.len() > 10_000);
}

/// Without depth maps, depth is ray-cast from the mesh: on the frames the
/// mesh was made from, it agrees with Replica's depth.
#[test]
fn mesh_depth_stands_in_for_missing_depth_maps() {
    let Some(dir) = shared_dataset("replica_room0_20f") else {
        return;
    };
    let frames = ReplicaFrames::read(&dir).expect("frames");
    let want = replica(&dir);
    let tmp = tempfile::tempdir().expect("tmp");
    scanner::write(
        &frames,
        tmp.path(),
        scanner::ScannerExport {
            depth: false,
            mesh: true,
        },
    )
    .expect("write");
    let got = phone(
        tmp.path(),
        LoaderOptions::ScannerApp,
        PhoneOptions::default(),
    );
    for &i in &scanner::MESH_FRAMES {
        let (g, w) = (
            got.frames[i].depth.as_ref().expect("ray-cast depth"),
            want.frames[i].depth.as_ref().expect("depth"),
        );
        let (mut close, mut both) = (0usize, 0usize);
        for (a, b) in g.to_f32().iter().zip(w.to_f32().iter()) {
            if *a > 0.0 && *b > 0.0 {
                both += 1;
                close += usize::from((a - b).abs() < 0.02);
            }
        }
        let share = close as f64 / both as f64;
        println!(
            "frame {i}: {both} pixels with both depths, {:.2}% within 2 cm",
            100.0 * share
        );
        assert!(both > 40_000 && share > 0.95, "frame {i}: {both}, {share}");
    }
}
