//! `scene.json`: sources written before the loader options were typed still
//! read, and today's sources round-trip byte for byte.

use std::path::PathBuf;

use datasets::blender::BlenderOptions;
use datasets::features::PcaSetting;
use datasets::llff::LlffOptions;
use datasets::options::{FeatureInput, FrameSelection};
use datasets::replica::ReplicaOptions;
use datasets::{LoaderOptions, SceneMeta, SceneSource};

fn read(text: &str) -> SceneSource {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

#[test]
fn old_disk_sources_still_read() {
    // As the Replica loader recorded it: every option, PCA as a fit target.
    let replica = read(
        r#"{"kind":"disk","format":"replica","path":"/data/room0","options":{"stride":10,"max_frames":null,"resolution":[640,360],"features":"/data/room0/feats","pca":{"explained_variance":0.99},"seed":0,"box_margin":0.05,"box_pixel_step":8}}"#,
    );
    assert_eq!(
        replica,
        SceneSource::Disk {
            loader: LoaderOptions::Replica(ReplicaOptions {
                selection: FrameSelection {
                    stride: 10,
                    resolution: Some((640, 360)),
                    ..FrameSelection::default()
                },
                feature_input: FeatureInput {
                    features: Some(PathBuf::from("/data/room0/feats")),
                    pca: PcaSetting::ExplainedVariance(0.99),
                    ..FeatureInput::default()
                },
                ..ReplicaOptions::default()
            }),
            path: PathBuf::from("/data/room0"),
        }
    );
    assert_eq!(replica.kind_name(), "replica");
    // `pca: null` (no compression), fields left out, a fixed component count.
    let partial =
        read(r#"{"kind":"disk","format":"replica","path":"/r","options":{"stride":5,"pca":null}}"#);
    let SceneSource::Disk {
        loader: LoaderOptions::Replica(o),
        ..
    } = &partial
    else {
        panic!("{partial:?}");
    };
    assert_eq!(
        (o.selection.stride, o.feature_input.pca, o.box_pixel_step),
        (5, PcaSetting::Off, 8)
    );
    let k = read(
        r#"{"kind":"disk","format":"replica","path":"/r","options":{"pca":{"components":16}}}"#,
    );
    assert!(matches!(
        k,
        SceneSource::Disk {
            loader: LoaderOptions::Replica(ReplicaOptions {
                feature_input: FeatureInput {
                    pca: PcaSetting::Components(16),
                    ..
                },
                ..
            }),
            ..
        }
    ));
    // `options: null` and empty options take every default.
    for options in ["null", "{}"] {
        let text =
            format!(r#"{{"kind":"disk","format":"blender","path":"/b","options":{options}}}"#);
        assert_eq!(
            read(&text),
            SceneSource::Disk {
                loader: LoaderOptions::Blender(BlenderOptions::default()),
                path: PathBuf::from("/b"),
            }
        );
    }
    let llff =
        read(r#"{"kind":"disk","format":"llff","path":"/f","options":{"images":"images_8"}}"#);
    assert_eq!(
        llff,
        SceneSource::Disk {
            loader: LoaderOptions::Llff(LlffOptions {
                images: Some("images_8".into()),
                ..LlffOptions::default()
            }),
            path: PathBuf::from("/f"),
        }
    );
    assert_eq!(llff.kind_name(), "llff");
}

#[test]
fn old_synthetic_sources_still_read() {
    for (text, pca) in [
        (r#"{"kind":"synthetic","seed":3,"size":"ci"}"#, None),
        (
            r#"{"kind":"synthetic","seed":3,"size":"ci","pca":"auto"}"#,
            Some(PcaSetting::Auto),
        ),
        (
            r#"{"kind":"synthetic","seed":3,"size":"ci","pca":"off"}"#,
            Some(PcaSetting::Off),
        ),
        (
            r#"{"kind":"synthetic","seed":3,"size":"ci","pca":{"components":8}}"#,
            Some(PcaSetting::Components(8)),
        ),
    ] {
        let s = read(text);
        assert_eq!(
            s,
            SceneSource::Synthetic {
                seed: 3,
                size: "ci".into(),
                pca
            }
        );
        assert_eq!(s.kind_name(), "synthetic");
        // Unchanged representation: written back as it was read.
        assert_eq!(serde_json::to_string(&s).unwrap(), text);
    }
}

#[test]
fn sources_round_trip_byte_for_byte() {
    let sources = [
        SceneSource::Disk {
            loader: LoaderOptions::Replica(ReplicaOptions {
                selection: FrameSelection {
                    stride: 10,
                    resolution: Some((640, 360)),
                    ..FrameSelection::default()
                },
                feature_input: FeatureInput {
                    features: Some(PathBuf::from("/data/feats")),
                    pca: PcaSetting::Auto,
                    ..FeatureInput::default()
                },
                ..ReplicaOptions::default()
            }),
            path: PathBuf::from("/data/room0"),
        },
        SceneSource::Disk {
            loader: LoaderOptions::Replica(ReplicaOptions {
                feature_input: FeatureInput {
                    pca: PcaSetting::ExplainedVariance(0.9),
                    ..FeatureInput::default()
                },
                ..ReplicaOptions::default()
            }),
            path: PathBuf::from("/r"),
        },
        SceneSource::Disk {
            loader: LoaderOptions::Blender(BlenderOptions {
                downscale: 4,
                ..BlenderOptions::default()
            }),
            path: PathBuf::from("/b"),
        },
        SceneSource::Disk {
            loader: LoaderOptions::Llff(LlffOptions::default()),
            path: PathBuf::from("/f"),
        },
        SceneSource::Synthetic {
            seed: 1,
            size: "bench".into(),
            pca: Some(PcaSetting::Components(12)),
        },
    ];
    for s in sources {
        let text = serde_json::to_string_pretty(&s).unwrap();
        let back = read(&text);
        assert_eq!(back, s);
        assert_eq!(serde_json::to_string_pretty(&back).unwrap(), text);
        // The keys of the old form: kind, format, path, options.
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        if let SceneSource::Disk { loader, .. } = &s {
            assert_eq!(v["kind"], "disk");
            // Serialised with an underscore where the command line has a
            // hyphen (`scanner_app`, `--dataset scanner-app`).
            assert_eq!(v["format"], loader.format().name().replace('-', "_"));
            assert!(v["path"].is_string() && v["options"].is_object(), "{text}");
        }
    }
}

#[test]
fn old_scene_meta_with_a_basis_still_reads() {
    let text = r#"{"source":{"kind":"disk","format":"replica","path":"/r","options":{"features":"/r/f","pca":{"components":1}}},
        "scene_box":{"min":[-1.0,-1.0,-1.0],"max":[1.0,1.0,1.0]},"background":null,
        "pca":{"dim":2,"k":1,"mean":[0.5,0.5],"components":[1.0,0.0],"explained_variance_ratio":0.9},
        "feature_dim":2}"#;
    let meta: SceneMeta = serde_json::from_str(text).expect("old scene.json");
    let basis = meta.pca.clone().expect("basis");
    assert_eq!((basis.dim, basis.k), (2, 1));
    let again: SceneMeta = serde_json::from_str(&serde_json::to_string(&meta).unwrap()).unwrap();
    assert_eq!(again.pca, Some(basis));
}
