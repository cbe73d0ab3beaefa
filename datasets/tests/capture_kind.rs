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
