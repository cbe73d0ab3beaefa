//! Broken vision inputs: every one is an error that says which file (or
//! image) is at fault and what is wrong with it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use burn::tensor::Device;
use clip::tensors::{HostTensor, write_f32};
use clip::tower::{ClipTextConfig, ClipVisionConfig};
use clip::vision::export::{hf_vision_tensors, save_hf_clip_model};
use clip::vision::{DenseOptions, VisionModel, Vlm};
use serde_json::Value;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// A copy of `fixtures/vision/NAME` in a temporary directory, to mutate.
fn fixture_copy(name: &str) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join(name);
    std::fs::create_dir(&dir).expect("mkdir");
    for entry in std::fs::read_dir(fixtures().join("vision").join(name)).expect("fixture") {
        let entry = entry.expect("entry");
        std::fs::copy(entry.path(), dir.join(entry.file_name())).expect("copy");
    }
    (tmp, dir)
}

fn copy_tokenizer(dir: &Path) {
    for name in ["vocab.json", "merges.txt"] {
        std::fs::copy(fixtures().join("tokenizer").join(name), dir.join(name)).expect("copy");
    }
}

fn vision_error(dir: &Path) -> String {
    VisionModel::load(dir, &Device::flex())
        .expect_err("should fail")
        .to_string()
}

fn vlm_error(dir: &Path) -> String {
    Vlm::load(dir, &Device::flex())
        .expect_err("should fail")
        .to_string()
}

fn assert_names(e: &str, path: &Path, words: &[&str]) {
    println!("{e}");
    assert!(
        e.contains(&path.display().to_string()),
        "the error should name {}: {e}",
        path.display()
    );
    for w in words {
        assert!(e.contains(w), "the error should say {w:?}: {e}");
    }
}

fn text_config() -> ClipTextConfig {
    // The default vocabulary covers the tokenizer fixture's ids.
    ClipTextConfig::new()
        .with_width(8)
        .with_layers(1)
        .with_heads(2)
        .with_mlp_width(16)
        .with_embed_dim(6)
}

fn vision_config() -> ClipVisionConfig {
    ClipVisionConfig::new()
        .with_image_size(16)
        .with_patch_size(4)
        .with_width(8)
        .with_layers(1)
        .with_heads(2)
        .with_mlp_width(16)
        .with_embed_dim(6)
}

#[test]
fn a_text_only_checkpoint_has_no_vision_tower() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("text");
    let device = Device::flex();
    let config = text_config();
    clip::export::save_hf_model(&config.init(&device), &config, &dir).expect("save");
    copy_tokenizer(&dir);
    // The text tower itself is fine.
    clip::TextModel::load(&dir, &device).expect("text loads");
    let weights = dir.join("model.safetensors");
    assert_names(&vision_error(&dir), &weights, &["no vision tower"]);
    assert_names(&vlm_error(&dir), &weights, &["no vision tower"]);
}

#[test]
fn towers_projecting_to_different_dimensions_are_not_one_model() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("clip");
    let device = Device::flex();
    let (tc, vc) = (text_config(), vision_config());
    let text = tc.init(&device);
    save_hf_clip_model(&text, &tc, &vc.init(&device), &vc, &dir).expect("save");
    copy_tokenizer(&dir);
    Vlm::load(&dir, &device).expect("the consistent model loads");
    // The same directory with a vision tower projecting to 5 dimensions.
    let weights = dir.join("model.safetensors");
    let mut tensors = clip::export::hf_tensors(&text, &weights).expect("text tensors");
    let narrow = vc.clone().with_embed_dim(5).init(&device);
    tensors.extend(hf_vision_tensors(&narrow, &weights).expect("vision tensors"));
    write_f32(&weights, &tensors).expect("write");
    let vision = VisionModel::load(&dir, &device).expect("the vision tower alone loads");
    assert_eq!(vision.dim(), 5);
    assert_names(
        &vlm_error(&dir),
        &weights,
        &["5 dimensions", "text tower to 6", "not one CLIP model"],
    );
}

