//! Writing a whole CLIP model (both towers) as a Hugging Face `CLIPModel`
//! directory: `model.safetensors`, `config.json` and
//! `preprocessor_config.json`. The inverse of [`super::Vlm::load`] on that
//! layout, for tests and for converting OpenCLIP weights.

use std::collections::BTreeMap;
use std::path::Path;

use crate::tower::{ClipTextConfig, ClipTextEncoder, ClipVisionConfig, ClipVisionEncoder};
use serde_json::{Map, Value, json};

use super::config::{OPENAI_MEAN, OPENAI_STD};
use crate::error::ClipError;
use crate::export::{
    hf_activation, hf_tensors, host, put_hf_block, put_linear, put_norm, text_config_json,
    write_json,
};
use crate::tensors::{HostTensor, transpose, write_f32};

/// `transformers`' initial `logit_scale` (ln(1 / 0.07)), written so that
/// `CLIPModel.from_pretrained` finds every parameter; the encoders do not
/// hold one.
const LOGIT_SCALE_INIT: f32 = 2.6592;

/// The vision encoder's tensors under Hugging Face names (`vision_model.*`
/// and `visual_projection.weight`; PyTorch's `[out, in]` linear weights, the
/// patch embedding as the convolution's `[width, 3, patch, patch]`).
pub fn hf_vision_tensors(
    enc: &ClipVisionEncoder,
    path: &Path,
) -> Result<BTreeMap<String, HostTensor>, ClipError> {
    let mut out = BTreeMap::new();
    // Burn's `[3 * p * p, width]` back to the convolution's weight.
    let patch = host(&enc.patch_embedding.weight, path)?;
    let (d_in, width) = (patch.shape[0], patch.shape[1]);
    let p = enc.patch_size;
    if d_in != 3 * p * p {
        return Err(ClipError::invalid(
            path,
            format!("the patch embedding takes {d_in} values, not 3 x {p} x {p} (patch size {p})"),
        ));
    }
    out.insert(
        "vision_model.embeddings.patch_embedding.weight".into(),
        HostTensor {
            shape: vec![width, 3, p, p],
            data: transpose(&patch.data, d_in, width),
        },
    );
    out.insert(
        "vision_model.embeddings.class_embedding".into(),
        host(&enc.class_embedding, path)?,
    );
    out.insert(
        "vision_model.embeddings.position_embedding.weight".into(),
        host(&enc.position_embedding, path)?,
    );
    put_norm(&mut out, "vision_model.pre_layrnorm", &enc.pre_ln, path)?;
    for (i, b) in enc.blocks.iter().enumerate() {
        put_hf_block(
            &mut out,
            &format!("vision_model.encoder.layers.{i}"),
            b,
            path,
        )?;
    }
    put_norm(&mut out, "vision_model.post_layernorm", &enc.post_ln, path)?;
    put_linear(&mut out, "visual_projection", &enc.projection, path)?;
    Ok(out)
}

