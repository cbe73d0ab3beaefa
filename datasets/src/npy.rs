//! Reading and writing `.npy` arrays of floats (f16 / f32 / f64, C order,
//! little endian), with validation that names the file and the problem.
//!
//! Headers are parsed by `npyz`; the data is read here directly so that a
//! slice of a large array (one feature map of a stacked file) can be read
//! without touching the rest.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use half::f16;
use npyz::{DType, Order, TypeChar};

use crate::error::DatasetError;

/// Element type of a float `.npy` array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NpyDtype {
    /// `<f2`
    F16,
    /// `<f4`
    F32,
    /// `<f8`
    F64,
}

impl NpyDtype {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            NpyDtype::F16 => 2,
            NpyDtype::F32 => 4,
            NpyDtype::F64 => 8,
        }
    }
}

/// The validated header of a float `.npy` file.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyInfo {
    /// The file.
    pub path: PathBuf,
    /// Element type.
    pub dtype: NpyDtype,
    /// Shape (C order).
    pub shape: Vec<usize>,
    /// Byte offset of the first element.
    pub data_offset: u64,
}

/// Counts the bytes the header parser consumes, to find where the data starts.
struct Counting<R> {
    inner: R,
    count: u64,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count += n as u64;
        Ok(n)
    }
}

impl NpyInfo {
    /// Reads and validates the header of `path`: a float dtype, C order, and a
    /// file long enough to hold all elements.
    pub fn open(path: &Path) -> Result<Self, DatasetError> {
        let mut file = File::open(path).map_err(|e| DatasetError::io(path, e))?;
        let file_len = file
            .metadata()
            .map_err(|e| DatasetError::io(path, e))?
            .len();
        check_header_len(path, &mut file, file_len)?;
        let mut reader = Counting {
            inner: BufReader::new(file),
            count: 0,
        };
        let header = npyz::NpyHeader::from_reader(&mut reader)
            .map_err(|e| DatasetError::invalid(path, format!("not a valid .npy header: {e}")))?;
        let dtype = match header.dtype() {
            DType::Plain(ts) => {
                let little = !matches!(ts.endianness(), npyz::Endianness::Big);
                match (ts.type_char(), ts.size_field(), little) {
                    (TypeChar::Float, 2, true) => NpyDtype::F16,
                    (TypeChar::Float, 4, true) => NpyDtype::F32,
                    (TypeChar::Float, 8, true) => NpyDtype::F64,
                    _ => {
                        return Err(DatasetError::invalid(
                            path,
                            format!(
                                "unsupported dtype {ts} (expected little-endian float16/32/64)"
                            ),
                        ));
                    }
                }
            }
            other => {
                return Err(DatasetError::invalid(
                    path,
                    format!("unsupported structured dtype {}", other.descr()),
                ));
            }
        };
        if header.order() == Order::Fortran && header.shape().iter().filter(|&&d| d > 1).count() > 1
        {
            return Err(DatasetError::invalid(
                path,
                "array is stored in Fortran order (expected C order)",
            ));
        }
        let shape: Vec<usize> = header.shape().iter().map(|&d| d as usize).collect();
        // A damaged or hostile header can announce a shape whose element
        // count wraps around; every later size computation relies on this.
        let need = shape
            .iter()
            .try_fold(1usize, |n, &d| n.checked_mul(d))
            .and_then(|n| n.checked_mul(dtype.size()))
            .and_then(|b| u64::try_from(b).ok())
            .and_then(|b| b.checked_add(reader.count))
            .ok_or_else(|| {
                DatasetError::invalid(
                    path,
                    format!(
                        "shape {shape:?} has more elements than can be addressed (damaged header?)"
                    ),
                )
            })?;
        let info = Self {
            path: path.to_path_buf(),
            dtype,
            shape,
            data_offset: reader.count,
        };
        if file_len < need {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "file is truncated: {file_len} bytes, but shape {:?} needs {need}",
                    info.shape
                ),
            ));
        }
        Ok(info)
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// Whether the array has no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Errors unless the array has rank `rank`; `what` describes the expected layout.
    pub fn expect_rank(&self, rank: usize, what: &str) -> Result<(), DatasetError> {
        if self.shape.len() != rank {
            return Err(DatasetError::invalid(
                &self.path,
                format!(
                    "expected a rank-{rank} array ({what}), found shape {:?}",
                    self.shape
                ),
            ));
        }
        Ok(())
    }

    /// Reads `count` elements starting at element `start`, as raw bytes.
    fn read_bytes(&self, start: usize, count: usize) -> Result<Vec<u8>, DatasetError> {
        if start.checked_add(count).is_none_or(|end| end > self.len()) {
            return Err(DatasetError::invalid(
                &self.path,
                format!(
                    "read of {count} elements from element {start} is past the end ({})",
                    self.len()
                ),
            ));
        }
        let mut file = File::open(&self.path).map_err(|e| DatasetError::io(&self.path, e))?;
        let size = self.dtype.size();
        file.seek(SeekFrom::Start(self.data_offset + (start * size) as u64))
            .map_err(|e| DatasetError::io(&self.path, e))?;
        let mut bytes = allocate(&self.path, count * size)?;
        file.read_exact(&mut bytes)
            .map_err(|e| DatasetError::io(&self.path, e))?;
        Ok(bytes)
    }

    /// Reads `count` elements from element `start`, converted to `f32`.
    pub fn read_f32_range(&self, start: usize, count: usize) -> Result<Vec<f32>, DatasetError> {
        let bytes = self.read_bytes(start, count)?;
        Ok(decode(&bytes, self.dtype, |v| v as f32, |h| h.to_f32()))
    }

    /// Reads `count` elements from element `start`, converted to `f16`.
    pub fn read_f16_range(&self, start: usize, count: usize) -> Result<Vec<f16>, DatasetError> {
        let bytes = self.read_bytes(start, count)?;
        Ok(decode(&bytes, self.dtype, f16::from_f64, |h| h))
    }

    /// Reads `count` elements from element `start`, converted to `f64`.
    pub fn read_f64_range(&self, start: usize, count: usize) -> Result<Vec<f64>, DatasetError> {
        let bytes = self.read_bytes(start, count)?;
        Ok(decode(&bytes, self.dtype, |v| v, |h| h.to_f64()))
    }
}

