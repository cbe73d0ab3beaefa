//! Text embeddings computed once: a small JSON cache (in a run directory)
//! keyed by the model directory, a hash of the content of every file that
//! decides an embedding (configuration, tokenizer, weights), and the text.
//! The model is only loaded when a text is missing.
//!
//! The key is the content, not the weights' size and modification time:
//! switching `quick_gelu` in `open_clip_config.json` or editing the
//! vocabulary leaves the weights untouched but changes every embedding.
//! Hashing the weights (hundreds of MB) on every query would cost seconds,
//! so their hash is kept in the cache file under their size and
//! modification time.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::ClipError;
use crate::model_dir::{OPEN_CLIP_VOCAB, TextModel, weights_file};

/// The configuration and tokenizer files a model directory may hold (see
/// [`crate::model_dir::load_encoder`] and [`crate::model_dir::load_tokenizer`]):
/// all that exist are hashed, used or not, so that none can go stale.
const KEYED_FILES: [&str; 7] = [
    "config.json",
    "open_clip_config.json",
    "vocab.json",
    "merges.txt",
    "tokenizer.json",
    OPEN_CLIP_VOCAB[0],
    OPEN_CLIP_VOCAB[1],
];

/// The cache file name inside a run directory.
pub const CACHE_FILE: &str = "text_embeddings_cache.json";

/// One cached embedding.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CacheEntry {
    /// The model directory (canonical path).
    pub model: String,
    /// SHA-256 of its configuration, tokenizer and weights files.
    pub fingerprint: String,
    /// The text as given.
    pub text: String,
    /// Its unit-length embedding.
    pub embedding: Vec<f32>,
}

/// The content hash of a weights file, valid while its size and
/// modification time stay the same.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeightsHash {
    /// The weights file (canonical path).
    pub path: String,
    /// Its size in bytes.
    pub size: u64,
    /// Its modification time, nanoseconds since the Unix epoch.
    pub modified_ns: u128,
    /// SHA-256 of its content, hex.
    pub sha256: String,
}

/// The cache file's content.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EmbeddingCache {
    /// Every cached embedding.
    pub entries: Vec<CacheEntry>,
    /// Hashes of the weights files seen (absent in older cache files).
    #[serde(default)]
    pub weights: Vec<WeightsHash>,
}

/// Embeddings of some texts, with where they came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Embedded {
    /// One unit-length row per text.
    pub rows: Vec<Vec<f32>>,
    /// Their dimension.
    pub dim: usize,
    /// How many came from the cache.
    pub cached: usize,
    /// Notes from loading the model (assumed options), if it was loaded.
    pub notes: Vec<String>,
}

fn hex(digest: &[u8]) -> String {
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of a whole file, read in pieces (weights do not fit twice in memory).
pub fn hash_file(path: &Path) -> Result<String, ClipError> {
    let mut file = std::fs::File::open(path).map_err(|e| ClipError::io(path, e))?;
    let mut hasher = Sha256::new();
    std::io::copy(&mut file, &mut hasher).map_err(|e| ClipError::io(path, e))?;
    Ok(hex(&hasher.finalize()))
}

impl EmbeddingCache {
    /// The SHA-256 of `weights`: from the cache while its size and
    /// modification time are the recorded ones, else computed and recorded.
    fn weights_hash(&mut self, weights: &Path) -> Result<String, ClipError> {
        let meta = std::fs::metadata(weights).map_err(|e| ClipError::io(weights, e))?;
        let modified_ns = meta
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos());
        let path = std::fs::canonicalize(weights)
            .unwrap_or_else(|_| weights.to_path_buf())
            .display()
            .to_string();
        let (size, recorded) = (meta.len(), &mut self.weights);
        if let Some(h) = recorded
            .iter()
            .find(|h| h.path == path && h.size == size && h.modified_ns == modified_ns)
        {
            return Ok(h.sha256.clone());
        }
        let sha256 = hash_file(weights)?;
        recorded.retain(|h| h.path != path);
        recorded.push(WeightsHash {
            path,
            size,
            modified_ns,
            sha256: sha256.clone(),
        });
        Ok(sha256)
    }

    /// The model directory (canonical) and the hash of everything in it
    /// that decides an embedding: the configuration and tokenizer files
    /// (hashed every time: they are small) and the weights.
    fn model_key(&mut self, dir: &Path) -> Result<(String, String), ClipError> {
        let weights = weights_file(dir)?;
        let mut hasher = Sha256::new();
        for name in KEYED_FILES {
            let p = dir.join(name);
            if p.is_file() {
                let bytes = std::fs::read(&p).map_err(|e| ClipError::io(&p, e))?;
                // Name and length first: no two file sets hash alike by
                // moving bytes from one file to the next.
                hasher.update(name.as_bytes());
                hasher.update((bytes.len() as u64).to_le_bytes());
                hasher.update(&bytes);
            }
        }
        hasher.update(b"weights");
        hasher.update(self.weights_hash(&weights)?.as_bytes());
        let canonical = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
        Ok((canonical.display().to_string(), hex(&hasher.finalize())))
    }

    /// Reads `path`; a missing or unreadable cache is an empty one (it is
    /// only a cache).
    pub fn read(path: &Path) -> Self {
        std::fs::read_to_string(path)
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or_default()
    }

    /// Writes the cache (through a temporary file, so a reader never sees
    /// half of it).
    pub fn write(&self, path: &Path) -> Result<(), ClipError> {
        let text =
            serde_json::to_string(self).map_err(|e| ClipError::invalid(path, e.to_string()))?;
        let tmp = path.with_extension("json.tmp");
        std::fs::write(&tmp, text).map_err(|e| ClipError::io(&tmp, e))?;
        std::fs::rename(&tmp, path).map_err(|e| ClipError::io(path, e))
    }

    fn get(&self, model: &str, fingerprint: &str, text: &str) -> Option<&[f32]> {
        self.entries
            .iter()
            .find(|e| e.model == model && e.fingerprint == fingerprint && e.text == text)
            .map(|e| e.embedding.as_slice())
    }
}