/// `x` as the `f64` of its shortest decimal form (`0.48145466`, not
/// `0.48145467042922974`), which reads back as the same `f32`.
fn decimal(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// Why `enc` does not have the sizes `config` gives, if it does not.
fn vision_mismatch(enc: &ClipVisionEncoder, config: &ClipVisionConfig) -> Option<String> {
    let [_, width] = enc.patch_embedding.weight.dims();
    let found = [
        ("patch_size", enc.patch_size),
        ("width", width),
        ("layers", enc.blocks.len()),
        ("grid", enc.native_grid()),
        ("embed_dim", enc.embed_dim()),
    ];
    let want = [
        config.patch_size,
        config.width,
        config.layers,
        config.grid(),
        config.embed_dim,
    ];
    found
        .iter()
        .zip(want)
        .find(|((_, f), w)| *f != *w)
        .map(|((name, f), w)| format!("the vision encoder's {name} is {f}, its config says {w}"))
}

/// Writes `dir/model.safetensors` (both towers, Hugging Face names),
/// `dir/config.json` (a `CLIPModel`'s, with `text_config` and
/// `vision_config`) and `dir/preprocessor_config.json` (OpenAI's pixel mean
/// and std), creating `dir`. The towers must project to the same dimension.
/// The tokenizer files are not written.
pub fn save_hf_clip_model(
    text: &ClipTextEncoder,
    text_config: &ClipTextConfig,
    vision: &ClipVisionEncoder,
    vision_config: &ClipVisionConfig,
    dir: &Path,
) -> Result<(), ClipError> {
    if text_config.embed_dim != vision_config.embed_dim {
        return Err(ClipError::invalid(
            dir,
            format!(
                "a CLIPModel has one projection_dim: the text tower projects to {} dimensions, \
                 the vision tower to {}",
                text_config.embed_dim, vision_config.embed_dim
            ),
        ));
    }
    if let Some(problem) = vision_config
        .problem()
        .or_else(|| vision_mismatch(vision, vision_config))
    {
        return Err(ClipError::invalid(dir, problem));
    }
    std::fs::create_dir_all(dir).map_err(|e| ClipError::io(dir, e))?;
    let weights = dir.join("model.safetensors");
    let mut tensors = hf_tensors(text, &weights)?;
    tensors.extend(hf_vision_tensors(vision, &weights)?);
    tensors.insert(
        "logit_scale".into(),
        HostTensor {
            shape: vec![],
            data: vec![LOGIT_SCALE_INIT],
        },
    );
    write_f32(&weights, &tensors)?;

    let c = vision_config;
    let vision_json: Map<String, Value> = [
        ("model_type", json!("clip_vision_model")),
        ("hidden_size", json!(c.width)),
        ("intermediate_size", json!(c.mlp_width)),
        ("num_hidden_layers", json!(c.layers)),
        ("num_attention_heads", json!(c.heads)),
        ("num_channels", json!(3)),
        ("image_size", json!(c.image_size)),
        ("patch_size", json!(c.patch_size)),
        ("hidden_act", json!(hf_activation(c.activation))),
        ("layer_norm_eps", json!(c.layer_norm_eps)),
        ("projection_dim", json!(c.embed_dim)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let config = json!({
        "architectures": ["CLIPModel"],
        "model_type": "clip",
        "projection_dim": text_config.embed_dim,
        "logit_scale_init_value": decimal(LOGIT_SCALE_INIT),
        "text_config": Value::Object(text_config_json(text_config)),
        "vision_config": Value::Object(vision_json),
    });
    write_json(&dir.join("config.json"), &config)?;

    let size = c.image_size;
    let preprocessor = json!({
        "image_processor_type": "CLIPImageProcessor",
        "do_resize": true,
        "size": {"shortest_edge": size},
        "resample": 3,
        "do_center_crop": true,
        "crop_size": {"height": size, "width": size},
        "do_rescale": true,
        "rescale_factor": 1.0 / 255.0,
        "do_normalize": true,
        "image_mean": OPENAI_MEAN.map(decimal),
        "image_std": OPENAI_STD.map(decimal),
        "do_convert_rgb": true,
    });
    write_json(&dir.join("preprocessor_config.json"), &preprocessor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tower::DenseVariant;
    use crate::vision::Vlm;
    use burn::tensor::{Device, Distribution, Int, Tensor, TensorData};

    fn tokenizer_fixture() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/tokenizer")
    }

    #[test]
    fn a_saved_clip_model_loads_back_with_both_towers() {
        let device = Device::flex();
        device.seed(17);
        // The default vocabulary covers the tokenizer fixture's ids.
        let text_config = ClipTextConfig::new()
            .with_width(8)
            .with_layers(2)
            .with_heads(2)
            .with_mlp_width(16)
            .with_embed_dim(6);
        let vision_config = ClipVisionConfig::new()
            .with_image_size(16)
            .with_patch_size(4)
            .with_width(8)
            .with_layers(2)
            .with_heads(2)
            .with_mlp_width(16)
            .with_embed_dim(6);
        let text = text_config.init(&device);
        let vision = vision_config.init(&device);
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("clip");
        save_hf_clip_model(&text, &text_config, &vision, &vision_config, &dir).unwrap();
        for name in ["vocab.json", "merges.txt"] {
            std::fs::copy(tokenizer_fixture().join(name), dir.join(name)).unwrap();
        }
        let config: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("config.json")).unwrap())
                .unwrap();
        assert_eq!(config["architectures"], json!(["CLIPModel"]));
        assert_eq!(config["vision_config"]["patch_size"], json!(4));
        assert_eq!(config["text_config"]["vocab_size"], json!(49408));

        let vlm = Vlm::load(&dir, &device).unwrap();
        assert!(vlm.notes().is_empty(), "nothing assumed: {:?}", vlm.notes());
        assert_eq!(vlm.dim(), 6);
        assert_eq!(vlm.vision.config.image_size, 16);
        assert_eq!(vlm.vision.config.heads, 2);
        assert_eq!(vlm.vision.norm.mean, OPENAI_MEAN);
        assert_eq!(vlm.vision.norm.std, OPENAI_STD);
        // Dense features (a stretched 3x5 grid) and the pooled embedding.
        let pixels: Tensor<4> =
            Tensor::random([2, 3, 12, 20], Distribution::Normal(0.0, 1.0), &device);
        let max_diff = |a: Vec<f32>, b: Vec<f32>| {
            assert_eq!(a.len(), b.len());
            a.iter()
                .zip(&b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f32::max)
        };
        for v in DenseVariant::ALL {
            let want = vision.dense(pixels.clone(), v).try_into_vec_as::<f32>();
            let got = vlm.vision.encoder.dense(pixels.clone(), v);
            let d = max_diff(got.try_into_vec_as::<f32>().unwrap(), want.unwrap());
            assert!(d <= 1e-6, "{v}: {d}");
        }
        let native = pixels.slice([0..2, 0..3, 0..16, 0..16]);
        let d = max_diff(
            vlm.vision
                .encoder
                .forward(native.clone())
                .try_into_vec_as::<f32>()
                .unwrap(),
            vision.forward(native).try_into_vec_as::<f32>().unwrap(),
        );
        assert!(d <= 1e-6, "image embedding: {d}");
        // The text tower too.
        let ids = Tensor::<2, Int>::from_data(
            TensorData::new(vec![49406i64, 320, 1929, 49407], [1, 4]),
            &device,
        );
        let d = max_diff(
            vlm.text
                .encoder
                .forward(ids.clone())
                .try_into_vec_as::<f32>()
                .unwrap(),
            text.forward(ids).try_into_vec_as::<f32>().unwrap(),
        );
        assert!(d <= 1e-6, "text embedding: {d}");
    }

    #[test]
    fn towers_of_different_dimensions_are_refused() {
        let device = Device::flex();
        let text_config = ClipTextConfig::new()
            .with_vocab_size(16)
            .with_context_length(8)
            .with_width(8)
            .with_layers(1)
            .with_heads(2)
            .with_mlp_width(16)
            .with_embed_dim(6);
        let vision_config = ClipVisionConfig::new()
            .with_image_size(8)
            .with_patch_size(4)
            .with_width(8)
            .with_layers(1)
            .with_heads(2)
            .with_mlp_width(16)
            .with_embed_dim(5);
        let tmp = tempfile::tempdir().unwrap();
        let e = save_hf_clip_model(
            &text_config.init(&device),
            &text_config,
            &vision_config.init(&device),
            &vision_config,
            tmp.path(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains('6') && e.contains('5'), "{e}");
        // An encoder that is not the configuration's.
        let vision = vision_config.clone().with_embed_dim(6);
        let e = save_hf_clip_model(
            &text_config.init(&device),
            &text_config,
            &vision_config.init(&device),
            &vision,
            tmp.path(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("embed_dim is 5, its config says 6"), "{e}");
    }
}
