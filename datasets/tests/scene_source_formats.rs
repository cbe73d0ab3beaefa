//! `scene.json` of every format on disk, as runs wrote it before the
//! formats shared [`FrameSelection`] and [`FeatureInput`], reads back to the
//! same options; written again, it keeps every key and value it had (the
//! formats that gained an option gain its key, nothing else).

use std::path::PathBuf;

use datasets::blender::BlenderOptions;
use datasets::colmap::ColmapOptions;
use datasets::features::PcaSetting;
use datasets::llff::LlffOptions;
use datasets::options::{DepthConfidence, FeatureInput, FrameSelection};
use datasets::replica::ReplicaOptions;
use datasets::scannet::ScannetOptions;
use datasets::{LoaderOptions, PhoneOptions, SceneSource};

/// The source of a run on `format` with `options` (a JSON object), as
/// `scene.json` records it.
fn source_text(format: &str, options: &str) -> String {
    format!(r#"{{"kind":"disk","format":"{format}","options":{options},"path":"/data/scene"}}"#)
}

/// Reads `options` of `format` as a run's source and checks them against
/// `expected`; writes them again and checks that every key of `options`
/// keeps its value and that the only keys added are `added`.
fn check(format: &str, options: &str, expected: LoaderOptions, added: &[&str]) {
    let text = source_text(format, options);
    let source: SceneSource = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{text}: {e}"));
    assert_eq!(
        source,
        SceneSource::Disk {
            loader: expected,
            path: PathBuf::from("/data/scene"),
        },
        "{format}"
    );
    let written: serde_json::Value = serde_json::to_value(&source).expect("writes");
    let old: serde_json::Value = serde_json::from_str(options).expect("json");
    let (old, new) = (
        old.as_object().unwrap(),
        written["options"].as_object().unwrap(),
    );
    for (key, value) in old {
        assert_eq!(new.get(key), Some(value), "{format}: {key}");
    }
    let mut gained: Vec<&str> = new
        .keys()
        .filter(|k| !old.contains_key(*k))
        .map(String::as_str)
        .collect();
    gained.sort_unstable();
    assert_eq!(gained, added, "{format}");
    if added.is_empty() {
        // Nothing gained: written back byte for byte.
        assert_eq!(serde_json::to_string(&source).unwrap(), text, "{format}");
    }
}

fn selection(
    stride: usize,
    max_frames: Option<usize>,
    resolution: Option<(u32, u32)>,
) -> FrameSelection {
    FrameSelection {
        stride,
        max_frames,
        resolution,
        ..FrameSelection::default()
    }
}

#[test]
fn replica_scannet_and_phone_sources_read_and_write_as_before() {
    check(
        "replica",
        r#"{"stride":10,"max_frames":20,"resolution":[640,360],"features":"/data/feats","pca":{"components":16},"seed":3,"box_margin":0.1,"box_pixel_step":4}"#,
        LoaderOptions::Replica(ReplicaOptions {
            selection: selection(10, Some(20), Some((640, 360))),
            feature_input: FeatureInput {
                features: Some(PathBuf::from("/data/feats")),
                pca: PcaSetting::Components(16),
                basis: None,
                seed: 3,
            },
            box_margin: 0.1,
            box_pixel_step: 4,
        }),
        &[],
    );
    check(
        "scannet",
        r#"{"stride":10,"max_frames":null,"resolution":[640,480],"box_margin":0.05,"box_pixel_step":8}"#,
        LoaderOptions::Scannet(ScannetOptions {
            selection: selection(10, None, Some((640, 480))),
            ..ScannetOptions::default()
        }),
        &[],
    );
    // As a scanner-app run wrote it (the defaults), and a Record3D run at a
    // resolution with compressed maps.
    check(
        "scanner_app",
        r#"{"stride":1,"max_frames":null,"resolution":null,"min_depth_confidence":"high","max_depth":5.0,"box_margin":0.05,"box_pixel_step":8,"features":null,"pca":"off","seed":0}"#,
        LoaderOptions::ScannerApp(PhoneOptions::default()),
        &[],
    );
    for format in ["record3d", "polycam"] {
        let options = PhoneOptions {
            selection: selection(2, Some(40), Some((320, 240))),
            min_depth_confidence: DepthConfidence::Medium,
            max_depth: 3.5,
            feature_input: FeatureInput {
                features: Some(PathBuf::from("/data/maps")),
                pca: PcaSetting::Auto,
                ..FeatureInput::default()
            },
            ..PhoneOptions::default()
        };
        let loader = match format {
            "record3d" => LoaderOptions::Record3d(options),
            _ => LoaderOptions::Polycam(options),
        };
        check(
            format,
            r#"{"stride":2,"max_frames":40,"resolution":[320,240],"min_depth_confidence":"medium","max_depth":3.5,"box_margin":0.05,"box_pixel_step":8,"features":"/data/maps","pca":"auto","seed":0}"#,
            loader,
            &[],
        );
    }
}

#[test]
fn blender_llff_and_colmap_sources_read_as_before_and_gain_only_the_new_keys() {
    check(
        "blender",
        r#"{"transforms":"transforms_train.json","downscale":4,"background":[0.0,0.0,0.0],"max_frames":3,"box_margin":0.05}"#,
        LoaderOptions::Blender(BlenderOptions {
            transforms: Some("transforms_train.json".into()),
            downscale: 4,
            background: [0.0; 3],
            selection: selection(1, Some(3), None),
            box_margin: 0.05,
        }),
        &["resolution", "stride"],
    );
    check(
        "llff",
        r#"{"images":null,"max_frames":null,"box_margin":0.05}"#,
        LoaderOptions::Llff(LlffOptions::default()),
        &["resolution", "stride"],
    );
    check(
        "colmap",
        r#"{"images":"images_2","depth":false,"sparse_depth":true,"stride":2,"max_frames":5,"box_margin":0.2,"features":"/data/f","pca":{"explained_variance":0.99},"seed":0}"#,
        LoaderOptions::Colmap(ColmapOptions {
            images: "images_2".into(),
            depth: false,
            sparse_depth: true,
            selection: selection(2, Some(5), None),
            box_margin: 0.2,
            feature_input: FeatureInput {
                features: Some(PathBuf::from("/data/f")),
                pca: PcaSetting::ExplainedVariance(0.99),
                ..FeatureInput::default()
            },
        }),
        &["resolution"],
    );
}

/// Options left out or `null` take their defaults, in the shared parts too.
#[test]
fn partial_and_null_options_take_the_defaults() {
    for format in [
        "replica",
        "blender",
        "llff",
        "colmap",
        "scannet",
        "scanner_app",
        "record3d",
        "polycam",
    ] {
        for options in ["null", "{}"] {
            let text = source_text(format, options);
            let source: SceneSource =
                serde_json::from_str(&text).unwrap_or_else(|e| panic!("{text}: {e}"));
            let SceneSource::Disk { loader, .. } = source else {
                panic!("{text}");
            };
            assert_eq!(*loader.selection(), FrameSelection::default(), "{text}");
            if let Some(input) = loader.feature_input() {
                assert_eq!(*input, FeatureInput::default(), "{text}");
            }
        }
    }
    let text = source_text("colmap", r#"{"pca":null,"max_frames":7}"#);
    let source: SceneSource = serde_json::from_str(&text).expect("reads");
    let SceneSource::Disk { loader, .. } = source else {
        panic!("{text}");
    };
    assert_eq!(loader.selection().max_frames, Some(7));
    assert_eq!(loader.feature_input().map(|f| f.pca), Some(PcaSetting::Off));
}

/// The formats that read pre-sized images refuse a resolution before
/// reading anything, naming the option and what to use instead; a stride
/// of 0 is refused by every format.
#[test]
fn formats_that_cannot_resample_refuse_a_resolution() {
    let dir = std::path::Path::new("/no/such/scene");
    let sized = selection(1, None, Some((64, 48)));
    for (loader, instead) in [
        (
            LoaderOptions::Blender(BlenderOptions {
                selection: sized,
                ..BlenderOptions::default()
            }),
            "downscale",
        ),
        (
            LoaderOptions::Llff(LlffOptions {
                selection: sized,
                ..LlffOptions::default()
            }),
            "images",
        ),
        (
            LoaderOptions::Colmap(ColmapOptions {
                selection: sized,
                ..ColmapOptions::default()
            }),
            "images_2",
        ),
    ] {
        let format = loader.format().name();
        let err = datasets::load_disk(dir, &loader).err().expect(format);
        assert!(
            matches!(
                &err,
                datasets::DatasetError::Unsupported {
                    option: "resolution",
                    format: f,
                    ..
                } if *f == format
            ),
            "{err:?}"
        );
        let msg = err.to_string();
        assert!(
            msg.contains("resolution") && msg.contains(instead) && msg.contains("/no/such/scene"),
            "{msg}"
        );
    }
    for format in [
        "replica",
        "blender",
        "llff",
        "colmap",
        "scannet",
        "scanner_app",
        "record3d",
        "polycam",
    ] {
        let text = source_text(format, r#"{"stride":0}"#);
        let SceneSource::Disk { loader, .. } = serde_json::from_str(&text).expect("reads") else {
            panic!("{text}");
        };
        let msg = datasets::load_disk(dir, &loader)
            .err()
            .expect(format)
            .to_string();
        assert!(msg.contains("stride must be at least 1"), "{format}: {msg}");
    }
}
