//! `train --vlm` end to end on the CI scene with a tiny random CLIP model
//! (both towers) written by the test: the maps are made in process and
//! cached, reused by a second run and on resume, novel views are extracted
//! in process, and `eval segment --classes` / `eval query --text` use the
//! run's own model with no `--text-model`. Bad input is refused before
//! anything is written.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use clap::Parser;
use clip::vision::export::save_hf_clip_model;
use clip::{ClipTextConfig, ClipVisionConfig};
use datasets::{SceneMeta, SceneSource};
use eval::commands::query::{QueryArgs, query_command};
use eval::commands::segment::{SegmentArgs, segment_command};
use tests::{scratch_dir, serial};
use train::cli::Cli;

/// A tiny random CLIP model directory embedding into `dim` dimensions.
fn tiny_clip(dir: &Path, dim: usize) -> PathBuf {
    let device = Device::flex();
    device.seed(11);
    let text_config = ClipTextConfig::new()
        .with_width(8)
        .with_layers(1)
        .with_heads(2)
        .with_mlp_width(16)
        .with_embed_dim(dim);
    let vision_config = ClipVisionConfig::new()
        .with_image_size(32)
        .with_patch_size(8)
        .with_width(16)
        .with_layers(2)
        .with_heads(2)
        .with_mlp_width(32)
        .with_embed_dim(dim);
    let out = dir.join(format!("clip{dim}"));
    save_hf_clip_model(
        &text_config.init(&device),
        &text_config,
        &vision_config.init(&device),
        &vision_config,
        &out,
    )
    .expect("save the model");
    let vocab = Path::new(env!("CARGO_MANIFEST_DIR")).join("../clip/tests/fixtures/tokenizer");
    for name in ["vocab.json", "merges.txt"] {
        std::fs::copy(vocab.join(name), out.join(name)).expect("copy tokenizer");
    }
    out
}

/// The tests' serial guard, a scratch directory and a 12-d tiny CLIP model in it.
fn setup() -> (
    std::sync::MutexGuard<'static, ()>,
    tempfile::TempDir,
    PathBuf,
) {
    let guard = serial();
    let tmp = scratch_dir();
    let model = tiny_clip(tmp.path(), 12);
    (guard, tmp, model)
}

fn train(args: &[&str]) -> Result<train::RunOutcome, String> {
    let mut all = vec!["train", "--quiet", "--no-final-render"];
    all.extend_from_slice(args);
    let cli = Cli::try_parse_from(&all).map_err(|e| e.to_string())?;
    train::run_cli(&cli, &train::interrupt::StopFlag::new()).map_err(|e| e.to_string())
}

#[derive(Parser)]
struct Segment {
    #[command(flatten)]
    args: SegmentArgs,
}

#[derive(Parser)]
struct Query {
    #[command(flatten)]
    args: QueryArgs,
}

fn mtimes(dir: &Path) -> Vec<(String, std::time::SystemTime)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("features dir")
        .filter_map(Result::ok)
        .filter(|e| e.path().extension().is_some_and(|x| x == "npy"))
        // Class embeddings are re-embedded by every run (cheap); the maps are not.
        .filter(|e| e.file_name() != "classes.npy")
        .map(|e| {
            let m = e.metadata().and_then(|m| m.modified()).expect("mtime");
            (e.file_name().to_string_lossy().into_owned(), m)
        })
        .collect();
    v.sort();
    v
}

#[test]
fn train_with_a_clip_model_then_query_and_segment_with_its_text_tower() {
    let (_guard, tmp, model) = setup();
    let m = model.to_str().expect("utf-8");
    let run = tmp.path().join("run");
    let r = run.to_str().expect("utf-8");
    let out = train(&[
        "--vlm",
        m,
        "--short-side",
        "32",
        "--dense",
        "clearclip",
        "--out",
        r,
        "--iters",
        "40",
        "--stop-at",
        "30",
        "--novel-views",
        "2",
        "--novel-after",
        "20",
        "--pca",
        "off",
    ])
    .expect("train --vlm");
    assert_eq!(out.summary.iterations, 30);
    // The maps: one per frame at the patch grid (54 x 96 at short side 32:
    // 32 x 56 pixels, 4 x 7 patches), 12 channels, and the stamp.
    let features = run.join("features");
    let maps = mtimes(&features);
    assert_eq!(maps.len(), 20, "{maps:?}");
    assert!(features.join("classes.npy").is_file());
    let info = datasets::npy::NpyInfo::open(&features.join(&maps[0].0)).expect("npy");
    assert_eq!(info.shape, vec![4, 7, 12]);
    assert!(features.join(field_ops::vlm_maps::STAMP).is_file());
    let meta: SceneMeta =
        serde_json::from_str(&std::fs::read_to_string(run.join("scene.json")).expect("scene.json"))
            .expect("meta");
    assert_eq!(meta.feature_dim, Some(12));
    let vlm = meta.source.vlm().expect("the run records its model");
    assert_eq!(vlm.dense, clip::DenseVariant::Clearclip);
    assert_eq!(vlm.short_side, 32);
    assert!(matches!(meta.source.base(), SceneSource::Synthetic { .. }));
    // The novel views were read by the model in process (no command given).
    let record = datasets::novel_record::read_record(&run.join("novel"))
        .expect("record")
        .expect("views.json");
    assert_eq!(record.views.len(), 2);

    // Resume reads the cached maps: none is rewritten.
    let resumed = train(&["--resume", r]).expect("resume");
    assert_eq!(resumed.summary.iterations, 40);
    assert_eq!(mtimes(&features), maps);

    // A second run with the same model and options reuses the maps; a
    // different variant makes new ones.
    let second = tmp.path().join("second");
    let f = features.to_str().expect("utf-8");
    train(&[
        "--vlm",
        m,
        "--short-side",
        "32",
        "--dense",
        "clearclip",
        "--out",
        second.to_str().expect("utf-8"),
        "--iters",
        "5",
        "--features-out",
        f,
        "--pca",
        "off",
    ])
    .expect("second run");
    assert_eq!(mtimes(&features), maps);

    // eval with the run's own text tower.
    let seg = Segment::try_parse_from(["segment", "--run", r, "--classes", "wall, floor, sofa"])
        .expect("segment args");
    segment_command(&seg.args).expect("segment with the run's model");
    let q = Query::try_parse_from([
        "query",
        "--run",
        r,
        "--text",
        "something to sit on",
        "--max-views",
        "1",
    ])
    .expect("query args");
    let written = query_command(&q.args).expect("query with the run's model");
    assert!(!written.is_empty());
    // A text model of another dimension is refused, naming both.
    let other = tiny_clip(tmp.path(), 10);
    let q = Query::try_parse_from([
        "query",
        "--run",
        r,
        "--text",
        "sofa",
        "--text-model",
        other.to_str().expect("utf-8"),
    ])
    .expect("query args");
    let e = query_command(&q.args)
        .expect_err("dimension differs")
        .to_string();
    assert!(e.contains("10 dimensions") && e.contains("12"), "{e}");
}

