//! Text embeddings of class names (`C x D` `.npy`) with their labels file.

use std::path::Path;

use crate::error::DatasetError;
use crate::npy::{NpyInfo, write_npy_f32};

/// Class names with one embedding row each.
#[derive(Debug, Clone, PartialEq)]
pub struct TextEmbeddings {
    /// Class names, one per row.
    pub names: Vec<String>,
    /// Embedding dimension D.
    pub dim: usize,
    /// `C x D` values, row-major, as stored (not renormalised).
    pub data: Vec<f32>,
}

/// Reads a text file and returns its non-empty trimmed lines.
pub(crate) fn read_lines(path: &Path) -> Result<Vec<String>, DatasetError> {
    let text = std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))?;
    Ok(text
        .lines()
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect())
}

impl TextEmbeddings {
    /// Loads `npy` (`C x D`, f16/f32/f64) and `labels` (one name per line;
    /// blank lines skipped). The counts must agree and values be finite.
    pub fn load(npy: &Path, labels: &Path) -> Result<Self, DatasetError> {
        let info = NpyInfo::open(npy)?;
        info.expect_rank(2, "classes x embedding dim")?;
        let data = info.read_f32_range(0, info.len())?;
        if data.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::invalid(
                npy,
                "embeddings contain NaN or infinite values",
            ));
        }
        let names = read_lines(labels)?;
        if names.len() != info.shape[0] {
            return Err(DatasetError::invalid(
                labels,
                format!(
                    "{} labels but {} has {} embedding rows",
                    names.len(),
                    npy.display(),
                    info.shape[0]
                ),
            ));
        }
        Ok(Self {
            names,
            dim: info.shape[1],
            data,
        })
    }

    /// Writes the embeddings as float32 `.npy` and the names one per line.
    pub fn save(&self, npy: &Path, labels: &Path) -> Result<(), DatasetError> {
        write_npy_f32(npy, &[self.names.len(), self.dim], &self.data)?;
        let mut text = self.names.join("\n");
        text.push('\n');
        std::fs::write(labels, text).map_err(|e| DatasetError::io(labels, e))
    }

    /// Embedding of class `i`.
    pub fn row(&self, i: usize) -> &[f32] {
        &self.data[i * self.dim..(i + 1) * self.dim]
    }

    /// Number of classes.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there are no classes.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Index of the class called `name` (exact match).
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }
}
