//! `--appearance` through the real `train` binary: bad values refused with
//! the choices named, the choice printed with its reason, the learned
//! exposure saved with the run's configuration and weights (one correction
//! per frame of the scene) and loaded back as `eval` loads a run.

use std::path::Path;

mod common;

use common::{TINY, assert_config_refused, assert_refused, tiny_run};

fn saved_exposure(run: &Path) -> serde_json::Value {
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).expect("config"))
            .expect("json");
    saved["model"]["exposure"].clone()
}

#[test]
fn bad_appearance_values_are_refused() {
    assert_refused(
        &["--appearance", "grey"],
        &["grey", "none", "exposure", "embedding"],
    );
    let tmp = tempfile::tempdir().expect("tmp");
    assert_config_refused(
        tmp.path(),
        "bad.json",
        r#"{"losses": {"exposure_penalty": -1.0}}"#,
        &["losses.exposure_penalty", "-1"],
    );
    assert_config_refused(
        tmp.path(),
        "dim.json",
        r#"{"model": {"appearance": {"dim": 0}}}"#,
        &["model.appearance.dim", "0"],
    );
}

#[test]
fn the_choice_is_printed_and_the_exposure_saved_and_loaded_with_the_run() {
    let tmp = tempfile::tempdir().expect("tmp");
    // Auto on the synthetic room: none, and the configuration says so.
    let plain = tmp.path().join("plain");
    let err = tiny_run(tmp.path(), &plain, TINY, &[]);
    assert!(
        err.contains("appearance: none (auto: a room stood in"),
        "{err}"
    );
    assert!(saved_exposure(&plain).is_null());
    // Asked for: one correction per frame of the scene.
    let exposed = tmp.path().join("exposed");
    let err = tiny_run(tmp.path(), &exposed, TINY, &["--appearance", "exposure"]);
    assert!(
        err.contains("appearance: a learned exposure per photograph (--appearance exposure)"),
        "{err}"
    );
    let scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(exposed.join("split.json")).expect("split"))
            .expect("json");
    let frames = scene["train"].as_array().map_or(0, Vec::len)
        + scene["heldout"].as_array().map_or(0, Vec::len);
    assert!(frames > 0, "{scene}");
    assert_eq!(saved_exposure(&exposed)["images"], frames);
    // Loaded as `eval` loads a run: the corrections are among the weights,
    // and they moved from zero in two steps.
    let device = burn::tensor::Device::flex();
    let loaded = field_ops::run_dir::load_run(&exposed, &device).expect("the run loads");
    let table: Vec<f32> = loaded
        .model
        .exposure
        .as_ref()
        .expect("exposure loaded")
        .params
        .val()
        .try_into_vec_as::<f32>()
        .expect("f32");
    assert_eq!(table.len(), 6 * frames);
    assert!(table.iter().any(|&v| v != 0.0), "{table:?}");
    // A configuration that sets model.exposure chooses it under auto (its
    // count of photographs is the scene's); --appearance none overrides it.
    let asked = r#"{"model": {"mlp": {"width": 16, "depth": 2, "skip_layer": 1, "max_deg": 4},
        "num_samples": 4, "head": {"width": 8, "layers": 1}, "exposure": {"images": 3}},
        "sampler": {"rays_per_batch": 32, "border_margin": 2},
        "logging": {"checkpoint_every": 2, "eval_every": 0, "eval_pixels": 64}}"#;
    let by_config = tmp.path().join("by-config");
    let err = tiny_run(tmp.path(), &by_config, asked, &[]);
    assert!(
        err.contains("auto: the configuration's model.exposure"),
        "{err}"
    );
    assert_eq!(saved_exposure(&by_config)["images"], frames);
    let overridden = tmp.path().join("overridden");
    let err = tiny_run(tmp.path(), &overridden, asked, &["--appearance", "none"]);
    assert!(
        err.contains("appearance: none (--appearance none)"),
        "{err}"
    );
    assert!(saved_exposure(&overridden).is_null());
    // Appearance codes: one per frame of the scene, of the default length,
    // loaded with the run; a training photograph's code moved in two steps.
    let coded = tmp.path().join("coded");
    let err = tiny_run(tmp.path(), &coded, TINY, &["--appearance", "embedding"]);
    assert!(
        err.contains("appearance: a learned appearance code per photograph")
            && err.contains("(--appearance embedding)"),
        "{err}"
    );
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(coded.join("config.json")).expect("config"))
            .expect("json");
    assert!(saved["model"]["exposure"].is_null());
    assert_eq!(saved["model"]["appearance"]["images"], frames);
    assert_eq!(saved["model"]["appearance"]["dim"], 16);
    let loaded = field_ops::run_dir::load_run(&coded, &device).expect("the run loads");
    assert_eq!(loaded.model.radiance().appearance_dim(), 16);
    let codes: Vec<f32> = loaded
        .model
        .appearance
        .as_ref()
        .expect("codes loaded")
        .codes
        .val()
        .try_into_vec_as::<f32>()
        .expect("f32");
    assert_eq!(codes.len(), 16 * frames);
    assert!(codes.iter().any(|&v| v != 0.0));
}