#[test]
fn bad_vlm_input_is_refused_before_anything_is_written() {
    let (_guard, tmp, model) = setup();
    let m = model.to_str().expect("utf-8");
    let out = tmp.path().join("never");
    let o = out.to_str().expect("utf-8");
    let refused = |args: &[&str], words: &[&str]| {
        let e = train(args).expect_err("refused");
        for w in words {
            assert!(e.contains(w), "{args:?}: {e}");
        }
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    };
    refused(
        &["--vlm", m, "--dense", "sclip", "--out", o],
        &["sclip", "naclip"],
    );
    refused(&["--vlm", m, "--features", m, "--out", o], &["--features"]);
    refused(
        &["--vlm", m, "--extractor-command", "x", "--out", o],
        &["--extractor-command"],
    );
    refused(&["--dense", "naclip", "--out", o], &["--vlm"]);
    refused(
        &["--vlm", m, "--short-side", "16", "--out", o],
        &["16", "32"],
    );
    // A text-only checkpoint.
    let text_only = tmp.path().join("text_only");
    let device = Device::flex();
    let config = ClipTextConfig::new()
        .with_width(8)
        .with_layers(1)
        .with_heads(2)
        .with_mlp_width(16)
        .with_embed_dim(12);
    clip::export::save_hf_model(&config.init(&device), &config, &text_only).expect("save");
    refused(
        &["--vlm", text_only.to_str().expect("utf-8"), "--out", o],
        &["no vision tower"],
    );
    // A truncated weights file: named, with the reason.
    let cut = tmp.path().join("cut");
    std::fs::create_dir_all(&cut).expect("mkdir");
    for entry in std::fs::read_dir(&model)
        .expect("model dir")
        .filter_map(Result::ok)
    {
        std::fs::copy(entry.path(), cut.join(entry.file_name())).expect("copy");
    }
    let weights = cut.join("model.safetensors");
    let bytes = std::fs::read(&weights).expect("weights");
    std::fs::write(&weights, &bytes[..bytes.len() / 2]).expect("truncate");
    refused(
        &["--vlm", cut.to_str().expect("utf-8"), "--out", o],
        &["model.safetensors", "not a safetensors file"],
    );
    // A directory that is not there.
    refused(
        &["--vlm", "/nonexistent/clip", "--out", o],
        &["/nonexistent/clip"],
    );
}

#[derive(Parser)]
struct Extract {
    #[command(flatten)]
    args: eval::commands::extract::ExtractArgs,
}

#[test]
fn eval_extract_writes_maps_and_previews_that_train_reuses() {
    let (_guard, tmp, model) = setup();
    let m = model.to_str().expect("utf-8");
    let maps = tmp.path().join("maps");
    let o = maps.to_str().expect("utf-8");
    let run = |args: &[&str]| {
        let mut all = vec!["extract", "--vlm", m, "--dataset", "synthetic", "--out", o];
        all.extend_from_slice(args);
        let a = Extract::try_parse_from(&all).map_err(|e| e.to_string())?;
        eval::commands::extract::extract_command(&a.args).map_err(|e| e.to_string())
    };
    let written = run(&["--short-side", "32", "--text", "a sofa"]).expect("extract");
    let npy = written
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "npy"))
        .count();
    assert_eq!(npy, 20);
    for kind in ["pca", "relevancy"] {
        let p = maps
            .join("previews")
            .join(format!("frame000000_{kind}.png"));
        let img = image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!((img.width(), img.height()), (7, 4));
    }
    let before = mtimes(&maps);
    // train --vlm with the same model and size finds them.
    train(&[
        "--vlm",
        m,
        "--short-side",
        "32",
        "--features-out",
        o,
        "--iters",
        "3",
        "--pca",
        "off",
        "--out",
        tmp.path().join("run").to_str().expect("utf-8"),
    ])
    .expect("train reuses the maps");
    assert_eq!(mtimes(&maps), before);
    // Bad flags.
    assert!(run(&["--text", " "]).expect_err("blank").contains("--text"));
    let e = run(&["--data", "/x"]).expect_err("synthetic with --data");
    assert!(e.contains("--data"), "{e}");
    let a = Extract::try_parse_from([
        "extract",
        "--vlm",
        "/nonexistent",
        "--data",
        "/x",
        "--out",
        o,
    ])
    .expect("args");
    let e = eval::commands::extract::extract_command(&a.args)
        .expect_err("no model")
        .to_string();
    assert!(e.contains("/nonexistent"), "{e}");
}