/// Refuses a header whose announced length runs past the end of the file.
/// `npyz` allocates the announced length (up to 4 GiB in format versions 2
/// and 3) before reading any of it, so a damaged length must not reach it.
/// Other preamble errors (magic, version) are left to `npyz`'s messages.
fn check_header_len(path: &Path, file: &mut File, file_len: u64) -> Result<(), DatasetError> {
    let mut pre = Vec::with_capacity(12);
    let io = |e| DatasetError::io(path, e);
    Read::by_ref(file)
        .take(12)
        .read_to_end(&mut pre)
        .map_err(io)?;
    file.seek(SeekFrom::Start(0)).map_err(io)?;
    if pre.len() < 10 || &pre[..6] != b"\x93NUMPY" {
        return Ok(());
    }
    let (len, start) = match (pre[6], pre.get(8..12)) {
        (1, _) => (u16::from_le_bytes([pre[8], pre[9]]) as u64, 10),
        (2 | 3, Some(b)) => (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64, 12),
        _ => return Ok(()),
    };
    if start + len > file_len {
        return Err(DatasetError::invalid(
            path,
            format!(
                "not a valid .npy header: it announces {len} bytes of header text, \
                 but the file has {file_len} bytes in all (damaged header?)"
            ),
        ));
    }
    Ok(())
}

/// Total physical memory in bytes (`MemTotal` of `/proc/meminfo`), where known.
fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

