//! `eval query --text` and `eval segment --classes` with `--text-model`:
//! the flags' help, clear errors for bad inputs (never a panic), and free
//! text embedded, cached in the run directory and queried.
//!
//! The text model is made here: a randomly initialised tiny CLIP text
//! encoder saved in Hugging Face layout, with the tokenizer fixture of the
//! `clip` crate (a part of the real CLIP vocabulary).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use burn::tensor::Device;
use clip::ClipTextConfig;
use datasets::SceneMeta;

/// An untrained tiny field on the synthetic CI scene (as in `cli.rs`).
fn run_dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        common::write_tiny_run(dir.path());
        dir
    })
    .path()
}

fn feature_dim() -> usize {
    let text = std::fs::read_to_string(run_dir().join("scene.json")).expect("scene.json");
    let meta: SceneMeta = serde_json::from_str(&text).expect("meta");
    meta.feature_dim.expect("feature dim")
}

fn copy_run(to: &Path) -> PathBuf {
    let dst = to.join("run");
    std::fs::create_dir_all(&dst).expect("mkdir");
    for name in ["model.bpk", "config.json", "scene.json", "split.json"] {
        std::fs::copy(run_dir().join(name), dst.join(name)).expect("copy");
    }
    dst
}

/// A tiny CLIP text model directory embedding into `embed_dim` dimensions.
fn text_model(dir: &Path, embed_dim: usize) -> PathBuf {
    let config = ClipTextConfig::new()
        .with_width(8)
        .with_layers(1)
        .with_heads(2)
        .with_mlp_width(16)
        .with_embed_dim(embed_dim);
    let device = Device::flex();
    device.seed(7);
    let enc = config.init(&device);
    let out = dir.join(format!("clip{embed_dim}"));
    clip::export::save_hf_model(&enc, &config, &out).expect("save text model");
    let vocab = Path::new(env!("CARGO_MANIFEST_DIR")).join("../clip/tests/fixtures/tokenizer");
    for name in ["vocab.json", "merges.txt"] {
        std::fs::copy(vocab.join(name), out.join(name)).expect("copy tokenizer");
    }
    out
}

fn eval(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(args)
        .output()
        .expect("the eval binary runs")
}

fn assert_refused(args: &[&str], words: &[&str]) {
    let out = eval(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    for w in words {
        assert!(err.contains(w), "{args:?}: {w:?} not in {err:?}");
    }
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn help_explains_the_new_flags() {
    for (cmd, flags) in [
        ("query", &["--text <TEXT>", "--text-model <DIR>"]),
        ("segment", &["--classes <CLASSES>", "--text-model <DIR>"]),
    ] {
        let out = eval(&[cmd, "--help"]);
        let help = String::from_utf8_lossy(&out.stdout);
        for f in flags {
            assert!(help.contains(f), "{cmd}: {f} not in {help}");
        }
        assert!(help.contains("CLIP text model directory"), "{help}");
        assert!(help.contains("vocab.json"), "{help}");
    }
}

#[test]
fn bad_text_inputs_are_refused_by_flag_or_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = s(run_dir());
    let model = text_model(tmp.path(), feature_dim());
    let m = s(&model);
    // Flags that need each other.
    assert_refused(
        &["query", "--run", &run, "--text", "chair"],
        &["--text-model"],
    );
    assert_refused(
        &["segment", "--run", &run, "--classes", "a,b"],
        &["--text-model"],
    );
    // A missing directory, blank text, an empty class.
    assert_refused(
        &[
            "query",
            "--run",
            &run,
            "--text",
            "chair",
            "--text-model",
            "/nonexistent/clip",
        ],
        &["--text-model /nonexistent/clip", "not a directory"],
    );
    assert_refused(
        &["query", "--run", &run, "--text", "  ", "--text-model", &m],
        &["--text", "empty text"],
    );
    assert_refused(
        &[
            "segment",
            "--run",
            &run,
            "--classes",
            "chair,,sofa",
            "--text-model",
            &m,
        ],
        &["--classes", "class 2 is empty"],
    );
    // A directory without weights names the file looked for.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    assert_refused(
        &[
            "query",
            "--run",
            &run,
            "--text",
            "chair",
            "--text-model",
            &s(&empty),
        ],
        &["--text-model", "model.safetensors", "missing"],
    );
}

