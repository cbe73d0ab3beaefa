//! Text embeddings computed once: a small JSON cache (in a run directory)
//! keyed by the model directory, its weights file's size and modification
//! time, and the text. The model is only loaded when a text is missing.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use serde::{Deserialize, Serialize};

use crate::error::ClipError;
use crate::model_dir::{TextModel, weights_file};

/// The cache file name inside a run directory.
pub const CACHE_FILE: &str = "text_embeddings_cache.json";

/// One cached embedding.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CacheEntry {
    /// The model directory (canonical path).
    pub model: String,
    /// Size and modification time of its weights file.
    pub fingerprint: String,
    /// The text as given.
    pub text: String,
    /// Its unit-length embedding.
    pub embedding: Vec<f32>,
}

/// The cache file's content.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EmbeddingCache {
    /// Every cached embedding.
    pub entries: Vec<CacheEntry>,
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

fn model_key(dir: &Path) -> Result<(String, String), ClipError> {
    let weights = weights_file(dir)?;
    let meta = std::fs::metadata(&weights).map_err(|e| ClipError::io(&weights, e))?;
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let canonical = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    Ok((
        canonical.display().to_string(),
        format!("{} bytes, modified {mtime}", meta.len()),
    ))
}

impl EmbeddingCache {
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
    let (model, fingerprint) = model_key(model_dir)?;
    let cache_path: Option<PathBuf> = cache_dir.map(|d| d.join(CACHE_FILE));
    let mut cache = cache_path
        .as_deref()
        .map(EmbeddingCache::read)
        .unwrap_or_default();
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
        if let Some(p) = &cache_path
            && let Err(e) = cache.write(p)
        {
            eprintln!("note: text embeddings not cached: {e}");
        }
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