/// A zeroed buffer of `len` bytes for the data of `path`, or an error naming
/// the file when it cannot be held in memory. An allocation failure would
/// abort the process, and with memory overcommit a buffer larger than the
/// machine "succeeds" and is killed later, so both are checked up front.
fn allocate(path: &Path, len: usize) -> Result<Vec<u8>, DatasetError> {
    let too_large = |what: String| {
        DatasetError::invalid(
            path,
            format!(
                "reading this array needs {:.1} GB of memory, {what}; is the shape in its \
                 header right? (feature maps may be stored at a lower resolution than the images)",
                len as f64 / 1e9
            ),
        )
    };
    if let Some(total) = physical_memory()
        && len as u64 > total
    {
        return Err(too_large(format!(
            "more than this machine has ({:.1} GB)",
            total as f64 / 1e9
        )));
    }
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(len)
        .map_err(|_| too_large("which cannot be allocated".into()))?;
    bytes.resize(len, 0);
    Ok(bytes)
}

/// Decodes little-endian elements; `from_f64` converts f32/f64 values (via
/// f64, exact for both) and `from_f16` converts half values.
fn decode<T>(
    bytes: &[u8],
    dtype: NpyDtype,
    from_f64: impl Fn(f64) -> T,
    from_f16: impl Fn(f16) -> T,
) -> Vec<T> {
    match dtype {
        NpyDtype::F16 => bytes
            .chunks_exact(2)
            .map(|c| from_f16(f16::from_le_bytes([c[0], c[1]])))
            .collect(),
        NpyDtype::F32 => bytes
            .chunks_exact(4)
            .map(|c| from_f64(f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64))
            .collect(),
        NpyDtype::F64 => bytes
            .chunks_exact(8)
            .map(|c| {
                let mut a = [0u8; 8];
                a.copy_from_slice(c);
                from_f64(f64::from_le_bytes(a))
            })
            .collect(),
    }
}

/// Reads a whole float array as `f32`: `(shape, data)`.
pub fn read_npy_f32(path: &Path) -> Result<(Vec<usize>, Vec<f32>), DatasetError> {
    let info = NpyInfo::open(path)?;
    let data = info.read_f32_range(0, info.len())?;
    Ok((info.shape, data))
}

/// Reads a whole float array as `f64`: `(shape, data)`.
pub fn read_npy_f64(path: &Path) -> Result<(Vec<usize>, Vec<f64>), DatasetError> {
    let info = NpyInfo::open(path)?;
    let data = info.read_f64_range(0, info.len())?;
    Ok((info.shape, data))
}

/// Writes a version-1.0 header for `descr` and `shape`, padded so the data
/// starts on a 64-byte boundary as numpy does.
fn write_header(w: &mut impl Write, descr: &str, shape: &[usize]) -> std::io::Result<()> {
    let dims = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {dims}, }}");
    let unpadded = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    dict.push('\n');
    w.write_all(b"\x93NUMPY\x01\x00")?;
    w.write_all(&(dict.len() as u16).to_le_bytes())?;
    w.write_all(dict.as_bytes())
}

fn write_npy(
    path: &Path,
    descr: &str,
    shape: &[usize],
    n: usize,
    body: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), DatasetError> {
    if shape.iter().product::<usize>() != n {
        return Err(DatasetError::invalid(
            path,
            format!("shape {shape:?} does not match {n} values"),
        ));
    }
    let file = File::create(path).map_err(|e| DatasetError::io(path, e))?;
    let mut w = BufWriter::new(file);
    write_header(&mut w, descr, shape)
        .and_then(|_| body(&mut w))
        .and_then(|_| w.flush())
        .map_err(|e| DatasetError::io(path, e))
}

/// Writes `data` (C order) as a little-endian float16 `.npy` of `shape`.
pub fn write_npy_f16(path: &Path, shape: &[usize], data: &[f16]) -> Result<(), DatasetError> {
    write_npy(path, "<f2", shape, data.len(), |w| {
        data.iter().try_for_each(|v| w.write_all(&v.to_le_bytes()))
    })
}

/// Writes `data` (C order) as a little-endian float32 `.npy` of `shape`.
pub fn write_npy_f32(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), DatasetError> {
    write_npy(path, "<f4", shape, data.len(), |w| {
        data.iter().try_for_each(|v| w.write_all(&v.to_le_bytes()))
    })
}
