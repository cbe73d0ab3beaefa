//! The vision tower's configuration: sizes from the tensor shapes; heads,
//! activation, layer-norm epsilon and the image normalisation from Hugging
//! Face's `config.json` + `preprocessor_config.json` or OpenCLIP's
//! `open_clip_config.json`. Whatever a file leaves out and is assumed is
//! reported in `notes`, never assumed silently.

use std::path::Path;

use crate::tower::{ClipActivation, ClipVisionConfig};
use serde_json::Value;

use super::layout::VisionSizes;
use crate::config::{get_usize, read_json};
use crate::error::ClipError;

/// OpenAI's CLIP pixel mean (RGB), used by every CLIP checkpoint we know
/// (written with the digits OpenAI published).
#[allow(clippy::excessive_precision)]
pub const OPENAI_MEAN: [f32; 3] = [0.481_454_66, 0.457_827_5, 0.408_210_73];
/// OpenAI's CLIP pixel standard deviation (RGB).
#[allow(clippy::excessive_precision)]
pub const OPENAI_STD: [f32; 3] = [0.268_629_54, 0.261_302_58, 0.275_777_11];

/// Per-channel pixel normalisation, `(x - mean) / std` on `[0, 1]` values.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImageNorm {
    /// Mean per channel.
    pub mean: [f32; 3],
    /// Standard deviation per channel.
    pub std: [f32; 3],
}

/// Options the shapes do not tell.
#[derive(Debug, Clone, PartialEq)]
pub struct VisionOptions {
    /// Attention heads.
    pub heads: usize,
    /// MLP activation.
    pub activation: ClipActivation,
    /// Layer-norm epsilon.
    pub layer_norm_eps: f64,
    /// Pixel normalisation.
    pub norm: ImageNorm,
    /// What was assumed where the files were silent.
    pub notes: Vec<String>,
}

fn triple(v: Option<&Value>, key: &str, path: &Path) -> Result<Option<[f32; 3]>, ClipError> {
    let Some(v) = v.filter(|v| !v.is_null()) else {
        return Ok(None);
    };
    let bad = || {
        ClipError::invalid(
            path,
            format!("{key}: expected three positive numbers, got {v}"),
        )
    };
    let a = v.as_array().ok_or_else(bad)?;
    let vals: Vec<f32> = a
        .iter()
        .filter_map(Value::as_f64)
        .map(|x| x as f32)
        .collect();
    if vals.len() != 3 || a.len() != 3 || vals.iter().any(|x| !x.is_finite()) {
        return Err(bad());
    }
    Ok(Some([vals[0], vals[1], vals[2]]))
}

fn norm_from(
    mean: Option<[f32; 3]>,
    std: Option<[f32; 3]>,
    path: &Path,
    notes: &mut Vec<String>,
) -> Result<ImageNorm, ClipError> {
    if let Some(s) = std
        && s.iter().any(|x| *x <= 0.0)
    {
        return Err(ClipError::invalid(
            path,
            format!("image std {s:?} must be positive"),
        ));
    }
    if mean.is_none() || std.is_none() {
        notes.push(format!(
            "{}: no image mean/std, using OpenAI's CLIP normalisation",
            path.display()
        ));
    }
    Ok(ImageNorm {
        mean: mean.unwrap_or(OPENAI_MEAN),
        std: std.unwrap_or(OPENAI_STD),
    })
}

/// Refuses a configuration count that disagrees with the weights' shapes:
/// `checks` holds (key, the weights' value); `what` prefixes the key in
/// the message.
fn agree_with_weights(
    v: &Value,
    checks: &[(&str, usize)],
    what: &str,
    path: &Path,
) -> Result<(), ClipError> {
    for &(key, want) in checks {
        if let Some(n) = get_usize(v, key, path)?
            && n != want
        {
            return Err(ClipError::invalid(
                path,
                format!("{what}{key} {n} disagrees with the weights ({want})"),
            ));
        }
    }
    Ok(())
}

