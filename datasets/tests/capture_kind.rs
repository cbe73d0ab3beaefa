//! The capture's kind told from its content, on the built-in scenes and on
//! every capture of the shared data (skipped with a message when absent).

use datasets::blender::{BlenderOptions, load_blender};
use datasets::capture_kind::{CaptureKind, capture_kind};
use datasets::colmap::load_colmap;
use datasets::llff::{LlffOptions, load_llff};
use datasets::options::ColmapOptions;
use datasets::replica::{ReplicaOptions, load_replica};
use datasets::synthetic::{SceneSize, generate};
use datasets::{Scene, shared_dataset};

fn check(label: &str, scene: &Scene, expected: CaptureKind) {
    let (kind, evidence) = capture_kind(scene);
    eprintln!("{label}: {kind:?}: {}", evidence.describe());
    assert_eq!(kind, expected, "{label}: {}", evidence.describe());
}

#[test]
fn the_built_in_scenes() {
    for size in [SceneSize::Ci, SceneSize::Bench] {
        let s = generate(0, size).expect("the synthetic room");
        check(&format!("synthetic {size:?}"), &s, CaptureKind::Room);
    }
    let s = generate(0, SceneSize::Outdoor).expect("the outdoor scene");
    check("synthetic outdoor", &s, CaptureKind::OpenScene);
}

#[test]
fn the_shared_captures() {
    if let Some(dir) = shared_dataset("lego_train") {
        let opts = BlenderOptions {
            downscale: 8,
            ..BlenderOptions::default()
        };
        let s = load_blender(&dir, &opts).expect("lego");
        check("lego", &s, CaptureKind::RenderedObject);
    }
    if let Some(dir) = shared_dataset("llff_fern") {
        let s = load_llff(&dir, &LlffOptions::default()).expect("fern");
        check("fern", &s, CaptureKind::ForwardFacing);
    }
    if let Some(dir) = shared_dataset("replica_room0_20f") {
        let s = load_replica(&dir, &ReplicaOptions::default()).expect("replica");
        check("replica", &s, CaptureKind::Room);
    }
    for name in ["colmap_statue", "colmap_cup"] {
        if let Some(dir) = shared_dataset(name) {
            let opts = ColmapOptions {
                sparse_depth: true,
                ..ColmapOptions::default()
            };
            let s = load_colmap(&dir, &opts).expect(name);
            check(name, &s, CaptureKind::PhotographedObject);
        }
    }
}

/// The largest side of the scene box over the median distance of the
/// cameras from its centre: how much of what the cameras look at the box
/// holds, in any frame's units.
fn box_over_distance(s: &Scene) -> f64 {
    let b = &s.scene_box;
    let side = (0..3).map(|k| b.max[k] - b.min[k]).fold(0.0, f64::max);
    let c = b.center();
    let mut d: Vec<f64> = s
        .frames
        .iter()
        .map(|f| {
            let p = f.camera.pose.center();
            ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt()
        })
        .collect();
    d.sort_by(f64::total_cmp);
    side / d[d.len() / 2]
}

#[test]
fn lego_as_a_colmap_model_without_points_is_the_same_rendered_object() {
    let Some(dir) = shared_dataset("lego_train") else {
        return;
    };
    let opts = BlenderOptions {
        downscale: 8,
        ..BlenderOptions::default()
    };
    let lego = load_blender(&dir, &opts).expect("lego");
    let tmp = tempfile::tempdir().expect("tmp");
    datasets::writer::write_colmap_text(&lego, tmp.path(), datasets::writer::ImageFormat::Png)
        .expect("written");
    let colmap = load_colmap(tmp.path(), &ColmapOptions::default()).expect("loads back");
    check(
        "lego as COLMAP without points",
        &colmap,
        CaptureKind::RenderedObject,
    );
    // The frame is fitted to what the cameras see around their focus, not
    // to a box holding every camera: about the object's own box.
    let (known, fitted) = (box_over_distance(&lego), box_over_distance(&colmap));
    eprintln!("box side over camera distance: transforms.json {known:.3}, COLMAP {fitted:.3}");
    assert!((fitted / known - 1.0).abs() < 0.25, "{known} {fitted}");
    assert!(
        colmap
            .frames
            .iter()
            .all(|f| !colmap.scene_box.contains(f.camera.pose.center()))
    );
}

#[test]
fn photographs_in_a_transforms_json_are_photographs() {
    let Some(dir) = shared_dataset("colmap_statue") else {
        return;
    };
    let statue = load_colmap(&dir, &ColmapOptions::default()).expect("statue");
    let tmp = tempfile::tempdir().expect("tmp");
    datasets::writer::write_nerfstudio(&statue, tmp.path(), datasets::writer::ImageFormat::Jpeg)
        .expect("written");
    let s = load_blender(tmp.path(), &BlenderOptions::default()).expect("loads back");
    check(
        "the statue as transforms.json",
        &s,
        CaptureKind::PhotographedObject,
    );
}

#[test]
fn the_synthetic_room_in_every_written_format_is_a_room() {
    let room = generate(0, SceneSize::Ci).expect("the synthetic room");
    let tmp = tempfile::tempdir().expect("tmp");
    let replica = tmp.path().join("replica");
    datasets::writer::write_scene(&room, &replica, &datasets::writer::WriteOptions::default())
        .expect("written");
    let s = load_replica(&replica, &ReplicaOptions::default()).expect("replica loads");
    check("the room as Replica", &s, CaptureKind::Room);
    let ns = tmp.path().join("nerfstudio");
    datasets::writer::write_nerfstudio(&room, &ns, datasets::writer::ImageFormat::Png)
        .expect("written");
    let s = load_blender(&ns, &BlenderOptions::default()).expect("nerfstudio loads");
    check("the room as transforms.json", &s, CaptureKind::Room);
}
