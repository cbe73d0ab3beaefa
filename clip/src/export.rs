//! Writing an encoder as a Hugging Face `CLIPTextModelWithProjection`
//! directory (`model.safetensors` + `config.json`): the inverse of loading,
//! for tests and for converting OpenCLIP weights.

use std::collections::BTreeMap;
use std::path::Path;

use crate::tower::{
    ClipActivation, ClipTextConfig, ClipTextEncoder, EotPooling, ResidualAttentionBlock,
};
use burn::module::Param;
use burn::nn::{LayerNorm, Linear};
use burn::tensor::Tensor;
use serde_json::{Map, Value, json};

use crate::error::ClipError;
use crate::tensors::{HostTensor, transpose, write_f32};

/// A parameter's values on the host, with its shape.
pub(crate) fn host<const D: usize>(
    t: &Param<Tensor<D>>,
    path: &Path,
) -> Result<HostTensor, ClipError> {
    let v = t.val();
    let shape = v.dims().to_vec();
    let data = v
        .try_into_vec_as::<f32>()
        .map_err(|e| ClipError::invalid(path, format!("cannot read a tensor back: {e:?}")))?;
    Ok(HostTensor { shape, data })
}

/// Inserts `name.weight` (PyTorch's `[out, in]`) and `name.bias`, if any.
pub(crate) fn put_linear(
    out: &mut BTreeMap<String, HostTensor>,
    name: &str,
    l: &Linear,
    path: &Path,
) -> Result<(), ClipError> {
    let w = host(&l.weight, path)?;
    let (d_in, d_out) = (w.shape[0], w.shape[1]);
    out.insert(
        format!("{name}.weight"),
        HostTensor {
            shape: vec![d_out, d_in],
            data: transpose(&w.data, d_in, d_out),
        },
    );
    if let Some(b) = &l.bias {
        out.insert(format!("{name}.bias"), host(b, path)?);
    }
    Ok(())
}

/// Inserts `name.weight` and `name.bias` (if any) of a layer norm.
pub(crate) fn put_norm(
    out: &mut BTreeMap<String, HostTensor>,
    name: &str,
    n: &LayerNorm,
    path: &Path,
) -> Result<(), ClipError> {
    out.insert(format!("{name}.weight"), host(&n.gamma, path)?);
    if let Some(b) = &n.beta {
        out.insert(format!("{name}.bias"), host(b, path)?);
    }
    Ok(())
}

/// Inserts one residual attention block's tensors under `prefix` in
/// Hugging Face's names (the same in the text and the vision tower).
pub(crate) fn put_hf_block(
    out: &mut BTreeMap<String, HostTensor>,
    prefix: &str,
    b: &ResidualAttentionBlock,
    path: &Path,
) -> Result<(), ClipError> {
    for (name, l) in [
        ("self_attn.q_proj", &b.attn.q_proj),
        ("self_attn.k_proj", &b.attn.k_proj),
        ("self_attn.v_proj", &b.attn.v_proj),
        ("self_attn.out_proj", &b.attn.out_proj),
        ("mlp.fc1", &b.mlp.fc1),
        ("mlp.fc2", &b.mlp.fc2),
    ] {
        put_linear(out, &format!("{prefix}.{name}"), l, path)?;
    }
    put_norm(out, &format!("{prefix}.layer_norm1"), &b.ln1, path)?;
    put_norm(out, &format!("{prefix}.layer_norm2"), &b.ln2, path)
}

/// The encoder's tensors under Hugging Face names (PyTorch's `[out, in]`
/// linear weights).
pub fn hf_tensors(
    enc: &ClipTextEncoder,
    path: &Path,
) -> Result<BTreeMap<String, HostTensor>, ClipError> {
    let mut out = BTreeMap::new();
    out.insert(
        "text_model.embeddings.token_embedding.weight".into(),
        host(&enc.token_embedding.weight, path)?,
    );
    out.insert(
        "text_model.embeddings.position_embedding.weight".into(),
        host(&enc.position_embedding, path)?,
    );
    for (i, b) in enc.blocks.iter().enumerate() {
        put_hf_block(&mut out, &format!("text_model.encoder.layers.{i}"), b, path)?;
    }
    put_norm(&mut out, "text_model.final_layer_norm", &enc.final_ln, path)?;
    put_linear(&mut out, "text_projection", &enc.projection, path)?;
    Ok(out)
}

/// Writes `dir/model.safetensors` and `dir/config.json` (creating `dir`).
pub fn save_hf_model(
    enc: &ClipTextEncoder,
    config: &ClipTextConfig,
    dir: &Path,
) -> Result<(), ClipError> {
    std::fs::create_dir_all(dir).map_err(|e| ClipError::io(dir, e))?;
    let weights = dir.join("model.safetensors");
    write_f32(&weights, &hf_tensors(enc, &weights)?)?;
    let mut json = Map::new();
    json.insert(
        "architectures".into(),
        json!(["CLIPTextModelWithProjection"]),
    );
    json.extend(text_config_json(config));
    write_json(&dir.join("config.json"), &Value::Object(json))
}

/// Writes `value` as pretty-printed JSON.
pub(crate) fn write_json(path: &Path, value: &Value) -> Result<(), ClipError> {
    let text =
        serde_json::to_string_pretty(value).map_err(|e| ClipError::invalid(path, e.to_string()))?;
    std::fs::write(path, text).map_err(|e| ClipError::io(path, e))
}

/// The text tower's Hugging Face configuration (`model_type`
/// `clip_text_model`): the top level of a `CLIPTextModelWithProjection`'s
/// `config.json`, or a `CLIPModel`'s `text_config`.
pub(crate) fn text_config_json(config: &ClipTextConfig) -> Map<String, Value> {
    let eos = match config.pooling {
        EotPooling::HighestId => 2,
        EotPooling::EosId(id) => id as u64,
    };
    [
        ("model_type", json!("clip_text_model")),
        ("vocab_size", json!(config.vocab_size)),
        ("max_position_embeddings", json!(config.context_length)),
        ("hidden_size", json!(config.width)),
        ("num_hidden_layers", json!(config.layers)),
        ("num_attention_heads", json!(config.heads)),
        ("intermediate_size", json!(config.mlp_width)),
        ("projection_dim", json!(config.embed_dim)),
        ("hidden_act", json!(hf_activation(config.activation))),
        ("layer_norm_eps", json!(config.layer_norm_eps)),
        ("eos_token_id", json!(eos)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

/// Hugging Face's `hidden_act` name of `a`.
pub(crate) fn hf_activation(a: ClipActivation) -> &'static str {
    match a {
        ClipActivation::QuickGelu => "quick_gelu",
        ClipActivation::Gelu => "gelu",
    }
}
