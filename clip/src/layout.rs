//! The two naming schemes of CLIP weights, Hugging Face (`CLIPModel`,
//! `CLIPTextModelWithProjection`, `CLIPVisionModelWithProjection`) and
//! OpenCLIP / OpenAI (`CLIP`), how each maps the text tower onto
//! [`ClipTextEncoder`], and the residual attention block that both towers
//! name alike (the vision tower's mapping is in
//! [`crate::vision::layout`]).

use crate::tower::{ClipTextConfig, ClipTextEncoder, ResidualAttentionBlock};
use burn::module::Param;
use burn::nn::{LayerNorm, Linear};
use burn::tensor::{Device, Tensor, TensorData};

use crate::config::Sizes;
use crate::error::ClipError;
use crate::tensors::{HostTensor, TensorFile, transpose};

/// A naming scheme (one for both towers of a checkpoint).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// `text_model.embeddings.token_embedding.weight`, `text_model.encoder.layers.N...`,
    /// `text_projection.weight`; `vision_model.*`, `visual_projection.weight`.
    HuggingFace,
    /// `token_embedding.weight`, `positional_embedding`,
    /// `transformer.resblocks.N...`, `ln_final`, `text_projection`;
    /// `visual.*`.
    OpenClip,
}

const HF_TOKENS: &str = "text_model.embeddings.token_embedding.weight";
const HF_POSITIONS: &str = "text_model.embeddings.position_embedding.weight";
const OC_TOKENS: &str = "token_embedding.weight";
const OC_POSITIONS: &str = "positional_embedding";

