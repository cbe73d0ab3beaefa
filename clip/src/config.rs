//! The text model's configuration: sizes from the tensor shapes, the rest
//! (heads, activation, layer-norm epsilon, pooling) from Hugging Face's
//! `config.json` or OpenCLIP's `open_clip_config.json`, with CLIP's
//! defaults where a file is silent about a field. A missing file is
//! refused: the weights alone do not say which activation they were
//! trained with.

use std::path::Path;

use crate::tower::{ClipActivation, ClipTextConfig, EotPooling};
use serde_json::Value;

use crate::error::{ClipError, read_text};

/// Options that the tensor shapes do not tell.
#[derive(Debug, Clone, PartialEq)]
pub struct TextOptions {
    /// Number of attention heads.
    pub heads: usize,
    /// MLP activation.
    pub activation: ClipActivation,
    /// Layer-norm epsilon.
    pub layer_norm_eps: f64,
    /// Which token is pooled.
    pub pooling: EotPooling,
    /// What was assumed for lack of a config file or field (for the user).
    pub notes: Vec<String>,
}

pub(crate) fn read_json(path: &Path) -> Result<Value, ClipError> {
    let text = read_text(path, "model configuration (JSON)")?;
    serde_json::from_str(&text).map_err(|e| ClipError::invalid(path, format!("invalid JSON: {e}")))
}

pub(crate) fn get_usize(v: &Value, key: &str, path: &Path) -> Result<Option<usize>, ClipError> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => x
            .as_u64()
            .map(|n| Some(n as usize))
            .ok_or_else(|| ClipError::invalid(path, format!("{key}: expected a count, got {x}"))),
    }
}

/// Options from a Hugging Face `config.json` (a `CLIPModel`'s `text_config`
/// or older `text_config_dict`, or a text model's top level) for a model of
/// `width` channels. As in `transformers`, an `eos_token_id` of 2 (older
/// configs) means pooling at the highest id. Without a head count, CLIP's
/// 64 channels per head are assumed.
pub fn hf_options(path: &Path, width: usize) -> Result<TextOptions, ClipError> {
    let root = read_json(path)?;
    let mut text = serde_json::Map::new();
    for key in ["text_config_dict", "text_config"] {
        if let Some(Value::Object(m)) = root.get(key) {
            text.extend(m.clone());
        }
    }
    let text = if text.is_empty() {
        root
    } else {
        Value::Object(text)
    };
    let text = &text;
    let mut notes = Vec::new();
    let heads = get_usize(text, "num_attention_heads", path)?.unwrap_or_else(|| {
        let h = (width / 64).max(1);
        notes.push(format!(
            "{}: no num_attention_heads, assuming {h} (64 channels each)",
            path.display()
        ));
        h
    });
    let activation = match text.get("hidden_act").and_then(Value::as_str) {
        None => ClipActivation::QuickGelu,
        Some(name) => ClipActivation::from_hf_name(name).ok_or_else(|| {
            ClipError::invalid(
                path,
                format!("hidden_act {name:?} is not supported (quick_gelu or gelu)"),
            )
        })?,
    };
    let layer_norm_eps = text
        .get("layer_norm_eps")
        .and_then(Value::as_f64)
        .unwrap_or(1e-5);
    let pooling = match get_usize(text, "eos_token_id", path)? {
        None | Some(2) => EotPooling::HighestId,
        Some(id) => EotPooling::EosId(id as u32),
    };
    Ok(TextOptions {
        heads,
        activation,
        layer_norm_eps,
        pooling,
        notes,
    })
}

