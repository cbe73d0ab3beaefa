//! A CLIP text model directory: weights, configuration and tokenizer files
//! found by their usual names, loaded into a [`TextModel`] that embeds text.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::tower::{ClipTextConfig, ClipTextEncoder, EotPooling};
use burn::tensor::{Device, Int, Tensor, TensorData};
use serde_json::Value;

use crate::config::{build_config, hf_options, open_clip_options};
use crate::error::{ClipError, read_file, read_text};
use crate::layout::Layout;
use crate::tensors::TensorFile;
use crate::tokenizer::ClipTokenizer;

/// Weights file names looked for, in order.
pub const WEIGHT_FILES: [&str; 2] = ["model.safetensors", "open_clip_model.safetensors"];
/// OpenAI's / OpenCLIP's BPE vocabulary file names.
pub const OPEN_CLIP_VOCAB: [&str; 2] =
    ["bpe_simple_vocab_16e6.txt.gz", "bpe_simple_vocab_16e6.txt"];

/// The weights file of `dir`: `model.safetensors`, `open_clip_model.safetensors`,
/// or the only `*.safetensors` there.
pub fn weights_file(dir: &Path) -> Result<PathBuf, ClipError> {
    if !dir.is_dir() {
        return Err(ClipError::missing(
            dir,
            "a CLIP text model directory (model.safetensors, config.json, vocab.json, merges.txt)",
        ));
    }
    for name in WEIGHT_FILES {
        if dir.join(name).is_file() {
            return Ok(dir.join(name));
        }
    }
    let others: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| ClipError::io(dir, e))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "safetensors"))
        .collect();
    match others.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(ClipError::missing(
            dir.join(WEIGHT_FILES[0]),
            "CLIP weights in safetensors (model.safetensors or open_clip_model.safetensors; \
             sharded checkpoints are not supported)",
        )),
        many => Err(ClipError::invalid(
            dir,
            format!(
                "{} safetensors files and none called model.safetensors: {:?}",
                many.len(),
                many.iter()
                    .filter_map(|p| p.file_name())
                    .collect::<Vec<_>>()
            ),
        )),
    }
}

/// The tokenizer of `dir`: `vocab.json` + `merges.txt`, else
/// `tokenizer.json`, else `bpe_simple_vocab_16e6.txt(.gz)`.
pub fn load_tokenizer(dir: &Path, context_length: usize) -> Result<ClipTokenizer, ClipError> {
    let (vocab, merges) = (dir.join("vocab.json"), dir.join("merges.txt"));
    if vocab.is_file() {
        let v = read_text(&vocab, "BPE vocabulary")?;
        let encoder: HashMap<String, u32> = serde_json::from_str(&v).map_err(|e| {
            ClipError::invalid(&vocab, format!("expected a token-to-id JSON map: {e}"))
        })?;
        let m = read_text(&merges, "BPE merges (next to vocab.json)")?;
        let merges_list =
            ClipTokenizer::parse_merges(&m).map_err(|e| ClipError::invalid(&merges, e.0))?;
        return ClipTokenizer::new(encoder, merges_list, context_length)
            .map_err(|e| ClipError::invalid(&vocab, e.0));
    }
    let tj = dir.join("tokenizer.json");
    if tj.is_file() {
        return tokenizer_json(&tj, context_length);
    }
    for name in OPEN_CLIP_VOCAB {
        let p = dir.join(name);
        if p.is_file() {
            let bytes = read_file(&p, "BPE vocabulary")?;
            let text = if name.ends_with(".gz") {
                let mut s = String::new();
                std::io::Read::read_to_string(
                    &mut flate2::read::GzDecoder::new(&bytes[..]),
                    &mut s,
                )
                .map_err(|e| ClipError::invalid(&p, format!("cannot decompress: {e}")))?;
                s
            } else {
                String::from_utf8(bytes).map_err(|e| ClipError::invalid(&p, e.to_string()))?
            };
            return ClipTokenizer::from_open_clip_bpe(&text, context_length)
                .map_err(|e| ClipError::invalid(&p, e.0));
        }
    }
    Err(ClipError::missing(
        dir.join("vocab.json"),
        "the tokenizer: vocab.json + merges.txt, tokenizer.json or bpe_simple_vocab_16e6.txt.gz",
    ))
}