/// Unit-length embeddings of `texts` by the model in `model_dir`, read from
/// and added to the cache file in `cache_dir` when one is given (a cache
/// that cannot be written is reported on stderr and skipped).
pub fn embed_texts(
    model_dir: &Path,
    texts: &[String],
    cache_dir: Option<&Path>,
    device: &Device,
) -> Result<Embedded, ClipError> {
    if let Some(t) = texts.iter().find(|t| t.trim().is_empty()) {
        return Err(ClipError::Text(format!(
            "empty text {t:?}: give some words to embed"
        )));
    }
    let cache_path: Option<PathBuf> = cache_dir.map(|d| d.join(CACHE_FILE));
    let mut cache = cache_path
        .as_deref()
        .map(EmbeddingCache::read)
        .unwrap_or_default();
    let hashes_before = cache.weights.clone();
    // Without a cache file there is nothing to look up: no hashing.
    let (model, fingerprint) = match cache_path {
        Some(_) => cache.model_key(model_dir)?,
        None => Default::default(),
    };
    let mut rows: Vec<Option<Vec<f32>>> = texts
        .iter()
        .map(|t| cache.get(&model, &fingerprint, t).map(<[f32]>::to_vec))
        .collect();
    let cached = rows.iter().filter(|r| r.is_some()).count();
    let missing: Vec<String> = texts
        .iter()
        .zip(&rows)
        .filter(|(_, r)| r.is_none())
        .map(|(t, _)| t.clone())
        .collect();
    let mut notes = Vec::new();
    if !missing.is_empty() {
        let m = TextModel::load(model_dir, device)?;
        notes = m.notes.clone();
        let mut fresh = m.embed(&missing)?.into_iter();
        for (t, r) in texts.iter().zip(rows.iter_mut()) {
            if r.is_none() {
                let e = fresh.next().unwrap_or_default();
                cache.entries.push(CacheEntry {
                    model: model.clone(),
                    fingerprint: fingerprint.clone(),
                    text: t.clone(),
                    embedding: e.clone(),
                });
                *r = Some(e);
            }
        }
        // Embeddings of this directory's earlier content are stale for good.
        cache
            .entries
            .retain(|e| e.model != model || e.fingerprint == fingerprint);
    }
    if let Some(p) = &cache_path
        && (!missing.is_empty() || cache.weights != hashes_before)
        && let Err(e) = cache.write(p)
    {
        eprintln!("note: text embeddings not cached: {e}");
    }
    let rows: Vec<Vec<f32>> = rows.into_iter().map(Option::unwrap_or_default).collect();
    let dim = rows.first().map_or(0, Vec::len);
    if rows.iter().any(|r| r.len() != dim || dim == 0) {
        return Err(ClipError::invalid(
            cache_path.unwrap_or_else(|| model_dir.to_path_buf()),
            "cached embeddings of different dimensions; delete the cache file",
        ));
    }
    Ok(Embedded {
        rows,
        dim,
        cached,
        notes,
    })
}