/// Options from OpenCLIP's `open_clip_config.json` (`model_cfg.text_cfg`,
/// `model_cfg.quick_gelu`). The file is required: OpenCLIP's weights do not
/// tell exact GELU from quick-GELU (OpenAI's CLIP, also in OpenCLIP's
/// layout, uses quick-GELU), and the wrong one gives wrong embeddings
/// without any error.
pub fn open_clip_options(path: &Path, width: usize) -> Result<TextOptions, ClipError> {
    let notes = Vec::new();
    if !path.is_file() {
        return Err(ClipError::missing(
            path,
            format!(
                "OpenCLIP weights need their open_clip_config.json: it decides the activation \
                 (\"model_cfg\": {{\"quick_gelu\": true}} for OpenAI's CLIP, false for models \
                 trained with exact GELU) and text_cfg.heads (CLIP has one per 64 channels, \
                 {} here); OpenCLIP writes it next to the weights",
                (width / 64).max(1)
            ),
        ));
    }
    let root = read_json(path)?;
    let cfg = root.get("model_cfg").unwrap_or(&root);
    let text = cfg.get("text_cfg").unwrap_or(&Value::Null);
    let heads = get_usize(text, "heads", path)?.unwrap_or(8);
    let quick = cfg
        .get("quick_gelu")
        .and_then(Value::as_bool)
        .unwrap_or(false);
    let pooling = match text.get("pool_type").and_then(Value::as_str) {
        None | Some("argmax") => EotPooling::HighestId,
        Some("eos") => EotPooling::EosId(get_usize(text, "eos_id", path)?.unwrap_or(2) as u32),
        Some(other) => {
            return Err(ClipError::invalid(
                path,
                format!("text_cfg.pool_type {other:?} is not supported (argmax or eos)"),
            ));
        }
    };
    for unsupported in [
        "hf_model_name",
        "embed_cls",
        "no_causal_mask",
        "ls_init_value",
    ] {
        if text
            .get(unsupported)
            .is_some_and(|v| !v.is_null() && v != &Value::Bool(false))
        {
            return Err(ClipError::invalid(
                path,
                format!("text_cfg.{unsupported} is not supported by this CLIP text encoder"),
            ));
        }
    }
    Ok(TextOptions {
        heads,
        activation: if quick {
            ClipActivation::QuickGelu
        } else {
            ClipActivation::Gelu
        },
        layer_norm_eps: 1e-5,
        pooling,
        notes,
    })
}

/// Sizes read from the tensor shapes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sizes {
    /// Vocabulary size.
    pub vocab_size: usize,
    /// Context length.
    pub context_length: usize,
    /// Width.
    pub width: usize,
    /// Number of blocks.
    pub layers: usize,
    /// MLP hidden width.
    pub mlp_width: usize,
    /// Projection output dimension.
    pub embed_dim: usize,
}

/// The full configuration; `path` names the file blamed if it cannot be built.
pub fn build_config(
    sizes: Sizes,
    o: &TextOptions,
    path: &Path,
) -> Result<ClipTextConfig, ClipError> {
    let c = ClipTextConfig::new()
        .with_vocab_size(sizes.vocab_size)
        .with_context_length(sizes.context_length)
        .with_width(sizes.width)
        .with_layers(sizes.layers)
        .with_heads(o.heads)
        .with_mlp_width(sizes.mlp_width)
        .with_embed_dim(sizes.embed_dim)
        .with_activation(o.activation)
        .with_layer_norm_eps(o.layer_norm_eps)
        .with_pooling(o.pooling);
    match c.problem() {
        Some(p) => Err(ClipError::invalid(
            path,
            format!("not a usable text model: {p}"),
        )),
        None => Ok(c),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hf_text_config_nested_or_top_level() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("config.json");
        std::fs::write(
            &p,
            r#"{"text_config": {"num_attention_heads": 12, "hidden_act": "gelu", "eos_token_id": 2}}"#,
        )
        .unwrap();
        let o = hf_options(&p, 512).unwrap();
        assert_eq!(
            (o.heads, o.activation, o.pooling),
            (12, ClipActivation::Gelu, EotPooling::HighestId)
        );
        std::fs::write(&p, r#"{"num_attention_heads": 4, "eos_token_id": 45}"#).unwrap();
        let o = hf_options(&p, 512).unwrap();
        assert_eq!(
            (o.heads, o.activation, o.pooling),
            (4, ClipActivation::QuickGelu, EotPooling::EosId(45))
        );
        std::fs::write(&p, r#"{"hidden_act": "relu"}"#).unwrap();
        let e = hf_options(&p, 512).unwrap_err().to_string();
        assert!(e.contains("config.json") && e.contains("relu"), "{e}");
        std::fs::write(&p, "{").unwrap();
        assert!(
            hf_options(&p, 512)
                .unwrap_err()
                .to_string()
                .contains("invalid JSON")
        );
    }

    #[test]
    fn a_missing_open_clip_config_is_refused_and_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("open_clip_config.json");
        let e = open_clip_options(&p, 768).unwrap_err().to_string();
        assert!(
            e.contains("open_clip_config.json") && e.contains("quick_gelu"),
            "{e}"
        );
    }
}
