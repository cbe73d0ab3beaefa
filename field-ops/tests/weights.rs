//! A loaded run owns its weights: the file can be replaced or removed (a
//! resumed training renames a new `model.bpk` over it) without changing what
//! the loaded field renders.

use burn::module::Module;
use burn::tensor::Device;
use field_ops::error::OpsError;
use field_ops::run_dir::load_weights;
use model::geometry::NormalizedRay;
use model::{FeatureHeadConfig, MipMlpConfig, OpenNerf, OpenNerfConfig, RenderRequest};

fn config() -> OpenNerfConfig {
    OpenNerfConfig::new(FeatureHeadConfig::new(4).with_width(8))
        .with_mlp(
            MipMlpConfig::new()
                .with_width(16)
                .with_depth(2)
                .with_skip_layer(1)
                .with_max_deg(4),
        )
        .with_num_samples(8)
}

fn render(field: &OpenNerf) -> Vec<f32> {
    let rays: Vec<NormalizedRay> = (0..3)
        .map(|i| NormalizedRay {
            origin: [0.3 * i as f32 - 0.3, 0.1, -2.5],
            direction: [0.0, 0.0, 1.0],
            radius: 0.002,
            near: 0.5,
            far: 4.5,
        })
        .collect();
    let out = field
        .render(&RenderRequest::inference(&rays))
        .expect("never cancelled without an observer");
    out.rgb.into_iter().chain(out.depth).collect()
}

#[test]
fn loaded_weights_do_not_follow_the_file_after_loading() {
    let device = Device::flex();
    let dir = std::env::temp_dir().join(format!("opennerf-weights-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("model.bpk");

    device.seed(11);
    let trained = config().init(&device);
    trained.clone().save_file(&path).expect("save");
    let expected = render(&trained);

    device.seed(12);
    let loaded = load_weights(config().init(&device), &path).expect("load");
    // Another run's weights take the file's place, then the file goes.
    device.seed(13);
    let other = config().init(&device);
    other.clone().save_file(&path).expect("overwrite");
    assert_ne!(render(&other), expected, "the two fields differ");
    assert_eq!(render(&loaded), expected);
    std::fs::remove_file(&path).expect("remove");
    assert_eq!(render(&loaded), expected);

    let missing = load_weights(config().init(&device), &path).unwrap_err();
    assert!(matches!(missing, OpsError::Io { .. }), "{missing}");
    std::fs::write(&path, b"not a burnpack").expect("write");
    let damaged = load_weights(config().init(&device), &path).unwrap_err();
    assert!(
        matches!(&damaged, OpsError::Weights { path: p, .. } if p == &path),
        "{damaged}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
