//! Reading named tensors from a safetensors file as `f32`, with errors that
//! name the file and the tensor.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use safetensors::{Dtype, SafeTensors};

use crate::error::{ClipError, read_file};

/// One tensor, converted to `f32`, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct HostTensor {
    /// The shape.
    pub shape: Vec<usize>,
    /// The values.
    pub data: Vec<f32>,
}

/// The tensors of one safetensors file (all of them, as `f32`).
#[derive(Debug, Clone)]
pub struct TensorFile {
    /// The file they were read from.
    pub path: PathBuf,
    tensors: BTreeMap<String, HostTensor>,
    /// Tensors of other types (e.g. integer position ids), by name.
    skipped: BTreeMap<String, Dtype>,
}

impl TensorFile {
    /// Reads every floating-point tensor (f32, f16, bf16 or f64) of `path`
    /// whose name `keep` accepts; others are only listed (see
    /// [`TensorFile::take`]).
    pub fn read(path: &Path, keep: impl Fn(&str) -> bool) -> Result<Self, ClipError> {
        let bytes = read_file(path, "weights (safetensors)")?;
        let st = SafeTensors::deserialize(&bytes)
            .map_err(|e| ClipError::invalid(path, format!("not a safetensors file: {e}")))?;
        let mut tensors = BTreeMap::new();
        let mut skipped = BTreeMap::new();
        for (name, view) in st.tensors() {
            if !keep(&name) {
                continue;
            }
            match to_f32(view.dtype(), view.data()) {
                Some(data) => {
                    let shape = view.shape().to_vec();
                    tensors.insert(name, HostTensor { shape, data });
                }
                None => {
                    skipped.insert(name, view.dtype());
                }
            }
        }
        Ok(Self {
            path: path.to_path_buf(),
            tensors,
            skipped,
        })
    }

    /// A file's worth of tensors made in memory (tests, conversions).
    pub fn from_tensors(path: &Path, tensors: BTreeMap<String, HostTensor>) -> Self {
        Self {
            path: path.to_path_buf(),
            tensors,
            skipped: BTreeMap::new(),
        }
    }

    /// Whether the file holds a tensor called `name`.
    pub fn contains(&self, name: &str) -> bool {
        self.tensors.contains_key(name)
    }

    /// The tensor names, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.tensors.keys().map(String::as_str)
    }

    /// The shape of `name`, if present.
    pub fn shape(&self, name: &str) -> Option<&[usize]> {
        self.tensors.get(name).map(|t| t.shape.as_slice())
    }

    /// Removes and returns tensor `name`, which must have shape `expected`.
    pub fn take(
        &mut self,
        name: &str,
        expected: &[usize],
        layout: &'static str,
    ) -> Result<HostTensor, ClipError> {
        if let Some(dtype) = self.skipped.get(name) {
            return Err(ClipError::invalid(
                &self.path,
                format!(
                    "tensor {name:?} is {dtype:?}; expected a float type (F32, F16, BF16, F64)"
                ),
            ));
        }
        let t = self
            .tensors
            .remove(name)
            .ok_or_else(|| ClipError::MissingTensor {
                path: self.path.clone(),
                name: name.to_string(),
                layout,
            })?;
        if t.shape != expected {
            return Err(ClipError::TensorShape {
                path: self.path.clone(),
                name: name.to_string(),
                expected: expected.to_vec(),
                found: t.shape,
            });
        }
        Ok(t)
    }

    /// Removes and returns tensor `name` if the file has it (with shape `expected`).
    pub fn take_optional(
        &mut self,
        name: &str,
        expected: &[usize],
        layout: &'static str,
    ) -> Result<Option<HostTensor>, ClipError> {
        if self.contains(name) {
            self.take(name, expected, layout).map(Some)
        } else {
            Ok(None)
        }
    }
}

fn to_f32(dtype: Dtype, bytes: &[u8]) -> Option<Vec<f32>> {
    let chunks = |n: usize| bytes.chunks_exact(n);
    Some(match dtype {
        Dtype::F32 => chunks(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        Dtype::F16 => chunks(2)
            .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
            .collect(),
        Dtype::BF16 => chunks(2)
            .map(|c| half::bf16::from_le_bytes([c[0], c[1]]).to_f32())
            .collect(),
        Dtype::F64 => chunks(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]) as f32)
            .collect(),
        _ => return None,
    })
}

/// The transpose of a row-major `[rows, cols]` matrix.
pub fn transpose(data: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    let mut out = vec![0.0; data.len()];
    for r in 0..rows {
        for c in 0..cols {
            out[c * rows + r] = data[r * cols + c];
        }
    }
    out
}

/// Writes `tensors` as a float32 safetensors file.
pub fn write_f32(path: &Path, tensors: &BTreeMap<String, HostTensor>) -> Result<(), ClipError> {
    let bytes: Vec<(String, Vec<usize>, Vec<u8>)> = tensors
        .iter()
        .map(|(name, t)| {
            let raw = t.data.iter().flat_map(|v| v.to_le_bytes()).collect();
            (name.clone(), t.shape.clone(), raw)
        })
        .collect();
    let views = bytes
        .iter()
        .map(|(name, shape, raw)| {
            safetensors::tensor::TensorView::new(Dtype::F32, shape.clone(), raw)
                .map(|v| (name.clone(), v))
                .map_err(|e| ClipError::invalid(path, format!("tensor {name:?}: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    safetensors::serialize_to_file(views, None, path)
        .map_err(|e| ClipError::invalid(path, format!("cannot write safetensors: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors_name_file_and_tensor() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("w.safetensors");
        let mut m = BTreeMap::new();
        m.insert(
            "a".to_string(),
            HostTensor {
                shape: vec![2, 3],
                data: vec![1., 2., 3., 4., 5., 6.],
            },
        );
        write_f32(&path, &m).unwrap();
        let mut f = TensorFile::read(&path, |_| true).unwrap();
        let e = f.take("a", &[3, 2], "test").unwrap_err().to_string();
        assert!(
            e.contains("w.safetensors") && e.contains("\"a\"") && e.contains("[2, 3]"),
            "{e}"
        );
        let mut f = TensorFile::read(&path, |_| true).unwrap();
        assert_eq!(f.take("a", &[2, 3], "test").unwrap().data[5], 6.0);
        let e = f.take("b", &[1], "test").unwrap_err().to_string();
        assert!(e.contains("no tensor \"b\""), "{e}");
        assert_eq!(
            transpose(&[1., 2., 3., 4., 5., 6.], 2, 3),
            vec![1., 4., 2., 5., 3., 6.]
        );
        std::fs::write(&path, b"not safetensors").unwrap();
        let e = TensorFile::read(&path, |_| true).unwrap_err().to_string();
        assert!(e.contains("not a safetensors file"), "{e}");
    }
}
