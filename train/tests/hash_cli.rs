//! `--hash-grid` through the real `train` binary: bad values refused with
//! the choices named (and the flag refused with `--resume`), a bad
//! `model.hash` setting refused naming its key, the choice printed with its
//! reason, and the tables saved with the run's configuration and weights
//! and loaded back as `eval` loads a run.

mod common;

use common::{TINY, assert_config_refused, assert_refused, json, s, tiny_run};

#[test]
fn bad_hash_grid_values_are_refused() {
    assert_refused(&["--hash-grid", "maybe"], &["maybe", "auto", "off", "on"]);
    let tmp = tempfile::tempdir().expect("tmp");
    for (name, body, key) in [
        ("levels.json", r#"{"levels": 0}"#, "model.hash.levels"),
        (
            "rows.json",
            r#"{"log2_table": 40}"#,
            "model.hash.log2_table",
        ),
        (
            "resolution.json",
            r#"{"base_resolution": 64, "max_resolution": 8}"#,
            "model.hash.max_resolution",
        ),
        (
            "extent.json",
            r#"{"half_extent": -1.0}"#,
            "model.hash.half_extent",
        ),
    ] {
        let config = format!(r#"{{"model": {{"hash": {body}}}}}"#);
        assert_config_refused(tmp.path(), name, &config, &[key]);
    }
}

#[test]
fn the_choice_is_printed_and_the_tables_saved_and_loaded_with_the_run() {
    let tmp = tempfile::tempdir().expect("tmp");
    let plain = tmp.path().join("plain");
    let err = tiny_run(tmp.path(), &plain, TINY, &[]);
    assert!(
        err.contains("hash grid: none, the IPE alone (auto: a room stood in: not measured"),
        "{err}"
    );
    assert!(json(&plain.join("config.json"))["model"]["hash"].is_null());
    let hashed = tmp.path().join("hashed");
    let err = tiny_run(tmp.path(), &hashed, TINY, &["--hash-grid", "on"]);
    assert!(
        err.contains("hash grid: 16 levels of 2^15 rows x 2 features, 16 to 512 cells across")
            && err.contains("(--hash-grid on)"),
        "{err}"
    );
    let saved = json(&hashed.join("config.json"));
    assert_eq!(saved["model"]["hash"]["levels"], 16);
    let device = burn::tensor::Device::flex();
    let loaded = field_ops::run_dir::load_run(&hashed, &device).expect("the run loads");
    let table = loaded
        .model
        .hash
        .as_ref()
        .expect("tables loaded")
        .table
        .val();
    assert_eq!(table.dims(), [16 << 15, 2]);
    // A configuration's own settings are kept, and `off` overrides it.
    let mut asked: serde_json::Value = serde_json::from_str(TINY).expect("tiny json");
    asked["model"]["hash"] = serde_json::json!({"levels": 3, "log2_table": 8});
    let asked = asked.to_string();
    let by_config = tmp.path().join("by-config");
    let err = tiny_run(tmp.path(), &by_config, &asked, &[]);
    assert!(
        err.contains("hash grid: 3 levels of 2^8 rows")
            && err.contains("auto: the configuration's model.hash"),
        "{err}"
    );
    let off = tmp.path().join("off");
    let err = tiny_run(tmp.path(), &off, &asked, &["--hash-grid", "off"]);
    assert!(
        err.contains("hash grid: none, the IPE alone (--hash-grid off)"),
        "{err}"
    );
    assert!(json(&off.join("config.json"))["model"]["hash"].is_null());
    // A resumed run keeps its configuration: the flag is refused.
    assert_refused(
        &["--resume", s(&hashed), "--hash-grid", "off"],
        &["--hash-grid", "--resume"],
    );
}
