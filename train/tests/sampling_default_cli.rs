//! The per-capture sampling default through the `train` binary: an LLFF
//! capture trains with 16 samples per ray and level and the built-in 256
//! rays a batch (and says so) unless `--samples` / `--rays`, a `--config`
//! file or a `--preset` says otherwise, with the hash encoding; a COLMAP
//! capture and other scenes keep the built-in sizes.

use std::path::Path;

mod common;

use common::{s, text, train};

/// The samples per level and rays per batch a run was configured with.
fn sizes(run: &Path) -> (u64, u64) {
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).expect("config"))
            .expect("json");
    (
        c["model"]["num_samples"].as_u64().expect("num_samples"),
        c["sampler"]["rays_per_batch"]
            .as_u64()
            .expect("rays_per_batch"),
    )
}

/// Trains one iteration with `args` into `out`; returns what it printed on
/// stderr.
fn one_iteration(out: &Path, args: &[&str]) -> String {
    let mut all = vec![
        "--iters",
        "1",
        "--no-final-render",
        "--quiet",
        "--out",
        s(out),
    ];
    all.extend_from_slice(args);
    let run = train(&all);
    let (_, err) = text(&run);
    assert!(run.status.success(), "{all:?}: {err}");
    err
}

#[test]
fn an_llff_capture_trains_with_its_sampling_default_unless_told_otherwise() {
    let Some(fern) = datasets::shared_dataset("llff_fern") else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let data = ["--data", s(&fern), "--downscale", "16"];

    let out = dir.path().join("default");
    let err = one_iteration(&out, &data);
    assert_eq!(sizes(&out), (16, 256));
    assert!(
        err.contains(
            "sampling: 16 samples per ray and level, the built-in rays a batch (auto: a \
             forward-facing capture"
        ),
        "{err}"
    );
    assert!(
        err.contains("hash grid: 16 levels of 2^15 rows")
            && err.contains("(auto: a forward-facing capture: the hash encoding lifted"),
        "{err}"
    );

    let out = dir.path().join("flags");
    let err = one_iteration(
        &out,
        &[&data[..], &["--samples", "40", "--rays", "64"]].concat(),
    );
    assert_eq!(sizes(&out), (40, 64));
    // The default is not announced where the flags replaced it.
    assert!(!err.contains("sampling:"), "{err}");

    // A file's keys win over the default; what it leaves out keeps it.
    let file = dir.path().join("samples.json");
    std::fs::write(&file, r#"{"model": {"num_samples": 20}}"#).expect("write");
    let out = dir.path().join("config");
    let err = one_iteration(&out, &[&data[..], &["--config", s(&file)]].concat());
    assert_eq!(sizes(&out), (20, 256));
    assert!(!err.contains("sampling:"), "{err}");

    // A preset sets its own sizes, and the default says nothing.
    let out = dir.path().join("preset");
    let err = one_iteration(&out, &[&data[..], &["--preset", "fast"]].concat());
    assert_eq!(sizes(&out).0, 16);
    assert!(!err.contains("sampling:"), "{err}");
}

#[test]
fn other_scenes_keep_the_built_in_sizes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("synthetic");
    let err = one_iteration(&out, &[]);
    assert_eq!(sizes(&out), (48, 256));
    assert!(!err.contains("sampling:"), "{err}");
}

#[test]
fn a_colmap_capture_trains_with_the_built_in_sizes_unless_told_otherwise() {
    let Some(statue) = datasets::shared_dataset("colmap_statue") else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let data = ["--data", s(&statue)];

    let out = dir.path().join("default");
    let err = one_iteration(&out, &data);
    assert_eq!(sizes(&out), (48, 256));
    assert!(!err.contains("sampling:"), "{err}");

    let out = dir.path().join("flags");
    let err = one_iteration(&out, &[&data[..], &["--rays", "64"]].concat());
    assert_eq!(sizes(&out), (48, 64));
    assert!(!err.contains("sampling:"), "{err}");
}
