//! How each naming scheme of CLIP weights ([`Layout`]) maps the vision
//! tower onto [`ClipVisionEncoder`]: Hugging Face (`CLIPModel`,
//! `CLIPVisionModelWithProjection`) and OpenCLIP / OpenAI (`visual.*`,
//! packed attention projections, a `visual.proj` matrix).

use crate::tower::{ClipVisionConfig, ClipVisionEncoder};
use burn::nn::Linear;
use burn::tensor::Device;

use crate::error::ClipError;
use crate::layout::{Layout, linear_from_torch, param1, param2, set_norm};
use crate::tensors::{HostTensor, TensorFile};

const HF_PATCH: &str = "vision_model.embeddings.patch_embedding.weight";
const OC_PATCH: &str = "visual.conv1.weight";

/// Sizes the tensor shapes give.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VisionSizes {
    /// Transformer width.
    pub width: usize,
    /// Patch side in pixels.
    pub patch_size: usize,
    /// Native input side in pixels (grid times patch).
    pub image_size: usize,
    /// Number of blocks.
    pub layers: usize,
    /// MLP hidden width.
    pub mlp_width: usize,
    /// Projection output dimension.
    pub embed_dim: usize,
}

/// Whether a tensor name belongs to a vision tower in some layout.
pub fn is_vision_tensor(name: &str) -> bool {
    name.starts_with("visual.")
        || name.starts_with("vision_model.")
        || name == "visual_projection.weight"
}

/// The vision tower in each naming scheme: Hugging Face's
/// `vision_model.embeddings.patch_embedding.weight`,
/// `vision_model.encoder.layers.N...`, `visual_projection.weight`;
/// OpenCLIP's `visual.conv1.weight`, `visual.transformer.resblocks.N...`,
/// `visual.proj`.
impl Layout {
    /// The scheme of `file` (read with [`is_vision_tensor`]), told by its
    /// patch embedding's name.
    pub fn detect_vision(file: &TensorFile) -> Result<Self, ClipError> {
        if file.contains(HF_PATCH) {
            return Ok(Self::HuggingFace);
        }
        if file.contains(OC_PATCH) {
            return Ok(Self::OpenClip);
        }
        let names: Vec<&str> = file.names().collect();
        let message = if names.is_empty() {
            "no vision tower: this checkpoint holds a text model only; features need a whole \
             CLIP model (Hugging Face CLIPModel or CLIPVisionModelWithProjection, or an OpenCLIP \
             model saved with its visual.* tensors)"
                .to_string()
        } else if names.iter().any(|n| n.starts_with("visual.trunk.")) {
            "a timm vision tower (visual.trunk.*) is not supported: only CLIP's own ViT \
             (visual.conv1, visual.transformer.resblocks)"
                .to_string()
        } else {
            format!(
                "unknown vision layout: no {HF_PATCH} (Hugging Face) or {OC_PATCH} (OpenCLIP); \
                 its vision tensors include {:?}",
                &names[..names.len().min(5)]
            )
        };
        Err(ClipError::invalid(&file.path, message))
    }

    fn vision_block_prefix(self, i: usize) -> String {
        match self {
            Self::HuggingFace => format!("vision_model.encoder.layers.{i}."),
            Self::OpenClip => format!("visual.transformer.resblocks.{i}."),
        }
    }

    fn vision_names(self) -> (&'static str, &'static str, &'static str) {
        match self {
            Self::HuggingFace => (
                HF_PATCH,
                "vision_model.embeddings.position_embedding.weight",
                "mlp.fc1.weight",
            ),
            Self::OpenClip => (OC_PATCH, "visual.positional_embedding", "mlp.c_fc.weight"),
        }
    }