fn tokenizer_json(path: &Path, context_length: usize) -> Result<ClipTokenizer, ClipError> {
    let text = read_text(path, "tokenizer")?;
    let root: Value = serde_json::from_str(&text)
        .map_err(|e| ClipError::invalid(path, format!("invalid JSON: {e}")))?;
    let model = root.get("model").unwrap_or(&Value::Null);
    let bad = |what: &str| ClipError::invalid(path, format!("model.{what} missing or malformed"));
    let encoder: HashMap<String, u32> = model
        .get("vocab")
        .and_then(|v| serde_json::from_value(v.clone()).ok())
        .ok_or_else(|| bad("vocab"))?;
    let merges = model
        .get("merges")
        .and_then(Value::as_array)
        .ok_or_else(|| bad("merges"))?
        .iter()
        .map(|m| match m {
            Value::String(s) => ClipTokenizer::parse_merges(s)
                .ok()
                .and_then(|v| v.into_iter().next()),
            Value::Array(p) => match (
                p.first().and_then(Value::as_str),
                p.get(1).and_then(Value::as_str),
            ) {
                (Some(a), Some(b)) if p.len() == 2 => Some((a.to_string(), b.to_string())),
                _ => None,
            },
            _ => None,
        })
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| bad("merges"))?;
    ClipTokenizer::new(encoder, merges, context_length).map_err(|e| ClipError::invalid(path, e.0))
}

/// The encoder of a model directory, without its tokenizer.
#[derive(Debug)]
pub struct LoadedEncoder {
    /// The weights file.
    pub weights: PathBuf,
    /// The encoder.
    pub encoder: ClipTextEncoder,
    /// Its configuration.
    pub config: ClipTextConfig,
    /// What was assumed where the files were silent.
    pub notes: Vec<String>,
}

/// Loads the weights of `dir` (Hugging Face or OpenCLIP naming, told
/// apart by the tensor names) with their configuration onto `device`.
pub fn load_encoder(dir: &Path, device: &Device) -> Result<LoadedEncoder, ClipError> {
    let weights = weights_file(dir)?;
    let mut file = TensorFile::read(&weights, Layout::is_text_tensor)?;
    let layout = Layout::detect(&file)?;
    let sizes = layout.sizes(&file)?;
    let options = match layout {
        Layout::HuggingFace => {
            let c = dir.join("config.json");
            if !c.is_file() {
                return Err(ClipError::missing(
                    &c,
                    "Hugging Face CLIP weights need their config.json: it decides the activation \
                     (hidden_act: quick_gelu for OpenAI's CLIP, gelu for others), the heads and \
                     the end-of-text id; it comes with the weights in the model's snapshot",
                ));
            }
            hf_options(&c, sizes.width)?
        }
        Layout::OpenClip => open_clip_options(&dir.join("open_clip_config.json"), sizes.width)?,
    };
    let config = build_config(sizes, &options, &weights)?;
    let encoder = layout.build(&mut file, &config, device)?;
    Ok(LoadedEncoder {
        weights,
        encoder,
        config,
        notes: options.notes,
    })
}

/// A loaded text model: tokenizer and encoder on one device.
#[derive(Debug)]
pub struct TextModel {
    /// The directory it was loaded from.
    pub dir: PathBuf,
    /// Its weights file.
    pub weights: PathBuf,
    /// The tokenizer.
    pub tokenizer: ClipTokenizer,
    /// The encoder.
    pub encoder: ClipTextEncoder,
    /// Its configuration.
    pub config: ClipTextConfig,
    /// What was assumed where the files were silent.
    pub notes: Vec<String>,
    device: Device,
}