#[test]
fn missing_or_misshapen_tensors_name_the_file_and_the_tensor() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = s(run_dir());
    let model = text_model(tmp.path(), feature_dim());
    let weights = model.join("model.safetensors");
    let device = Device::flex();
    let loaded = clip::model_dir::load_encoder(&model, &device).expect("loads");
    let tensors = clip::export::hf_tensors(&loaded.encoder, &weights).expect("tensors");

    let mut missing = tensors.clone();
    missing.remove("text_model.final_layer_norm.bias");
    clip::tensors::write_f32(&weights, &missing).expect("write");
    assert_refused(
        &[
            "query",
            "--run",
            &run,
            "--text",
            "chair",
            "--text-model",
            &s(&model),
        ],
        &["model.safetensors", "text_model.final_layer_norm.bias"],
    );

    let mut misshapen = tensors;
    let q = "text_model.encoder.layers.0.self_attn.q_proj.weight";
    let t = misshapen.get_mut(q).expect("q_proj");
    t.shape = vec![4, 16];
    clip::tensors::write_f32(&weights, &misshapen).expect("write");
    assert_refused(
        &[
            "query",
            "--run",
            &run,
            "--text",
            "chair",
            "--text-model",
            &s(&model),
        ],
        &["model.safetensors", q, "[4, 16]", "[8, 8]"],
    );
}

#[test]
fn a_text_model_of_another_dimension_is_refused() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = copy_run(tmp.path());
    let d = feature_dim();
    let model = text_model(tmp.path(), d + 3);
    assert_refused(
        &[
            "query",
            "--run",
            &s(&run),
            "--text",
            "chair",
            "--text-model",
            &s(&model),
        ],
        &[
            "--text-model",
            &format!("embeds in {} dimensions", d + 3),
            &format!("features have {d}"),
        ],
    );
}

#[test]
fn free_text_query_and_classes_run_and_are_cached() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = copy_run(tmp.path());
    let model = text_model(tmp.path(), feature_dim());
    let out = tmp.path().join("q");
    let args = [
        "query",
        "--run",
        &s(&run),
        "--text",
        "something to sit on",
        "--text-model",
        &s(&model),
        "--cameras",
        "all",
        "--max-views",
        "1",
        "--out",
        &s(&out),
    ];
    let r = eval(&args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("embedded 1 text(s)"), "{err}");
    let written: Vec<PathBuf> = std::fs::read_dir(&out)
        .expect("out")
        .map(|e| e.expect("entry").path())
        .collect();
    assert!(
        written
            .iter()
            .any(|p| s(p).ends_with("something_to_sit_on_relevancy.png")),
        "{written:?}"
    );
    let cache = run.join(clip::cache::CACHE_FILE);
    let text = std::fs::read_to_string(&cache).expect("cache written");
    let c: clip::cache::EmbeddingCache = serde_json::from_str(&text).expect("cache JSON");
    assert_eq!(c.entries.len(), 1);
    let norm: f32 = c.entries[0]
        .embedding
        .iter()
        .map(|x| x * x)
        .sum::<f32>()
        .sqrt();
    assert!((norm - 1.0).abs() < 1e-5, "{norm}");
    // The second run takes the embedding from the cache.
    let r = eval(&args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(!err.contains("embedded"), "{err}");

    let seg = tmp.path().join("seg");
    let r = eval(&[
        "segment",
        "--run",
        &s(&run),
        "--classes",
        "sofa, wall, something to sit on",
        "--text-model",
        &s(&model),
        "--max-views",
        "2",
        "--render-scale",
        "0.5",
        "--out",
        &s(&seg),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(seg.join("segmentation.json").exists());
    assert!(
        err.contains("not scored: [\"something to sit on\"]"),
        "{err}"
    );
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(seg.join("segmentation.json")).expect("json"),
    )
    .expect("parse");
    let classes = json["per_class"].as_array().expect("per-class scores");
    assert_eq!(classes.len(), 2, "{json}");
}