    /// The sizes the tensor shapes give.
    pub fn vision_sizes(self, file: &TensorFile) -> Result<VisionSizes, ClipError> {
        let (patch, positions, fc1) = self.vision_names();
        let shape = |name: &str| {
            file.shape(name)
                .map(<[usize]>::to_vec)
                .ok_or_else(|| ClipError::MissingTensor {
                    path: file.path.clone(),
                    name: name.to_string(),
                    layout: self.name(),
                })
        };
        let bad = |name: &str, s: &[usize], want: &str| {
            ClipError::invalid(
                &file.path,
                format!("tensor {name:?} has shape {s:?}, expected {want}"),
            )
        };
        let p = shape(patch)?;
        if p.len() != 4 || p[1] != 3 || p[2] != p[3] || p[2] == 0 {
            return Err(bad(patch, &p, "[width, 3, patch, patch]"));
        }
        let (width, patch_size) = (p[0], p[2]);
        let pos = shape(positions)?;
        let g = (pos.first().copied().unwrap_or(0).saturating_sub(1) as f64)
            .sqrt()
            .round() as usize;
        if pos.len() != 2 || pos[1] != width || g == 0 || g * g + 1 != pos[0] {
            return Err(bad(positions, &pos, "[1 + grid * grid, width]"));
        }
        let layers = (0..)
            .take_while(|&i| file.contains(&format!("{}{fc1}", self.vision_block_prefix(i))))
            .count();
        if layers == 0 {
            return Err(ClipError::MissingTensor {
                path: file.path.clone(),
                name: format!("{}{fc1}", self.vision_block_prefix(0)),
                layout: self.name(),
            });
        }
        let mlp = shape(&format!("{}{fc1}", self.vision_block_prefix(0)))?;
        let embed_dim = match self {
            Self::HuggingFace => match file.shape("visual_projection.weight") {
                Some([e, w]) if *w == width => *e,
                Some(s) => return Err(bad("visual_projection.weight", s, "[embed_dim, width]")),
                None => {
                    return Err(ClipError::invalid(
                        &file.path,
                        "no visual_projection.weight: a CLIPVisionModel without its projection \
                         gives features outside the text space (save CLIPModel or \
                         CLIPVisionModelWithProjection)",
                    ));
                }
            },
            Self::OpenClip => match file.shape("visual.proj") {
                Some([w, e]) if *w == width => *e,
                Some(s) => return Err(bad("visual.proj", s, "[width, embed_dim]")),
                None => {
                    return Err(ClipError::MissingTensor {
                        path: file.path.clone(),
                        name: "visual.proj".into(),
                        layout: self.name(),
                    });
                }
            },
        };
        Ok(VisionSizes {
            width,
            patch_size,
            image_size: g * patch_size,
            layers,
            mlp_width: mlp[0],
            embed_dim,
        })
    }

    /// The encoder with `file`'s weights (every tensor checked against `config`).
    pub fn build_vision(
        self,
        file: &mut TensorFile,
        config: &ClipVisionConfig,
        device: &Device,
    ) -> Result<ClipVisionEncoder, ClipError> {
        let mut enc = config.init(device);
        let (w, m, e, p) = (
            config.width,
            config.mlp_width,
            config.embed_dim,
            config.patch_size,
        );
        let g = config.grid();
        let layout = self.name();
        let mut take = |name: &str, shape: &[usize]| file.take(name, shape, layout);
        let (patch_name, pos_name, _) = self.vision_names();
        let patch = take(patch_name, &[w, 3, p, p])?;
        enc.patch_embedding = linear_from_torch(
            HostTensor {
                shape: vec![w, 3 * p * p],
                data: patch.data,
            },
            None,
            device,
        );
        enc.position_embedding = param2(take(pos_name, &[1 + g * g, w])?, device);
        let (class, pre, post) = match self {
            Self::HuggingFace => (
                "vision_model.embeddings.class_embedding",
                ("vision_model.", "pre_layrnorm"),
                ("vision_model.", "post_layernorm"),
            ),
            Self::OpenClip => (
                "visual.class_embedding",
                ("visual.", "ln_pre"),
                ("visual.", "ln_post"),
            ),
        };
        enc.class_embedding = param1(take(class, &[w])?, device);
        set_norm(&mut enc.pre_ln, pre.0, pre.1, w, &mut take, device)?;
        set_norm(&mut enc.post_ln, post.0, post.1, w, &mut take, device)?;
        for (i, block) in enc.blocks.iter_mut().enumerate() {
            self.load_block(
                block,
                &self.vision_block_prefix(i),
                [w, m],
                &mut take,
                device,
            )?;
        }
        enc.projection = match self {
            Self::HuggingFace => {
                linear_from_torch(take("visual_projection.weight", &[e, w])?, None, device)
            }
            // `x @ proj`: already Burn's `[d_in, d_out]`.
            Self::OpenClip => Linear {
                weight: param2(take("visual.proj", &[w, e])?, device),
                bias: None,
            },
        };
        Ok(enc)
    }
}