/// Options from a Hugging Face directory: `config.json` (`vision_config`, or
/// the top level of a vision-only model) and, when present,
/// `preprocessor_config.json` (`image_mean`, `image_std`).
pub fn hf_vision_options(dir: &Path, sizes: &VisionSizes) -> Result<VisionOptions, ClipError> {
    let path = dir.join("config.json");
    if !path.is_file() {
        return Err(ClipError::missing(
            &path,
            "Hugging Face CLIP weights need their config.json (vision_config.hidden_act: \
             quick_gelu for OpenAI's CLIP, gelu for others; num_attention_heads)",
        ));
    }
    let root = read_json(&path)?;
    let v = match root.get("vision_config") {
        Some(Value::Object(m)) => Value::Object(m.clone()),
        _ => root.clone(),
    };
    let mut notes = Vec::new();
    let heads = get_usize(&v, "num_attention_heads", &path)?.unwrap_or_else(|| {
        let h = (sizes.width / 64).max(1);
        notes.push(format!(
            "{}: no vision num_attention_heads, assuming {h} (64 channels each)",
            path.display()
        ));
        h
    });
    let activation = match v.get("hidden_act").and_then(Value::as_str) {
        None => {
            notes.push(format!(
                "{}: no vision hidden_act, using transformers' default quick_gelu",
                path.display()
            ));
            ClipActivation::QuickGelu
        }
        Some(name) => ClipActivation::from_hf_name(name).ok_or_else(|| {
            ClipError::invalid(
                &path,
                format!("vision hidden_act {name:?} is not supported (quick_gelu or gelu)"),
            )
        })?,
    };
    agree_with_weights(
        &v,
        &[
            ("patch_size", sizes.patch_size),
            ("image_size", sizes.image_size),
            ("hidden_size", sizes.width),
        ],
        "vision ",
        &path,
    )?;
    let layer_norm_eps = v
        .get("layer_norm_eps")
        .and_then(Value::as_f64)
        .unwrap_or(1e-5);
    let pre = dir.join("preprocessor_config.json");
    let (mean, std, blame) = if pre.is_file() {
        let p = read_json(&pre)?;
        (
            triple(p.get("image_mean"), "image_mean", &pre)?,
            triple(p.get("image_std"), "image_std", &pre)?,
            pre,
        )
    } else {
        (None, None, pre)
    };
    let norm = norm_from(mean, std, &blame, &mut notes)?;
    Ok(VisionOptions {
        heads,
        activation,
        layer_norm_eps,
        norm,
        notes,
    })
}

/// Options from OpenCLIP's `open_clip_config.json` (`model_cfg.vision_cfg`,
/// `model_cfg.quick_gelu`, `preprocess_cfg`). Required: the weights do not
/// tell exact GELU from quick-GELU.
pub fn open_clip_vision_options(
    dir: &Path,
    sizes: &VisionSizes,
) -> Result<VisionOptions, ClipError> {
    let path = dir.join("open_clip_config.json");
    if !path.is_file() {
        return Err(ClipError::missing(
            &path,
            "OpenCLIP weights need their open_clip_config.json: it decides the activation \
             (\"model_cfg\": {\"quick_gelu\": true} for OpenAI's CLIP) and vision_cfg.head_width",
        ));
    }
    let root = read_json(&path)?;
    let cfg = root.get("model_cfg").unwrap_or(&root);
    let v = cfg.get("vision_cfg").cloned().unwrap_or(Value::Null);
    let mut notes = Vec::new();
    for unsupported in [
        "timm_model_name",
        "attentional_pool",
        "attn_pooler_queries",
        "no_ln_pre",
        "final_ln_after_pool",
        "ls_init_value",
        "output_tokens",
    ] {
        if v.get(unsupported)
            .is_some_and(|x| !x.is_null() && x != &Value::Bool(false))
        {
            return Err(ClipError::invalid(
                &path,
                format!("vision_cfg.{unsupported} is not supported by this CLIP vision encoder"),
            ));
        }
    }
    if let Some(pool) = v.get("pool_type").and_then(Value::as_str)
        && pool != "tok"
    {
        return Err(ClipError::invalid(
            &path,
            format!("vision_cfg.pool_type {pool:?} is not supported (tok)"),
        ));
    }
    let head_width = get_usize(&v, "head_width", &path)?.unwrap_or(64).max(1);
    let heads = (sizes.width / head_width).max(1);
    if cfg.get("quick_gelu").is_none() {
        notes.push(format!(
            "{}: no quick_gelu, using OpenCLIP's default (exact GELU)",
            path.display()
        ));
    }
    let quick = cfg
        .get("quick_gelu")
        .and_then(Value::as_bool)
        .unwrap_or(false);
    agree_with_weights(
        &v,
        &[
            ("patch_size", sizes.patch_size),
            ("image_size", sizes.image_size),
            ("width", sizes.width),
            ("layers", sizes.layers),
        ],
        "vision_cfg.",
        &path,
    )?;
    let pre = root.get("preprocess_cfg").unwrap_or(&Value::Null);
    let norm = norm_from(
        triple(pre.get("mean"), "preprocess_cfg.mean", &path)?,
        triple(pre.get("std"), "preprocess_cfg.std", &path)?,
        &path,
        &mut notes,
    )?;
    Ok(VisionOptions {
        heads,
        activation: if quick {
            ClipActivation::QuickGelu
        } else {
            ClipActivation::Gelu
        },
        layer_norm_eps: 1e-5,
        norm,
        notes,
    })
}

/// The full configuration; `path` names the file blamed if it cannot be built.
pub fn build_vision_config(
    sizes: &VisionSizes,
    o: &VisionOptions,
    path: &Path,
) -> Result<ClipVisionConfig, ClipError> {
    let c = ClipVisionConfig::new()
        .with_image_size(sizes.image_size)
        .with_patch_size(sizes.patch_size)
        .with_width(sizes.width)
        .with_layers(sizes.layers)
        .with_heads(o.heads)
        .with_mlp_width(sizes.mlp_width)
        .with_embed_dim(sizes.embed_dim)
        .with_activation(o.activation)
        .with_layer_norm_eps(o.layer_norm_eps);
    match c.problem() {
        Some(p) => Err(ClipError::invalid(
            path,
            format!("not a usable vision tower: {p}"),
        )),
        None => Ok(c),
    }
}
