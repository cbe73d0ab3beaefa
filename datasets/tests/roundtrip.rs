//! Writes the synthetic scene in the Nice-SLAM layout and reads it back with
//! the on-disk loaders.

use datasets::options::FeatureInput;
use datasets::points::read_ply;
use datasets::replica::{ReplicaOptions, load_replica};
use datasets::synthetic::{self, SceneSize};
use datasets::text::TextEmbeddings;
use datasets::writer::{DEPTH_SCALE, FeatureLayout, ImageFormat, WriteOptions, write_scene};

fn check_roundtrip(format: ImageFormat, colour_tolerance: f32, mean_tolerance: f32) {
    let scene = synthetic::generate(3, SceneSize::Ci).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let options = WriteOptions {
        image_format: format,
        features: FeatureLayout::Full,
    };
    write_scene(&scene, &dir, &options).unwrap();
    let loaded = load_replica(
        &dir,
        &ReplicaOptions {
            feature_input: FeatureInput {
                features: Some(dir.join("features")),
                ..FeatureInput::default()
            },
            ..ReplicaOptions::default()
        },
    )
    .unwrap();
    assert_eq!(loaded.frames.len(), scene.frames.len());
    for (a, b) in scene.frames.iter().zip(&loaded.frames) {
        assert_eq!(a.name, b.name);
        let (ma, mb) = (a.camera.pose.to_matrix(), b.camera.pose.to_matrix());
        for (x, y) in ma.iter().flatten().zip(mb.iter().flatten()) {
            assert!((x - y).abs() < 1e-9, "pose {x} vs {y}");
        }
        let (ka, kb) = (a.camera.intrinsics, b.camera.intrinsics);
        assert_eq!((ka.width, ka.height), (kb.width, kb.height));
        for (x, y) in [
            (ka.fx, kb.fx),
            (ka.fy, kb.fy),
            (ka.cx, kb.cx),
            (ka.cy, kb.cy),
        ] {
            assert!((x - y).abs() < 1e-9, "intrinsics {x} vs {y}");
        }
        let (da, db) = (a.depth.as_ref().unwrap(), b.depth.as_ref().unwrap());
        for (x, y) in da.to_f32().iter().zip(db.to_f32().iter()) {
            assert!(
                ((x - y).abs() as f64) <= 0.5 / DEPTH_SCALE + 1e-6,
                "depth {x} vs {y}"
            );
        }
        let mut max = 0f32;
        let mut sum = 0f32;
        for (x, y) in a.rgb.to_f32().iter().zip(b.rgb.to_f32().iter()) {
            max = max.max((x - y).abs());
            sum += (x - y).abs();
        }
        let mean = sum / a.rgb.len() as f32;
        assert!(max <= colour_tolerance, "colour max error {max}");
        assert!(mean <= mean_tolerance, "colour mean error {mean}");
    }
    // Feature maps: f16 written, f16 read back exactly.
    let (fa, fb) = (
        scene.features.as_ref().unwrap(),
        loaded.features.as_ref().unwrap(),
    );
    assert_eq!(fa.maps, fb.maps);
    // Class embeddings (f32 on disk) and names.
    let classes = TextEmbeddings::load(&dir.join("classes.npy"), &dir.join("classes.txt")).unwrap();
    assert_eq!(&classes, scene.classes.as_ref().unwrap());
    // Point cloud: positions as f32, colours and labels exact.
    let cloud = read_ply(&dir.join("points.ply")).unwrap();
    let orig = scene.points.as_ref().unwrap();
    assert_eq!(cloud.positions.len(), orig.positions.len());
    for (p, q) in cloud.positions.iter().zip(&orig.positions) {
        for k in 0..3 {
            assert!((p[k] - q[k]).abs() < 1e-6 * (1.0 + q[k].abs()));
        }
    }
    assert_eq!(cloud.labels, orig.labels);
    assert_eq!(cloud.colors, orig.colors);
}

#[test]
fn png_scene_reads_back_through_the_replica_loader() {
    // 8-bit quantisation only.
    check_roundtrip(ImageFormat::Png, 0.5 / 255.0 + 1e-6, 0.5 / 255.0);
}

#[test]
fn jpeg_scene_reads_back_through_the_replica_loader() {
    // Quality-95 JPEG with chroma subsampling: small mean error, larger on edges.
    check_roundtrip(ImageFormat::Jpeg, 0.5, 0.03);
}

#[test]
fn compressed_features_can_be_written_as_coefficients_or_lifted() {
    let mut scene = synthetic::generate(3, SceneSize::Ci).unwrap();
    let maps = scene.features.take().unwrap().maps;
    let compressed = datasets::features::FeatureSet::from_maps(
        maps,
        datasets::features::PcaSetting::Components(8),
        1,
    )
    .unwrap();
    let pca = compressed.pca.clone().unwrap();
    let first = compressed.maps[0].clone();
    scene.features = Some(compressed);
    let tmp = tempfile::tempdir().unwrap();
    for layout in [FeatureLayout::Full, FeatureLayout::Coefficients] {
        let dir = tmp.path().join(format!("{layout:?}"));
        let options = WriteOptions {
            image_format: ImageFormat::Png,
            features: layout,
        };
        write_scene(&scene, &dir, &options).unwrap();
        let (shape, data) =
            datasets::npy::read_npy_f32(&dir.join("features/frame000000.npy")).unwrap();
        let coeffs: Vec<f32> = first.data.iter().map(|v| v.to_f32()).collect();
        match layout {
            FeatureLayout::Full => {
                assert_eq!(
                    shape,
                    vec![first.height as usize, first.width as usize, pca.dim]
                );
                let lifted = pca.lift(&coeffs);
                for (x, y) in data.iter().zip(&lifted) {
                    assert!((x - y).abs() < 2e-3, "{x} vs {y}");
                }
            }
            FeatureLayout::Coefficients => {
                assert_eq!(
                    shape,
                    vec![first.height as usize, first.width as usize, pca.k]
                );
                assert_eq!(data, coeffs);
                let text = std::fs::read_to_string(dir.join("features/pca.json")).unwrap();
                let back: datasets::features::PcaBasis = serde_json::from_str(&text).unwrap();
                assert_eq!(back, pca);
            }
        }
    }
}