impl TextModel {
    /// Loads `dir` (see [`weights_file`] and [`load_tokenizer`]) onto `device`.
    pub fn load(dir: &Path, device: &Device) -> Result<Self, ClipError> {
        let LoadedEncoder {
            weights,
            encoder,
            config,
            notes,
        } = load_encoder(dir, device)?;
        let tokenizer = load_tokenizer(dir, config.context_length)?;
        if tokenizer.max_id() as usize >= config.vocab_size {
            return Err(ClipError::invalid(
                dir,
                format!(
                    "the tokenizer has ids up to {} but {} has {} token embeddings: \
                     the vocabulary and the weights do not belong together",
                    tokenizer.max_id(),
                    weights.display(),
                    config.vocab_size
                ),
            ));
        }
        let end = tokenizer.end_id();
        let pooling_problem = match config.pooling {
            EotPooling::HighestId if end != tokenizer.max_id() => Some(format!(
                "pooling takes the highest token id, but the end-of-text id {end} is not the \
                 highest ({})",
                tokenizer.max_id()
            )),
            EotPooling::EosId(id) if id != end => Some(format!(
                "the configuration pools at eos id {id}, but the tokenizer's end-of-text id is {end}"
            )),
            _ => None,
        };
        if let Some(p) = pooling_problem {
            return Err(ClipError::invalid(dir, p));
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            weights,
            tokenizer,
            encoder,
            config,
            notes,
            device: device.clone(),
        })
    }

    /// Output dimension.
    pub fn dim(&self) -> usize {
        self.config.embed_dim
    }

    /// Unit-length embeddings of `texts`, one row each. Empty (or
    /// whitespace-only) text is refused.
    pub fn embed(&self, texts: &[String]) -> Result<Vec<Vec<f32>>, ClipError> {
        if texts.is_empty() {
            return Ok(Vec::new());
        }
        let mut rows = Vec::with_capacity(texts.len());
        for t in texts {
            if t.trim().is_empty() {
                return Err(ClipError::Text(
                    "empty text: give some words to embed".into(),
                ));
            }
            rows.push(
                self.tokenizer
                    .encode(t)
                    .map_err(|e| ClipError::Text(format!("{t:?}: {}", e.0)))?,
            );
        }
        // Batches of similar length (a long text does not make every short
        // one pay for its padding), at most 64 texts each.
        let mut order: Vec<usize> = (0..rows.len()).collect();
        order.sort_by_key(|&i| rows[i].len());
        let mut out = vec![Vec::new(); rows.len()];
        for batch in order.chunks(64) {
            let embedded = self.embed_ids(batch.iter().map(|&i| rows[i].as_slice()))?;
            for (&i, e) in batch.iter().zip(embedded) {
                out[i] = e;
            }
        }
        Ok(out)
    }

    /// Unit-length embeddings of token id sequences (each with its end-of-text).
    fn embed_ids<'a>(
        &self,
        rows: impl ExactSizeIterator<Item = &'a [u32]> + Clone,
    ) -> Result<Vec<Vec<f32>>, ClipError> {
        let n = rows.len();
        let s = rows.clone().map(<[u32]>::len).max().unwrap_or(2);
        // Padding after end-of-text changes nothing: attention is causal and
        // the end-of-text position is pooled.
        let ids: Vec<i64> = rows
            .flat_map(|r| {
                r.iter()
                    .map(|&i| i as i64)
                    .chain(std::iter::repeat_n(0, s - r.len()))
            })
            .collect();
        let tokens = Tensor::<2, Int>::from_data(TensorData::new(ids, [n, s]), &self.device);
        let out = self
            .encoder
            .embed(tokens)
            .try_into_vec_as::<f32>()
            .map_err(|e| {
                ClipError::invalid(&self.weights, format!("cannot read embeddings: {e:?}"))
            })?;
        Ok(out.chunks(self.dim()).map(<[f32]>::to_vec).collect())
    }
}
