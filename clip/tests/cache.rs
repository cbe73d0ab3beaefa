//! The text-embedding cache is keyed on the content of the model directory:
//! a change of configuration or tokenizer recomputes the embeddings, while
//! a weights file rewritten with the same bytes keeps them.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use clip::embed_texts;

/// The OpenCLIP tiny fixture (random weights, `quick_gelu: false`) copied
/// into `root`, with a vocabulary of single letters that fits its 40 token
/// embeddings (end-of-text the highest id, as OpenCLIP's pooling needs).
fn open_clip_dir(root: &Path) -> PathBuf {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/openclip_tiny");
    let dir = root.join("openclip");
    std::fs::create_dir_all(&dir).expect("mkdir");
    for name in ["open_clip_config.json", "open_clip_model.safetensors"] {
        std::fs::copy(fixture.join(name), dir.join(name)).expect("copy");
    }
    write_vocab(&dir, ["a", "b"]);
    std::fs::write(dir.join("merges.txt"), "#version: 0.2\n").expect("merges");
    dir
}

/// `vocab.json` with ids 0 and 1 for the two given letters (as whole
/// words), the rest of the alphabet after them.
fn write_vocab(dir: &Path, first: [&str; 2]) {
    let mut vocab = serde_json::Map::new();
    let rest = ('a'..='z')
        .map(String::from)
        .filter(|c| !first.contains(&c.as_str()));
    for (i, c) in first.iter().map(|c| c.to_string()).chain(rest).enumerate() {
        vocab.insert(format!("{c}</w>"), i.into());
    }
    vocab.insert("<|startoftext|>".into(), 38.into());
    vocab.insert("<|endoftext|>".into(), 39.into());
    std::fs::write(
        dir.join("vocab.json"),
        serde_json::Value::Object(vocab).to_string(),
    )
    .expect("vocab");
}

fn set_quick_gelu(dir: &Path, on: bool) {
    let path = dir.join("open_clip_config.json");
    let mut config: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
    config["model_cfg"]["quick_gelu"] = on.into();
    std::fs::write(&path, config.to_string()).expect("write");
}

#[test]
fn a_changed_config_or_tokenizer_recomputes_the_embeddings() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = open_clip_dir(tmp.path());
    let run = tmp.path().join("run");
    std::fs::create_dir_all(&run).expect("mkdir");
    let device = Device::flex();
    let texts = vec!["a b".to_string(), "c".to_string()];
    let embed = || embed_texts(&dir, &texts, Some(&run), &device).expect("embed");

    let first = embed();
    assert_eq!(first.cached, 0);
    assert_eq!(
        embed().cached,
        2,
        "the same directory again: from the cache"
    );

    // quick-GELU instead of exact GELU: same weights file, other embeddings.
    set_quick_gelu(&dir, true);
    let quick = embed();
    assert_eq!(
        quick.cached, 0,
        "a changed open_clip_config.json kept old embeddings"
    );
    assert_ne!(quick.rows, first.rows);
    assert_eq!(embed().cached, 2);

    // "a" and "b" swap ids: the text "a b" becomes another token sequence.
    write_vocab(&dir, ["b", "a"]);
    let swapped = embed();
    assert_eq!(
        swapped.cached, 0,
        "a changed vocab.json kept old embeddings"
    );
    assert_ne!(swapped.rows[0], quick.rows[0]);

    // Back to the first configuration and vocabulary: the first embeddings,
    // whether from the cache or recomputed.
    set_quick_gelu(&dir, false);
    write_vocab(&dir, ["a", "b"]);
    assert_eq!(embed().rows, first.rows);
}

#[test]
fn weights_rewritten_with_the_same_bytes_keep_the_cache_and_other_bytes_do_not() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = open_clip_dir(tmp.path());
    let run = tmp.path().join("run");
    std::fs::create_dir_all(&run).expect("mkdir");
    let device = Device::flex();
    let texts = vec!["a b c".to_string()];
    let embed = || embed_texts(&dir, &texts, Some(&run), &device).expect("embed");
    let first = embed();
    assert_eq!(first.cached, 0);

    let weights = dir.join("open_clip_model.safetensors");
    let bytes = std::fs::read(&weights).expect("read");
    // A new modification time (some file systems keep seconds only).
    std::thread::sleep(std::time::Duration::from_millis(1100));
    std::fs::write(&weights, &bytes).expect("rewrite");
    assert_eq!(embed().cached, 1, "same content, new mtime: still cached");

    // One float of the last tensor's data changed, size unchanged.
    let mut changed = bytes.clone();
    let last = changed.len() - 2;
    changed[last] ^= 0x40;
    std::fs::write(&weights, &changed).expect("rewrite");
    let again = embed();
    assert_eq!(again.cached, 0, "changed weights kept old embeddings");
}

#[test]
fn a_missing_config_is_refused_not_assumed() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = open_clip_dir(tmp.path());
    let device = Device::flex();
    clip::TextModel::load(&dir, &device).expect("with its config");
    std::fs::remove_file(dir.join("open_clip_config.json")).expect("rm");
    let e = clip::TextModel::load(&dir, &device)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("open_clip_config.json") && e.contains("missing") && e.contains("quick_gelu"),
        "{e}"
    );
    // The same for Hugging Face's layout and its config.json.
    let hf = tmp.path().join("hf");
    std::fs::create_dir_all(&hf).expect("mkdir");
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hf_tiny");
    std::fs::copy(
        fixture.join("model.safetensors"),
        hf.join("model.safetensors"),
    )
    .expect("copy");
    let e = clip::model_dir::load_encoder(&hf, &device)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("config.json") && e.contains("missing") && e.contains("hidden_act"),
        "{e}"
    );
    std::fs::copy(fixture.join("config.json"), hf.join("config.json")).expect("copy");
    clip::model_dir::load_encoder(&hf, &device).expect("with its config");
}