impl Layout {
    /// The name used in messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::HuggingFace => "Hugging Face",
            Self::OpenClip => "OpenCLIP",
        }
    }

    /// Whether a tensor name belongs to the text tower in some layout.
    pub fn is_text_tensor(name: &str) -> bool {
        !(name.starts_with("visual.") || name.starts_with("vision_model."))
    }

    /// The scheme of `file`, told by its token embedding's name.
    pub fn detect(file: &TensorFile) -> Result<Self, ClipError> {
        if file.contains(HF_TOKENS) {
            Ok(Self::HuggingFace)
        } else if file.contains(OC_TOKENS) {
            Ok(Self::OpenClip)
        } else {
            let some: Vec<&str> = file.names().take(5).collect();
            Err(ClipError::invalid(
                &file.path,
                format!(
                    "not a CLIP text model: no {HF_TOKENS} (Hugging Face) or {OC_TOKENS} \
                     (OpenCLIP); its tensors include {some:?}"
                ),
            ))
        }
    }

    fn block_prefix(self, i: usize) -> String {
        match self {
            Self::HuggingFace => format!("text_model.encoder.layers.{i}."),
            Self::OpenClip => format!("transformer.resblocks.{i}."),
        }
    }

    /// The sizes the tensor shapes give.
    pub fn sizes(self, file: &TensorFile) -> Result<Sizes, ClipError> {
        let (tokens, positions, fc1, proj_linear, proj_matrix) = match self {
            Self::HuggingFace => (
                HF_TOKENS,
                HF_POSITIONS,
                "mlp.fc1.weight",
                "text_projection.weight",
                "",
            ),
            Self::OpenClip => (
                OC_TOKENS,
                OC_POSITIONS,
                "mlp.c_fc.weight",
                "text_projection.weight",
                "text_projection",
            ),
        };
        let shape2 = |name: &str| -> Result<[usize; 2], ClipError> {
            match file.shape(name) {
                Some(&[a, b]) => Ok([a, b]),
                Some(other) => Err(ClipError::invalid(
                    &file.path,
                    format!("tensor {name:?} has shape {other:?}, expected a matrix"),
                )),
                None => Err(ClipError::MissingTensor {
                    path: file.path.clone(),
                    name: name.to_string(),
                    layout: self.name(),
                }),
            }
        };
        let [vocab_size, width] = shape2(tokens)?;
        let [context_length, _] = shape2(positions)?;
        let layers = (0..)
            .take_while(|&i| file.names().any(|n| n.starts_with(&self.block_prefix(i))))
            .count();
        if layers == 0 {
            return Err(ClipError::invalid(
                &file.path,
                format!(
                    "no transformer blocks ({}0.*)",
                    self.block_prefix(0).trim_end_matches("0.")
                ),
            ));
        }
        let [mlp_width, _] = shape2(&format!("{}{fc1}", self.block_prefix(0)))?;
        let embed_dim = if file.contains(proj_linear) {
            shape2(proj_linear)?[0]
        } else if !proj_matrix.is_empty() && file.contains(proj_matrix) {
            shape2(proj_matrix)?[1]
        } else {
            return Err(ClipError::MissingTensor {
                path: file.path.clone(),
                name: if proj_matrix.is_empty() {
                    proj_linear
                } else {
                    proj_matrix
                }
                .to_string(),
                layout: self.name(),
            });
        };
        Ok(Sizes {
            vocab_size,
            context_length,
            width,
            layers,
            mlp_width,
            embed_dim,
        })
    }

    /// The encoder with `file`'s weights (every tensor checked against `config`).
    pub fn build(
        self,
        file: &mut TensorFile,
        config: &ClipTextConfig,
        device: &Device,
    ) -> Result<ClipTextEncoder, ClipError> {
        let mut enc = config.init(device);
        let (w, m, e) = (config.width, config.mlp_width, config.embed_dim);
        let layout = self.name();
        let mut take = |name: &str, shape: &[usize]| file.take(name, shape, layout);
        let (tokens, positions, final_ln) = match self {
            Self::HuggingFace => (HF_TOKENS, HF_POSITIONS, ("text_model.", "final_layer_norm")),
            Self::OpenClip => (OC_TOKENS, OC_POSITIONS, ("", "ln_final")),
        };
        enc.token_embedding.weight = param2(take(tokens, &[config.vocab_size, w])?, device);
        enc.position_embedding = param2(take(positions, &[config.context_length, w])?, device);
        for (i, block) in enc.blocks.iter_mut().enumerate() {
            self.load_block(block, &self.block_prefix(i), [w, m], &mut take, device)?;
        }
        set_norm(
            &mut enc.final_ln,
            final_ln.0,
            final_ln.1,
            w,
            &mut take,
            device,
        )?;
        enc.projection = match self {
            Self::HuggingFace => {
                linear_from_torch(take("text_projection.weight", &[e, w])?, None, device)
            }
            Self::OpenClip if file.contains("text_projection.weight") => {
                let weight = file.take("text_projection.weight", &[e, w], layout)?;
                let bias = file.take_optional("text_projection.bias", &[e], layout)?;
                linear_from_torch(weight, bias, device)
            }
            // A `[width, embed_dim]` matrix applied as `x @ P`: already
            // Burn's `[d_in, d_out]` layout.
            Self::OpenClip => Linear {
                weight: param2(file.take("text_projection", &[w, e], layout)?, device),
                bias: None,
            },
        };
        Ok(enc)
    }
}

/// The tensor lookup of a load: a name and the shape it must have.
pub(crate) trait Take: FnMut(&str, &[usize]) -> Result<HostTensor, ClipError> {}
impl<F: FnMut(&str, &[usize]) -> Result<HostTensor, ClipError>> Take for F {}

