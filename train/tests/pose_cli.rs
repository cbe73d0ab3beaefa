//! `--pose-refine` through the real `train` binary: bad values refused
//! with the choices named (and the flag refused with `--resume`), the
//! choice printed with its reason, the learned corrections saved with the
//! run's configuration and weights (one per frame of the scene, held-out
//! frames left at zero) and loaded back as `eval` loads a run.

mod common;

use common::{TINY, assert_config_refused, assert_refused, json, s, tiny_run};

#[test]
fn bad_pose_refine_values_are_refused() {
    assert_refused(&["--pose-refine", "maybe"], &["maybe", "off", "on"]);
    let tmp = tempfile::tempdir().expect("tmp");
    assert_config_refused(
        tmp.path(),
        "penalty.json",
        r#"{"losses": {"pose_penalty": -1.0}}"#,
        &["losses.pose_penalty", "-1"],
    );
    assert_config_refused(
        tmp.path(),
        "rate.json",
        r#"{"optimiser": {"pose_lr_scale": 0.0}}"#,
        &["optimiser.pose_lr_scale", "0"],
    );
}

#[test]
fn the_choice_is_printed_and_the_corrections_saved_and_loaded_with_the_run() {
    let tmp = tempfile::tempdir().expect("tmp");
    let plain = tmp.path().join("plain");
    let err = tiny_run(tmp.path(), &plain, TINY, &[]);
    assert!(err.contains("camera poses: as given (auto:"), "{err}");
    assert!(json(&plain.join("config.json"))["model"]["pose"].is_null());
    let refined = tmp.path().join("refined");
    let err = tiny_run(tmp.path(), &refined, TINY, &["--pose-refine", "on"]);
    assert!(
        err.contains("camera poses: refined with the field") && err.contains("(--pose-refine on)"),
        "{err}"
    );
    let split = json(&refined.join("split.json"));
    let ids = |k: &str| -> Vec<usize> {
        split[k]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|v| v.as_u64())
                    .map(|v| v as usize)
                    .collect()
            })
            .unwrap_or_default()
    };
    let (trained, heldout) = (ids("train"), ids("heldout"));
    let frames = trained.len() + heldout.len();
    assert!(!trained.is_empty() && !heldout.is_empty(), "{split}");
    assert_eq!(
        json(&refined.join("config.json"))["model"]["pose"]["images"],
        frames
    );
    // Loaded as `eval` loads a run: the corrections are among the weights;
    // some training photograph's moved in two steps, no held-out one did.
    let device = burn::tensor::Device::flex();
    let loaded = field_ops::run_dir::load_run(&refined, &device).expect("the run loads");
    let table: Vec<f32> = loaded
        .model
        .pose
        .as_ref()
        .expect("corrections loaded")
        .params
        .val()
        .try_into_vec_as::<f32>()
        .expect("f32");
    assert_eq!(table.len(), 6 * frames);
    let row = |f: usize| &table[6 * f..6 * f + 6];
    assert!(trained.iter().any(|&f| row(f).iter().any(|&v| v != 0.0)));
    assert!(heldout.iter().all(|&f| row(f).iter().all(|&v| v == 0.0)));
    // `--pose-refine off` overrides a configuration that asks for it.
    let mut asked: serde_json::Value = serde_json::from_str(TINY).expect("tiny json");
    asked["model"]["pose"] = serde_json::json!({"images": 2});
    let asked = asked.to_string();
    let by_config = tmp.path().join("by-config");
    let err = tiny_run(tmp.path(), &by_config, &asked, &[]);
    assert!(
        err.contains("auto: the configuration's model.pose"),
        "{err}"
    );
    assert_eq!(
        json(&by_config.join("config.json"))["model"]["pose"]["images"],
        frames
    );
    let off = tmp.path().join("off");
    let err = tiny_run(tmp.path(), &off, &asked, &["--pose-refine", "off"]);
    assert!(
        err.contains("camera poses: as given (--pose-refine off)"),
        "{err}"
    );
    // A resumed run keeps its configuration: the flag is refused.
    assert_refused(
        &["--resume", s(&refined), "--pose-refine", "off"],
        &["--pose-refine", "--resume"],
    );
}
