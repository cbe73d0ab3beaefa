//! `--field-model` through the real `train` binary: bad values refused
//! with the choices named, flags that size the other field or add a second
//! grid refused, bad `model.fast` settings refused naming their key, the
//! choice printed with its reason, the field saved with the run and loaded
//! back as `eval` loads a run, and the flag refused with `--resume`.

mod common;

use common::{TINY, assert_config_refused, assert_refused, json, s, tiny_run, train};

#[test]
fn bad_field_model_values_and_settings_are_refused() {
    assert_refused(
        &["--field-model", "nerfacto"],
        &["nerfacto", "auto", "mip", "fast"],
    );
    assert_refused(
        &["--field-model", "fast", "--width", "64"],
        &["--width", "model.fast"],
    );
    assert_refused(
        &["--field-model", "fast", "--depth", "2"],
        &["--depth", "model.fast"],
    );
    assert_refused(
        &["--field-model", "fast", "--hash-grid", "on"],
        &["--hash-grid on", "model.fast.grid"],
    );
    let tmp = tempfile::tempdir().expect("tmp");
    for (name, body, key) in [
        (
            "levels.json",
            r#"{"grid": {"levels": 0}}"#,
            "model.fast.grid.levels",
        ),
        (
            "rows.json",
            r#"{"grid": {"log2_table": 30}}"#,
            "model.fast.grid.log2_table",
        ),
        (
            "geo.json",
            r#"{"geo_features": 0}"#,
            "model.fast.geo_features",
        ),
        ("sh.json", r#"{"sh_degree": 9}"#, "model.fast.sh_degree"),
        (
            "shift.json",
            r#"{"density_shift": -100}"#,
            "model.fast.density_shift",
        ),
        (
            "feature.json",
            r#"{"feature_grid": {"levels": 0}}"#,
            "model.fast.feature_grid.levels",
        ),
        (
            "feature_rows.json",
            r#"{"feature_grid": {"log2_table": 40}}"#,
            "model.fast.feature_grid.log2_table",
        ),
        (
            "alone.json",
            r#"{"head_reads_geometry": false}"#,
            "model.fast.head_reads_geometry",
        ),
        (
            "ramp.json",
            r#"{"coarse_to_fine": 1.5}"#,
            "model.fast.coarse_to_fine",
        ),
        (
            "ramp_negative.json",
            r#"{"coarse_to_fine": -0.1}"#,
            "model.fast.coarse_to_fine",
        ),
        (
            "word.json",
            r#"{"color_width": "wide"}"#,
            "\"wide\", expected usize",
        ),
    ] {
        let config = format!(r#"{{"model": {{"fast": {body}}}}}"#);
        assert_config_refused(tmp.path(), name, &config, &[key]);
    }
    let config = r#"{"model": {"proposal": {"hash": {"levels": 0}}}}"#;
    assert_config_refused(
        tmp.path(),
        "proposal.json",
        config,
        &["model.proposal.hash.levels"],
    );
}

#[test]
fn the_choice_is_printed_and_the_field_saved_and_loaded_with_the_run() {
    let tmp = tempfile::tempdir().expect("tmp");
    let plain = tmp.path().join("plain");
    let err = tiny_run(tmp.path(), &plain, TINY, &[]);
    assert!(
        err.contains(
            "field model: mip, the Mip-NeRF MLP of 2 x 16 (auto: a room stood in: the paper's field"
        ),
        "{err}"
    );
    assert!(json(&plain.join("config.json"))["model"]["fast"].is_null());

    let fast = tmp.path().join("fast");
    let err = tiny_run(
        tmp.path(),
        &fast,
        TINY,
        &["--field-model", "fast", "--sampler", "proposal"],
    );
    assert!(
        err.contains("field model: fast, a hash grid of 16 levels of 2^15 rows x 2 features")
            && err.contains("a density MLP of 1 x 64 (density exp(raw - 1))")
            && err.contains("(--field-model fast)"),
        "{err}"
    );
    assert!(!err.contains("hash grid: none"), "{err}");
    // A room's rounds are the fast field's 64 and 32.
    assert!(
        err.contains("proposal rounds: 64 and 32 samples (auto: a room stood in:"),
        "{err}"
    );
    let saved = json(&fast.join("config.json"));
    assert_eq!(
        saved["model"]["proposal"]["samples"],
        serde_json::json!([64, 32])
    );
    assert_eq!(saved["model"]["fast"]["grid"]["log2_table"], 15);
    assert_eq!(saved["model"]["proposal"]["hash"]["levels"], 5);
    // The density shifts `train` builds are saved, so that eval renders
    // the field as it was trained.
    assert_eq!(saved["model"]["fast"]["density_shift"], -1.0);
    assert_eq!(saved["model"]["proposal"]["density_shift"], -1.0);
    let device = burn::tensor::Device::flex();
    let loaded = field_ops::run_dir::load_run(&fast, &device).expect("the run loads");
    assert!(loaded.model.mlp.is_none());
    let field = loaded.model.fast.as_ref().expect("the fast field");
    assert_eq!(field.grid.table.val().dims(), [16 << 15, 2]);
    let proposal = loaded
        .model
        .proposal
        .as_ref()
        .expect("the proposal network");
    assert!(proposal.hash.is_some());
    assert_eq!((field.density_shift, proposal.density_shift), (-1.0, -1.0));

    // A file that gives some of the proposal sampler's keys changes only
    // those: the fast field keeps its hash-grid proposal networks, and the
    // Mip-NeRF field its proposal MLP.
    let mut rounds: serde_json::Value = serde_json::from_str(TINY).expect("tiny json");
    rounds["model"]["proposal"] = serde_json::json!({"samples": [12, 6]});
    let rounds = rounds.to_string();
    for (name, flags, hash, width) in [
        ("fast-rounds", &["--field-model", "fast"][..], true, 16),
        ("mip-rounds", &["--field-model", "mip"][..], false, 64),
    ] {
        let run = tmp.path().join(name);
        let err = tiny_run(tmp.path(), &run, &rounds, flags);
        assert!(err.contains("sampler: proposal"), "{name}: {err}");
        assert!(
            err.contains(
                "proposal rounds: 12 and 6 samples (auto: the configuration's \
                 model.proposal.samples)"
            ),
            "{name}: {err}"
        );
        let proposal = &json(&run.join("config.json"))["model"]["proposal"];
        assert_eq!(proposal["samples"], serde_json::json!([12, 6]), "{name}");
        assert_eq!(proposal["hash"].is_object(), hash, "{name}: {proposal}");
        assert_eq!(proposal["width"], width, "{name}: {proposal}");
    }

    // A configuration's own sizes are kept, and `mip` overrides it.
    let mut asked: serde_json::Value = serde_json::from_str(TINY).expect("tiny json");
    asked["model"]["fast"] = serde_json::json!({"grid": {"levels": 3, "log2_table": 8}});
    let mut asked = asked.to_string();
    let by_config = tmp.path().join("by-config");
    let err = tiny_run(tmp.path(), &by_config, &asked, &[]);
    assert!(
        err.contains("field model: fast, a hash grid of 3 levels of 2^8 rows")
            && err.contains("auto: the configuration's model.fast"),
        "{err}"
    );
    assert!(!err.contains("a hash grid of its own"), "{err}");

    // A feature grid given by some of its keys takes the others from the
    // fast field's feature grid, is printed, saved and loaded.
    asked = {
        let mut a: serde_json::Value = serde_json::from_str(&asked).expect("json");
        a["model"]["fast"]["feature_grid"] = serde_json::json!({"levels": 2, "log2_table": 8});
        a.to_string()
    };
    let featured = tmp.path().join("featured");
    let err = tiny_run(tmp.path(), &featured, &asked, &[]);
    assert!(
        err.contains(
            "the open-set head reads a hash grid of its own, 2 levels of 2^8 rows x 2 features \
             (16 to 512 cells across)"
        ),
        "{err}"
    );
    let saved = json(&featured.join("config.json"));
    assert_eq!(saved["model"]["fast"]["feature_grid"]["levels"], 2);
    let loaded = field_ops::run_dir::load_run(&featured, &device).expect("the run loads");
    let field = loaded.model.fast.as_ref().expect("the fast field");
    let grid = field.feature_grid.as_ref().expect("the feature grid");
    assert_eq!(grid.table.val().dims(), [2 << 8, 2]);
    assert_eq!(loaded.model.head.hidden[0].weight.dims()[0], 15 + 4);

    // The head reading the feature grid alone is printed, saved and loaded.
    let alone = {
        let mut a: serde_json::Value = serde_json::from_str(&asked).expect("json");
        a["model"]["fast"]["head_reads_geometry"] = serde_json::json!(false);
        a.to_string()
    };
    let grid_alone = tmp.path().join("grid_alone");
    let err = tiny_run(tmp.path(), &grid_alone, &alone, &[]);
    assert!(
        err.contains("a hash grid of its own (and not the geometry feature), 2 levels"),
        "{err}"
    );
    let saved = json(&grid_alone.join("config.json"));
    assert_eq!(saved["model"]["fast"]["head_reads_geometry"], false);
    let loaded = field_ops::run_dir::load_run(&grid_alone, &device).expect("the run loads");
    assert_eq!(loaded.model.head.hidden[0].weight.dims()[0], 4);
    let mip = tmp.path().join("mip");
    let err = tiny_run(tmp.path(), &mip, &asked, &["--field-model", "mip"]);
    assert!(
        err.contains("field model: mip") && err.contains("(--field-model mip)"),
        "{err}"
    );
    assert!(json(&mip.join("config.json"))["model"]["fast"].is_null());

    // A resumed run keeps its configuration: these flags are refused.
    for flag in [
        &["--field-model", "mip"][..],
        &["--field", "box"],
        &["--sampler", "coarse-fine"],
        &["--appearance", "none"],
    ] {
        let args = [&["--resume", s(&fast)][..], flag].concat();
        assert_refused(&args, &[flag[0], "--resume"]);
    }
    // And the run resumes as it was trained.
    let out = train(&["--resume", s(&fast), "--iters", "3", "--quiet"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
