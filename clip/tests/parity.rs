//! Parity with the reference implementations, on the fixtures that
//! `tests/clip_reference.py` wrote: randomly initialised tiny models saved
//! by `transformers` and `open_clip` with their outputs, and the ids the
//! real CLIP tokenizer gives a list of tricky strings. Three more tests need
//! Python packages and are ignored by default (see the README's testing
//! section); run with `--ignored`, a missing package fails them rather than
//! skips them. `.ci/run` installs `open_clip_torch`'s vocabulary into a
//! virtual environment and runs the full-vocabulary tokenizer test.

use std::path::{Path, PathBuf};
use std::process::Command;

use burn::tensor::{Int, Tensor, TensorData};
use clip::model_dir::{OPEN_CLIP_VOCAB, load_encoder, load_tokenizer};
use serde_json::Value;

mod common;
use common::{devices, floats, max_abs_diff, python, read_json, require_python};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

fn ids(v: &Value) -> (Vec<i64>, usize, usize) {
    let rows = v.as_array().expect("rows");
    let s = rows[0].as_array().expect("row").len();
    let flat = rows
        .iter()
        .flat_map(|r| {
            r.as_array()
                .expect("row")
                .iter()
                .map(|x| x.as_i64().expect("id"))
        })
        .collect();
    (flat, rows.len(), s)
}

/// Runs the model of `dir` on the reference's input ids on every CPU
/// backend and checks the embeddings (and hidden states, when the
/// reference has them) to 1e-4. Returns the largest difference per backend.
fn check_model(dir: &Path) -> Vec<(&'static str, f32)> {
    let reference = read_json(&dir.join("reference.json"));
    let (input, b, s) = ids(&reference["input_ids"]);
    let want = floats(&reference["text_embeds"]);
    let mut out = Vec::new();
    for (name, device) in devices() {
        let loaded = load_encoder(dir, &device).unwrap_or_else(|e| panic!("{name}: {e}"));
        let tokens =
            || Tensor::<2, Int>::from_data(TensorData::new(input.clone(), [b, s]), &device);
        let got = loaded
            .encoder
            .forward(tokens())
            .try_into_vec_as::<f32>()
            .expect("read");
        let mut diff = max_abs_diff(&got, &want);
        if let Some(h) = reference.get("last_hidden_state") {
            let hidden = loaded
                .encoder
                .hidden_states(tokens())
                .try_into_vec_as::<f32>()
                .expect("read");
            diff = diff.max(max_abs_diff(&hidden, &floats(h)));
        }
        println!("{}: {name}: max abs difference {diff:.2e}", dir.display());
        assert!(
            diff < 1e-4,
            "{name}: max abs difference {diff} on {}",
            dir.display()
        );
        out.push((name, diff));
    }
    out
}

#[test]
fn hugging_face_tiny_model_matches_transformers() {
    check_model(&fixtures().join("hf_tiny"));
}

#[test]
fn open_clip_tiny_model_matches_open_clip() {
    check_model(&fixtures().join("openclip_tiny"));
}

/// Checks the tokenizer of `vocab_dir` against the expected ids; returns
/// how many strings also match Hugging Face's tokenizer.
fn check_tokenizer(tokenizer: &clip::ClipTokenizer, expected: &Value) -> usize {
    let cases = expected["cases"].as_array().expect("cases");
    assert!(cases.len() >= 15);
    let mut same_as_hf = 0;
    for case in cases {
        let text = case["text"].as_str().expect("text");
        let want: Vec<u32> = case["open_clip"]
            .as_array()
            .expect("ids")
            .iter()
            .map(|x| x.as_u64().expect("id") as u32)
            .collect();
        let got = tokenizer
            .encode(text)
            .unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_eq!(got, want, "{text:?}");
        let hf: Vec<u32> = case["hf"]
            .as_array()
            .expect("ids")
            .iter()
            .map(|x| x.as_u64().expect("id") as u32)
            .collect();
        same_as_hf += usize::from(got == hf);
    }
    same_as_hf
}

#[test]
fn tokenizer_matches_open_clip_on_tricky_strings() {
    let dir = fixtures().join("tokenizer");
    let expected = read_json(&dir.join("expected.json"));
    let tokenizer = load_tokenizer(&dir, 77).expect("fixture tokenizer");
    let same = check_tokenizer(&tokenizer, &expected);
    let n = expected["cases"].as_array().map_or(0, Vec::len);
    println!("{n} strings match open_clip; {same} also match transformers' CLIPTokenizer");
    // The long string is cut to 77 tokens, ending in end-of-text.
    let long = tokenizer
        .encode(&"something to sit on ".repeat(25))
        .expect("long");
    assert_eq!(long.len(), 77);
    assert_eq!(long.last(), Some(&tokenizer.end_id()));
}

