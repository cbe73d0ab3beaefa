//! Targets of the CLIP model directory: safetensors weights, the BPE
//! vocabulary and merges, `tokenizer.json` and the two configurations.

use std::path::Path;

use clip::config::{hf_options, open_clip_options};
use clip::layout::Layout;
use clip::tensors::TensorFile;

use super::{Seeds, Target, present};

const FIXTURES: &str = "clip/tests/fixtures";

const ST_TOKENS: &[&str] = &[
    "\"dtype\":\"F16\"",
    "\"dtype\":\"BF16\"",
    "\"dtype\":\"I64\"",
    "\"shape\":[4294967296,4294967296]",
    "\"shape\":[]",
    "\"data_offsets\":[0,18446744073709551615]",
    "\"__metadata__\":{}",
    "text_model.embeddings.token_embedding.weight",
    "token_embedding.weight",
];

const TOKENIZER_TOKENS: &[&str] = &[
    "</w>",
    "<|startoftext|>",
    "<|endoftext|>",
    "\"model\"",
    "\"vocab\"",
    "\"merges\"",
    "#version: 0.2\n",
    "a b",
    "a b c",
    ": 4294967295",
    ": -1",
];

const CONFIG_TOKENS: &[&str] = &[
    "\"heads\"",
    "\"num_attention_heads\"",
    "\"hidden_act\": \"gelu\"",
    "\"quick_gelu\": true",
    "\"pool_type\": \"eos\"",
    "\"eos_id\"",
    "\"eos_token_id\"",
    "\"text_config\"",
    "\"text_cfg\"",
    "\"layer_norm_eps\"",
];

/// Texts encoded with a fuzzed tokenizer (words, punctuation, non-ASCII).
const TEXTS: [&str; 3] = [
    "a photo of a sofa.",
    "don't!! ...",
    "caf\u{e9} \u{1F600} 12",
];

fn fixture(s: &Seeds, rel: &str) -> Option<Vec<u8>> {
    s.fixture(&format!("{FIXTURES}/{rel}"))
}

fn run_safetensors(path: &Path) {
    if let Ok(file) = TensorFile::read(path, |_| true)
        && let Ok(layout) = Layout::detect(&file)
    {
        let _ = layout.sizes(&file);
    }
}

/// Loads the tokenizer of `path`'s directory and encodes a few texts.
fn run_tokenizer(path: &Path) {
    let Some(dir) = path.parent() else { return };
    if let Ok(tok) = clip::load_tokenizer(dir, 77) {
        for t in TEXTS {
            let _ = tok.encode(t);
        }
    }
}

fn vocab_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    present([
        fixture(s, "tokenizer/vocab.json"),
        Some(br#"{"a": 0, "b": 1, "a</w>": 2, "b</w>": 3, "ab</w>": 4, "<|startoftext|>": 5, "<|endoftext|>": 6}"#.to_vec()),
    ])
}

fn merges_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    present([
        fixture(s, "tokenizer/merges.txt"),
        Some(b"#version: 0.2\na b</w>\n".to_vec()),
    ])
}

/// `tokenizer.json` as Hugging Face writes it, made from the fixture's
/// vocabulary and merges (both forms of merges: strings and pairs).
fn tokenizer_json_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    let vocab = fixture(s, "tokenizer/vocab.json")
        .and_then(|v| serde_json::from_slice::<serde_json::Value>(&v).ok());
    let merges = fixture(s, "tokenizer/merges.txt")
        .and_then(|m| clip::ClipTokenizer::parse_merges(&String::from_utf8_lossy(&m)).ok());
    let (Some(vocab), Some(merges)) = (vocab, merges) else {
        return vec![br#"{"model": {"vocab": {"a</w>": 0, "<|startoftext|>": 1, "<|endoftext|>": 2}, "merges": []}}"#.to_vec()];
    };
    let strings: Vec<String> = merges.iter().map(|(a, b)| format!("{a} {b}")).collect();
    let pairs: Vec<[&String; 2]> = merges.iter().map(|(a, b)| [a, b]).collect();
    let a = serde_json::json!({"version": "1.0", "model": {"type": "BPE", "vocab": vocab, "merges": strings}});
    let b = serde_json::json!({"model": {"vocab": vocab, "merges": pairs}});
    vec![a.to_string().into_bytes(), b.to_string().into_bytes()]
}

fn tokenizer_setup(dir: &Path, s: &Seeds, own: &str) -> std::io::Result<()> {
    if own == "tokenizer.json" {
        return Ok(());
    }
    for name in ["vocab.json", "merges.txt"] {
        if name != own {
            let bytes = fixture(s, &format!("tokenizer/{name}")).unwrap_or_default();
            std::fs::write(dir.join(name), bytes)?;
        }
    }
    Ok(())
}

fn run_config(path: &Path) {
    let _ = open_clip_options(path, 512);
    let _ = hf_options(path, 512);
}

/// The targets of this module.
pub(super) fn targets() -> Vec<Target> {
    vec![
        Target {
            name: "safetensors",
            about: "clip::tensors::TensorFile::read, Layout::detect, Layout::sizes",
            file: "model.safetensors",
            tokens: ST_TOKENS,
            seeds: |s| {
                present([
                    fixture(s, "openclip_tiny/open_clip_model.safetensors"),
                    fixture(s, "hf_tiny/model.safetensors"),
                ])
            },
            setup: |_, _| Ok(()),
            run: run_safetensors,
        },
        Target {
            name: "clip-vocab",
            about: "clip::load_tokenizer (vocab.json beside merges.txt), ClipTokenizer::encode",
            file: "vocab.json",
            tokens: TOKENIZER_TOKENS,
            seeds: vocab_seeds,
            setup: |d, s| tokenizer_setup(d, s, "vocab.json"),
            run: run_tokenizer,
        },
        Target {
            name: "clip-merges",
            about: "clip::load_tokenizer (merges.txt beside vocab.json), ClipTokenizer::encode",
            file: "merges.txt",
            tokens: TOKENIZER_TOKENS,
            seeds: merges_seeds,
            setup: |d, s| tokenizer_setup(d, s, "merges.txt"),
            run: run_tokenizer,
        },
        Target {
            name: "clip-tokenizer-json",
            about: "clip::load_tokenizer (tokenizer.json), ClipTokenizer::encode",
            file: "tokenizer.json",
            tokens: TOKENIZER_TOKENS,
            seeds: tokenizer_json_seeds,
            setup: |d, s| tokenizer_setup(d, s, "tokenizer.json"),
            run: run_tokenizer,
        },
        Target {
            name: "clip-config",
            about: "clip::config::open_clip_options, hf_options",
            file: "config.json",
            tokens: CONFIG_TOKENS,
            seeds: |s| {
                present([
                    fixture(s, "openclip_tiny/open_clip_config.json"),
                    fixture(s, "hf_tiny/config.json"),
                ])
            },
            setup: |_, _| Ok(()),
            run: run_config,
        },
    ]
}