impl Layout {
    /// One residual attention block's weights, named under `prefix` (the
    /// names are the same in the text and the vision tower), into `block`
    /// of `width` channels and an MLP of `mlp_width`.
    pub(crate) fn load_block(
        self,
        block: &mut ResidualAttentionBlock,
        prefix: &str,
        [width, mlp_width]: [usize; 2],
        take: &mut impl Take,
        device: &Device,
    ) -> Result<(), ClipError> {
        let (p, w, m) = (prefix, width, mlp_width);
        let (fc1, fc2, ln1, ln2) = match self {
            Self::HuggingFace => {
                block.attn.q_proj = take_linear(take, p, "self_attn.q_proj", [w, w], device)?;
                block.attn.k_proj = take_linear(take, p, "self_attn.k_proj", [w, w], device)?;
                block.attn.v_proj = take_linear(take, p, "self_attn.v_proj", [w, w], device)?;
                block.attn.out_proj = take_linear(take, p, "self_attn.out_proj", [w, w], device)?;
                ("mlp.fc1", "mlp.fc2", "layer_norm1", "layer_norm2")
            }
            Self::OpenClip => {
                let packed = take(&format!("{p}attn.in_proj_weight"), &[3 * w, w])?;
                let bias = take(&format!("{p}attn.in_proj_bias"), &[3 * w])?;
                [block.attn.q_proj, block.attn.k_proj, block.attn.v_proj] =
                    split_in_proj(&packed, &bias, w, device);
                block.attn.out_proj = take_linear(take, p, "attn.out_proj", [w, w], device)?;
                ("mlp.c_fc", "mlp.c_proj", "ln_1", "ln_2")
            }
        };
        block.mlp.fc1 = take_linear(take, p, fc1, [w, m], device)?;
        block.mlp.fc2 = take_linear(take, p, fc2, [m, w], device)?;
        set_norm(&mut block.ln1, p, ln1, w, take, device)?;
        set_norm(&mut block.ln2, p, ln2, w, take, device)
    }
}

/// The linear layer `{prefix}{name}` (PyTorch's weight and bias) mapping
/// `d_in` to `d_out` channels.
fn take_linear(
    take: &mut impl Take,
    prefix: &str,
    name: &str,
    [d_in, d_out]: [usize; 2],
    device: &Device,
) -> Result<Linear, ClipError> {
    let weight = take(&format!("{prefix}{name}.weight"), &[d_out, d_in])?;
    let bias = take(&format!("{prefix}{name}.bias"), &[d_out])?;
    Ok(linear_from_torch(weight, Some(bias), device))
}

/// OpenCLIP's packed attention input projection (`in_proj_weight`, `[3 w,
/// w]`, and `in_proj_bias`, `[3 w]`) as the query, key and value layers.
pub(crate) fn split_in_proj(
    packed: &HostTensor,
    bias: &HostTensor,
    w: usize,
    device: &Device,
) -> [Linear; 3] {
    [0, 1, 2].map(|k| {
        let weight = HostTensor {
            shape: vec![w, w],
            data: packed.data[k * w * w..(k + 1) * w * w].to_vec(),
        };
        let b = HostTensor {
            shape: vec![w],
            data: bias.data[k * w..(k + 1) * w].to_vec(),
        };
        linear_from_torch(weight, Some(b), device)
    })
}

pub(crate) fn set_norm(
    norm: &mut LayerNorm,
    prefix: &str,
    name: &str,
    width: usize,
    take: &mut impl Take,
    device: &Device,
) -> Result<(), ClipError> {
    norm.gamma = param1(take(&format!("{prefix}{name}.weight"), &[width])?, device);
    norm.beta = Some(param1(
        take(&format!("{prefix}{name}.bias"), &[width])?,
        device,
    ));
    Ok(())
}

pub(crate) fn param1(t: HostTensor, device: &Device) -> Param<Tensor<1>> {
    let n = t.data.len();
    Param::from_tensor(Tensor::from_data(TensorData::new(t.data, [n]), device))
}

pub(crate) fn param2(t: HostTensor, device: &Device) -> Param<Tensor<2>> {
    let shape = [t.shape[0], t.shape[1]];
    Param::from_tensor(Tensor::from_data(TensorData::new(t.data, shape), device))
}

/// A Burn linear layer from PyTorch's `[d_out, d_in]` weight (transposed to
/// Burn's `[d_in, d_out]`) and optional bias.
pub(crate) fn linear_from_torch(
    weight: HostTensor,
    bias: Option<HostTensor>,
    device: &Device,
) -> Linear {
    let (d_out, d_in) = (weight.shape[0], weight.shape[1]);
    let w = HostTensor {
        shape: vec![d_in, d_out],
        data: transpose(&weight.data, d_out, d_in),
    };
    Linear {
        weight: param2(w, device),
        bias: bias.map(|b| param1(b, device)),
    }
}