/// A directory whose `model.safetensors` holds only `names` (2x2 tensors).
fn weights_only(names: &[&str]) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().expect("tmp");
    let weights = tmp.path().join("model.safetensors");
    let tensors: BTreeMap<String, HostTensor> = names
        .iter()
        .map(|n| {
            let t = HostTensor {
                shape: vec![2, 2],
                data: vec![0.0; 4],
            };
            (n.to_string(), t)
        })
        .collect();
    write_f32(&weights, &tensors).expect("write");
    (tmp, weights)
}

#[test]
fn an_unknown_layout_is_named_with_its_tensors() {
    let (tmp, weights) = weights_only(&["visual.foo.weight"]);
    assert_names(
        &vision_error(tmp.path()),
        &weights,
        &["unknown vision layout", "visual.foo.weight"],
    );
}

#[test]
fn a_timm_tower_is_refused() {
    let (tmp, weights) = weights_only(&["visual.trunk.x", "visual.head.proj.weight"]);
    assert_names(
        &vision_error(tmp.path()),
        &weights,
        &["timm", "visual.trunk", "not supported"],
    );
}

#[test]
fn a_truncated_weights_file_is_named() {
    for (name, file) in [
        ("hf_tiny", "model.safetensors"),
        ("openclip_tiny", "open_clip_model.safetensors"),
    ] {
        let (_tmp, dir) = fixture_copy(name);
        let weights = dir.join(file);
        let bytes = std::fs::read(&weights).expect("read");
        std::fs::write(&weights, &bytes[..bytes.len() / 2]).expect("truncate");
        assert_names(&vision_error(&dir), &weights, &["not a safetensors file"]);
        assert_names(&vlm_error(&dir), &weights, &["not a safetensors file"]);
    }
}

#[test]
fn hugging_face_weights_without_config_json() {
    let (_tmp, dir) = fixture_copy("hf_tiny");
    let config = dir.join("config.json");
    std::fs::remove_file(&config).expect("rm");
    assert_names(
        &vision_error(&dir),
        &config,
        &["missing", "config.json", "hidden_act"],
    );
}

#[test]
fn open_clip_weights_without_open_clip_config_json() {
    let (_tmp, dir) = fixture_copy("openclip_tiny");
    let config = dir.join("open_clip_config.json");
    std::fs::remove_file(&config).expect("rm");
    assert_names(&vision_error(&dir), &config, &["missing", "quick_gelu"]);
}

#[test]
fn an_unsupported_activation_is_refused() {
    let (_tmp, dir) = fixture_copy("hf_tiny");
    let path = dir.join("config.json");
    let mut config: Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
    config["vision_config"]["hidden_act"] = Value::from("relu");
    std::fs::write(&path, config.to_string()).expect("write");
    assert_names(
        &vision_error(&dir),
        &path,
        &["vision hidden_act \"relu\"", "not supported"],
    );
}

#[test]
fn images_dense_maps_cannot_be_made_of() {
    let m = VisionModel::load(&fixtures().join("vision/hf_tiny"), &Device::flex()).expect("load");
    assert_eq!((m.config.patch_size, m.config.image_size), (8, 32));
    let options = DenseOptions::default();
    // Narrower than one 8-px patch.
    let e = m
        .dense_map(&vec![0.5; 20 * 5 * 3], (20, 5), &options)
        .expect_err("too small")
        .to_string();
    assert!(
        e.contains("5x20") && e.contains("smaller than one 8-px patch"),
        "{e}"
    );
    // A buffer that is not height x width x 3.
    let e = m
        .dense_map(&vec![0.5; 40 * 40 * 3 - 1], (40, 40), &options)
        .expect_err("wrong length")
        .to_string();
    assert!(
        e.contains("40x40") && e.contains("4800") && e.contains("4799"),
        "{e}"
    );
    // A short side below the model's 32-px input.
    let small = DenseOptions {
        short_side: Some(16),
        ..options
    };
    let e = m
        .dense_map(&vec![0.5; 40 * 40 * 3], (40, 40), &small)
        .expect_err("short side")
        .to_string();
    assert!(
        e.contains("short side 16 px") && e.contains("32-px input"),
        "{e}"
    );
    // The same image with a usable short side works.
    let fine = DenseOptions {
        short_side: Some(48),
        ..options
    };
    let map = m
        .dense_map(&vec![0.5; 40 * 40 * 3], (40, 40), &fine)
        .expect("map");
    assert_eq!((map.rows, map.cols, map.dim), (6, 6, 16));
}
