//! `--unseen-depth` and its patches' settings through the real `train`
//! binary: bad values refused naming the flag or key (nothing written), a
//! run with it saves the weight and layout with its configuration, and a
//! resumed run refuses it.

mod common;

use common::{TINY, assert_config_refused, assert_refused, s, train};

#[test]
fn bad_unseen_values_are_refused() {
    for (v, shown) in [("-1", "-1"), ("nan", "NaN"), ("inf", "inf")] {
        assert_refused(&["--unseen-depth", v], &["--unseen-depth", shown, "weight"]);
    }
    assert_refused(&["--unseen-depth", "much"], &["--unseen-depth", "much"]);
    let tmp = tempfile::tempdir().expect("tmp");
    for key in ["unseen_patches", "unseen_patch_side", "unseen_patch_stride"] {
        assert_config_refused(
            tmp.path(),
            &format!("{key}.json"),
            &format!(r#"{{"losses": {{"{key}": 0}}}}"#),
            &[&format!("losses.{key}"), "at least 1"],
        );
    }
}

#[test]
fn a_run_with_unseen_patches_saves_their_settings() {
    let tmp = tempfile::tempdir().expect("tmp");
    let cfg = tmp.path().join("config.json");
    std::fs::write(&cfg, TINY).expect("write config");
    let run = tmp.path().join("run");
    let out = train(&[
        "--config",
        s(&cfg),
        "--iters",
        "2",
        "--quiet",
        "--no-final-render",
        "--unseen-depth",
        "0.5",
        "--out",
        s(&run),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).expect("config"))
            .expect("json");
    let losses = &saved["losses"];
    assert_eq!(losses["unseen_depth_weight"], 0.5);
    assert_eq!(losses["unseen_patches"], 4);
    assert_eq!(losses["unseen_patch_side"], 8);
    assert_eq!(losses["unseen_patch_stride"], 4);
    // A resumed run keeps its configuration: the flag is refused, not ignored.
    assert_refused(
        &["--resume", s(&run), "--unseen-depth", "1"],
        &["--unseen-depth", "--resume"],
    );
}