#[test]
#[ignore = "needs open_clip_torch's vocabulary file (.ci/run installs it with pip install --no-deps open_clip_torch)"]
fn tokenizer_with_the_full_vocabulary_of_open_clip() {
    // The package's directory without importing it: importing needs torch,
    // the vocabulary file does not.
    let out = Command::new(python())
        .args([
            "-c",
            "import importlib.util as u; print(u.find_spec('open_clip').submodule_search_locations[0])",
        ])
        .output()
        .unwrap_or_else(|e| panic!("{}: {e}", python()));
    assert!(
        out.status.success(),
        "{} has no open_clip package: pip install --no-deps open_clip_torch (or set \
         OPENNERF_PYTHON): {}",
        python(),
        String::from_utf8_lossy(&out.stderr)
    );
    let bpe = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()).join(OPEN_CLIP_VOCAB[0]);
    assert!(bpe.is_file(), "{}: missing", bpe.display());
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::copy(&bpe, dir.path().join(OPEN_CLIP_VOCAB[0])).expect("copy vocabulary");
    let tokenizer = load_tokenizer(dir.path(), 77).expect("full vocabulary");
    assert_eq!((tokenizer.start_id(), tokenizer.end_id()), (49406, 49407));
    let expected = read_json(&fixtures().join("tokenizer/expected.json"));
    let same = check_tokenizer(&tokenizer, &expected);
    println!(
        "full vocabulary {}: all strings match open_clip ({same} also transformers)",
        bpe.display()
    );
}

const REFERENCE_PACKAGES: &str = "pip install torch transformers open_clip_torch ftfy safetensors";

#[test]
#[ignore = "needs torch, transformers and open_clip_torch (several GB of Python packages)"]
fn regenerated_references_match() {
    require_python(
        "torch, transformers, open_clip, ftfy, safetensors",
        REFERENCE_PACKAGES,
    );
    let out = tempfile::tempdir().expect("tmp");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/clip_reference.py");
    let run = Command::new(python())
        .arg(&script)
        .arg(out.path())
        .output()
        .expect("python runs");
    assert!(
        run.status.success(),
        "{}: {}",
        script.display(),
        String::from_utf8_lossy(&run.stderr)
    );
    check_model(&out.path().join("hf_tiny"));
    check_model(&out.path().join("openclip_tiny"));
    let dir = out.path().join("tokenizer");
    let tokenizer = load_tokenizer(&dir, 77).expect("regenerated tokenizer");
    check_tokenizer(&tokenizer, &read_json(&dir.join("expected.json")));
}

/// End to end at full size: a random Hugging Face `CLIPModel` with the
/// ViT-L/14 text tower (the paper's query side) and the full vocabulary
/// against `transformers`, and a random OpenCLIP ViT-B-32-quickgelu text
/// tower with its `bpe_simple_vocab_16e6.txt.gz` against `open_clip`: text
/// in, normalised embeddings out. Ignored by default (it writes 750 MB): `cargo test --release -p clip --test parity
/// -- --ignored`. `CLIP_FULL_SIZE_DIR` reuses a directory made by
/// `tests/clip_reference.py --full-size DIR`.
#[test]
#[ignore = "writes and loads 750 MB of models"]
fn full_size_models_match_the_references_end_to_end() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = match std::env::var_os("CLIP_FULL_SIZE_DIR") {
        Some(d) => PathBuf::from(d),
        None => {
            require_python(
                "torch, transformers, open_clip, ftfy, safetensors",
                REFERENCE_PACKAGES,
            );
            let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/clip_reference.py");
            let run = Command::new(python())
                .arg(&script)
                .arg("--full-size")
                .arg(tmp.path())
                .output()
                .expect("python runs");
            assert!(
                run.status.success(),
                "{}",
                String::from_utf8_lossy(&run.stderr)
            );
            tmp.path().to_path_buf()
        }
    };
    for (sub, width, heads, dim) in [
        ("hf_vit_l14", 768, 12, 768),
        ("open_clip_vit_b32", 512, 8, 512),
    ] {
        let dir = root.join(sub);
        let reference = read_json(&dir.join("reference.json"));
        let texts: Vec<String> = reference["texts"]
            .as_array()
            .expect("texts")
            .iter()
            .map(|t| t.as_str().expect("text").to_string())
            .collect();
        let want = floats(&reference["text_embeds"]);
        for (name, device) in devices() {
            let start = std::time::Instant::now();
            let m = clip::TextModel::load(&dir, &device).expect("load");
            let loaded = start.elapsed();
            assert_eq!(
                (m.config.width, m.config.heads, m.dim()),
                (width, heads, dim)
            );
            let start = std::time::Instant::now();
            let got: Vec<f32> = m.embed(&texts).expect("embed").concat();
            let diff = max_abs_diff(&got, &want);
            println!(
                "{sub}, {name}: load {:.1} s, {} texts {:.2} s, max abs difference {diff:.2e}",
                loaded.as_secs_f64(),
                texts.len(),
                start.elapsed().as_secs_f64()
            );
            assert!(diff < 1e-4, "{sub}, {name}: {diff}");
        }
    }
}
