//! `losses.depth_cap` through the real `train` binary: values below 1 or
//! not finite refused naming the key and the file, one that is no number
//! refused naming the file and the value, the default saved with a run
//! that leaves the key out, a given cap saved with the run.

use std::path::Path;

mod common;

use common::{TINY, assert_config_refused, json, tiny_run};

fn saved_cap(run: &Path) -> serde_json::Value {
    json(&run.join("config.json"))["losses"]["depth_cap"].clone()
}

#[test]
fn bad_depth_caps_are_refused_and_a_given_cap_is_saved() {
    let tmp = tempfile::tempdir().expect("tmp");
    for (name, value, shown) in [
        ("below-one.json", "0.5", "0.5"),
        ("negative.json", "-2", "-2"),
        ("too-large.json", "1e40", "inf"),
    ] {
        assert_config_refused(
            tmp.path(),
            name,
            &format!(r#"{{"losses": {{"depth_cap": {value}}}}}"#),
            &["losses.depth_cap", "at least 1", shown],
        );
    }
    assert_config_refused(
        tmp.path(),
        "text.json",
        r#"{"losses": {"depth_cap": "far"}}"#,
        &["invalid JSON", "\"far\"", "f32"],
    );

    let plain = tmp.path().join("plain");
    tiny_run(tmp.path(), &plain, TINY, &[]);
    assert_eq!(saved_cap(&plain), serde_json::json!(2.0));

    let mut config: serde_json::Value = serde_json::from_str(TINY).expect("tiny json");
    config["losses"]["depth_cap"] = serde_json::json!(10.0);
    let capped = tmp.path().join("capped");
    tiny_run(tmp.path(), &capped, &config.to_string(), &[]);
    assert_eq!(saved_cap(&capped), serde_json::json!(10.0));
}
