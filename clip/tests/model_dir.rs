//! Loading text model directories: a saved encoder loads back to the same
//! outputs, embeddings are unit length and cached, and every broken input
//! is an error that names the file (and the tensor).

use std::path::{Path, PathBuf};

use burn::tensor::{Device, Int, Tensor, TensorData};
use clip::model_dir::{TextModel, load_encoder};
use clip::tower::ClipTextConfig;
use clip::{ClipError, embed_texts};

fn tokenizer_fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/tokenizer")
}

/// A tiny random model over the full id range of the tokenizer fixture,
/// saved in Hugging Face layout with that tokenizer.
fn model_dir(root: &Path) -> (PathBuf, ClipTextConfig) {
    let config = ClipTextConfig::new()
        .with_width(8)
        .with_layers(2)
        .with_heads(2)
        .with_mlp_width(16)
        .with_embed_dim(6);
    let device = Device::flex();
    device.seed(11);
    let enc = config.init(&device);
    let dir = root.join("clip");
    clip::export::save_hf_model(&enc, &config, &dir).expect("save");
    for name in ["vocab.json", "merges.txt"] {
        std::fs::copy(tokenizer_fixture().join(name), dir.join(name)).expect("copy");
    }
    (dir, config)
}

#[test]
fn saved_model_loads_back_and_embeds_unit_vectors() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (dir, config) = model_dir(tmp.path());
    let device = Device::flex();
    let m = TextModel::load(&dir, &device).expect("load");
    assert_eq!(m.config.width, config.width);
    assert_eq!(m.config.heads, 2);
    assert_eq!(m.dim(), 6);
    let texts = vec!["a photo of a chair".to_string(), "soft".to_string()];
    let rows = m.embed(&texts).expect("embed");
    assert_eq!(rows.len(), 2);
    for r in &rows {
        let n: f32 = r.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!((n - 1.0).abs() < 1e-5, "{n}");
    }
    assert!(
        rows[0]
            .iter()
            .zip(&rows[1])
            .any(|(a, b)| (a - b).abs() > 1e-3)
    );
    // Batched with padding or alone: the same embedding.
    let alone = m.embed(&texts[1..]).expect("embed");
    let d: f32 = alone[0]
        .iter()
        .zip(&rows[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(d < 1e-5, "{d}");
    // The same as running the encoder on the tokenizer's ids by hand.
    let ids: Vec<i64> = m
        .tokenizer
        .encode("soft")
        .expect("ids")
        .iter()
        .map(|&i| i as i64)
        .collect();
    let n = ids.len();
    let t = Tensor::<2, Int>::from_data(TensorData::new(ids, [1, n]), &device);
    let direct = m.encoder.embed(t).try_into_vec_as::<f32>().expect("read");
    let d: f32 = direct
        .iter()
        .zip(&rows[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(d < 1e-6, "{d}");
    let e = m.embed(&[" \t".to_string()]).unwrap_err();
    assert!(e.to_string().contains("empty text"), "{e}");
}

#[test]
fn embeddings_are_cached_by_model_and_text() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (dir, _) = model_dir(tmp.path());
    let run = tmp.path().join("run");
    std::fs::create_dir_all(&run).expect("mkdir");
    let device = Device::flex();
    let texts = vec!["wooden".to_string(), "soft".to_string()];
    let first = embed_texts(&dir, &texts, Some(&run), &device).expect("embed");
    assert_eq!((first.cached, first.dim), (0, 6));
    let again = embed_texts(&dir, &texts, Some(&run), &device).expect("embed");
    assert_eq!(again.cached, 2);
    assert_eq!(again.rows, first.rows);
    let more = vec!["soft".to_string(), "something to sit on".to_string()];
    let mixed = embed_texts(&dir, &more, Some(&run), &device).expect("embed");
    assert_eq!(mixed.cached, 1);
    assert_eq!(mixed.rows[0], first.rows[1]);
}

#[test]
fn broken_directories_name_the_file_and_tensor() {
    let tmp = tempfile::tempdir().expect("tmp");
    let device = Device::flex();
    let err = |dir: &Path| TextModel::load(dir, &device).unwrap_err().to_string();

    let e = err(&tmp.path().join("nowhere"));
    assert!(e.contains("nowhere") && e.contains("missing"), "{e}");
    let e = err(tmp.path());
    assert!(e.contains("model.safetensors"), "{e}");

    let (dir, _) = model_dir(tmp.path());
    let weights = dir.join("model.safetensors");
    let enc = load_encoder(&dir, &device).expect("load").encoder;
    let tensors = clip::export::hf_tensors(&enc, &weights).expect("tensors");

    let mut t = tensors.clone();
    t.remove("text_projection.weight");
    clip::tensors::write_f32(&weights, &t).expect("write");
    let e = err(&dir);
    assert!(
        e.contains("model.safetensors") && e.contains("text_projection.weight"),
        "{e}"
    );

    let mut t = tensors.clone();
    t.get_mut("text_model.encoder.layers.1.mlp.fc2.bias")
        .expect("bias")
        .shape = vec![4, 2];
    clip::tensors::write_f32(&weights, &t).expect("write");
    match TextModel::load(&dir, &device).unwrap_err() {
        ClipError::TensorShape {
            name,
            found,
            expected,
            ..
        } => {
            assert_eq!(name, "text_model.encoder.layers.1.mlp.fc2.bias");
            assert_eq!((found, expected), (vec![4, 2], vec![8]));
        }
        other => panic!("{other}"),
    }

    // Weights that are not a CLIP text model at all.
    let mut t = std::collections::BTreeMap::new();
    t.insert(
        "encoder.weight".to_string(),
        tensors["text_projection.weight"].clone(),
    );
    clip::tensors::write_f32(&weights, &t).expect("write");
    assert!(err(&dir).contains("not a CLIP text model"));

    // Weights and a vocabulary that do not belong together.
    clip::tensors::write_f32(&weights, &tensors).expect("write");
    let mut small = tensors;
    small
        .get_mut("text_model.embeddings.token_embedding.weight")
        .expect("tokens")
        .shape = vec![100, 8];
    small
        .get_mut("text_model.embeddings.token_embedding.weight")
        .expect("tokens")
        .data
        .truncate(800);
    clip::tensors::write_f32(&weights, &small).expect("write");
    let e = err(&dir);
    assert!(e.contains("do not belong together"), "{e}");

    // No tokenizer files.
    std::fs::remove_file(dir.join("vocab.json")).expect("rm");
    let e = err(&dir);
    assert!(e.contains("vocab.json"), "{e}");
    // A config with heads that do not divide the width.
    std::fs::write(dir.join("config.json"), r#"{"num_attention_heads": 3}"#).expect("write");
    let e = err(&dir);
    assert!(
        e.contains("model.safetensors") && e.contains("3 heads"),
        "{e}"
    );
}

#[test]
fn tokenizer_json_gives_the_ids_of_vocab_and_merges() {
    let fixture = tokenizer_fixture();
    let reference = clip::load_tokenizer(&fixture, 77).expect("vocab.json + merges.txt");
    let vocab: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture.join("vocab.json")).expect("read"))
            .expect("vocab");
    let merges_text = std::fs::read_to_string(fixture.join("merges.txt")).expect("read");
    let merges = clip::ClipTokenizer::parse_merges(&merges_text).expect("merges");
    // Both spellings of the merges: "a b" strings (older) and [a, b] pairs.
    let as_strings: Vec<String> = merges.iter().map(|(a, b)| format!("{a} {b}")).collect();
    let as_pairs: Vec<[String; 2]> = merges.iter().map(|(a, b)| [a.clone(), b.clone()]).collect();
    let texts = [
        "a photo of a chair",
        "Don’t use curly “quotes”",
        "café naïve",
    ];
    for merges in [serde_json::json!(as_strings), serde_json::json!(as_pairs)] {
        let dir = tempfile::tempdir().expect("tmp");
        let json = serde_json::json!({
            "model": { "type": "BPE", "vocab": vocab, "merges": merges, "end_of_word_suffix": "</w>" }
        });
        std::fs::write(dir.path().join("tokenizer.json"), json.to_string()).expect("write");
        let t = clip::load_tokenizer(dir.path(), 77).expect("tokenizer.json");
        for text in texts {
            assert_eq!(
                t.encode(text).expect("ids"),
                reference.encode(text).expect("ids"),
                "{text}"
            );
        }
    }
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::write(
        dir.path().join("tokenizer.json"),
        r#"{"model": {"vocab": {}}}"#,
    )
    .expect("write");
    let e = clip::load_tokenizer(dir.path(), 77)
        .unwrap_err()
        .to_string();
    assert!(e.contains("tokenizer.json") && e.contains("merges"), "{e}");
}

#[test]
fn a_clip_model_file_with_its_vision_tower_and_nested_config_loads() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (dir, config) = model_dir(tmp.path());
    let device = Device::flex();
    let plain = TextModel::load(&dir, &device).expect("load");
    let weights = dir.join("model.safetensors");
    let mut tensors = clip::export::hf_tensors(&plain.encoder, &weights).expect("tensors");
    let extra = clip::tensors::HostTensor {
        shape: vec![2, 3],
        data: vec![0.5; 6],
    };
    for name in [
        "vision_model.embeddings.patch_embedding.weight",
        "visual_projection.weight",
        "logit_scale",
    ] {
        tensors.insert(name.to_string(), extra.clone());
    }
    clip::tensors::write_f32(&weights, &tensors).expect("write");
    // A CLIPModel config: the text options under text_config; GELU there
    // must be taken (the saved model uses quick-GELU).
    let nested = serde_json::json!({
        "architectures": ["CLIPModel"],
        "projection_dim": config.embed_dim,
        "text_config": { "num_attention_heads": 2, "hidden_act": "quick_gelu", "eos_token_id": 2 },
        "vision_config": { "num_attention_heads": 12 }
    });
    std::fs::write(dir.join("config.json"), nested.to_string()).expect("write");
    let m = TextModel::load(&dir, &device).expect("CLIPModel layout");
    let texts = vec!["wooden".to_string()];
    assert_eq!(
        m.embed(&texts).expect("embed"),
        plain.embed(&texts).expect("embed")
    );
    let gelu =
        serde_json::json!({ "text_config": { "num_attention_heads": 2, "hidden_act": "gelu" } });
    std::fs::write(dir.join("config.json"), gelu.to_string()).expect("write");
    let m = TextModel::load(&dir, &device).expect("gelu");
    assert_eq!(m.config.activation, clip::tower::ClipActivation::Gelu);
    assert_ne!(
        m.embed(&texts).expect("embed"),
        plain.embed(&texts).expect("embed")
    );
}
