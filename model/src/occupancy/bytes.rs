//! The grid's byte format (`occupancy.bin` and the checkpoints' grid).
//!
//! Version 2 (`OCCGRID2`): magic, resolution (u64), update count (u64),
//! decay, min_opacity (f32), early_samples, early_updates, dilation (u32),
//! then the densities (f32), all little-endian. Version 1 (`OCCGRID1`, no
//! sampling or dilation fields) still loads, with the rules it was built
//! under: one sample per cell, no early updates, no dilation.
//!
//! As text (a checkpoint's JSON state), the same bytes in lower-case hex,
//! two digits a byte.

use super::{MAX_DILATION, MAX_EARLY_SAMPLES, OccupancyGrid};

const MAGIC_V1: &[u8; 8] = b"OCCGRID1";
const MAGIC_V2: &[u8; 8] = b"OCCGRID2";

impl OccupancyGrid {
    /// Serialises the grid (see the module's format); the bitfield is
    /// rebuilt on reading.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(44 + 4 * self.density.len());
        b.extend_from_slice(MAGIC_V2);
        b.extend_from_slice(&(self.resolution as u64).to_le_bytes());
        b.extend_from_slice(&self.updates.to_le_bytes());
        b.extend_from_slice(&self.decay.to_le_bytes());
        b.extend_from_slice(&self.min_opacity.to_le_bytes());
        b.extend_from_slice(&self.early_samples.to_le_bytes());
        b.extend_from_slice(&self.early_updates.to_le_bytes());
        b.extend_from_slice(&self.dilation.to_le_bytes());
        for d in &self.density {
            b.extend_from_slice(&d.to_le_bytes());
        }
        b
    }

    /// Reads [`OccupancyGrid::to_bytes`] (or a version 1 grid); `Err` names
    /// what is wrong.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        let m = MAGIC_V2.len();
        let v2 = match bytes.get(..m) {
            Some(magic) if magic == MAGIC_V2 => true,
            Some(magic) if magic == MAGIC_V1 => false,
            _ => return Err("not an occupancy grid (bad header)".into()),
        };
        let head = m + if v2 { 36 } else { 24 };
        if bytes.len() < head {
            return Err("not an occupancy grid (bad header)".into());
        }
        let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap_or([0; 8]));
        let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap_or([0; 4]));
        let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap_or([0; 4]));
        let resolution = u64_at(m) as usize;
        if resolution == 0 || resolution > 512 {
            return Err(format!("resolution {resolution} outside 1..=512"));
        }
        let (early_samples, early_updates, dilation) = if v2 {
            (u32_at(m + 24), u32_at(m + 28), u32_at(m + 32))
        } else {
            (1, 0, 0)
        };
        if !(1..=MAX_EARLY_SAMPLES).contains(&(early_samples as usize)) {
            return Err(format!(
                "early_samples {early_samples} outside 1..={MAX_EARLY_SAMPLES}"
            ));
        }
        if dilation as usize > MAX_DILATION {
            return Err(format!("dilation {dilation} above {MAX_DILATION}"));
        }
        let cells = resolution * resolution * resolution;
        if bytes.len() != head + 4 * cells {
            return Err(format!(
                "{} bytes where a {resolution}^3 grid has {}",
                bytes.len(),
                head + 4 * cells
            ));
        }
        let density: Vec<f32> = (0..cells).map(|c| f32_at(head + 4 * c)).collect();
        let mut grid = Self {
            resolution,
            density,
            bits: vec![0; cells.div_ceil(64)],
            updates: u64_at(m + 8),
            decay: f32_at(m + 16),
            min_opacity: f32_at(m + 20),
            early_samples,
            early_updates,
            dilation,
        };
        grid.refresh_bits();
        Ok(grid)
    }
}

/// Why a grid could not be read back from its hex text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GridDecodeError {
    /// The text has an odd number of characters.
    OddLength,
    /// Byte `index` (two characters, shown as `text`) is not two hex digits.
    NotHex {
        /// Index of the byte.
        index: usize,
        /// Its two characters (lossily decoded).
        text: String,
    },
    /// The bytes are not a grid ([`OccupancyGrid::from_bytes`]'s reason).
    Format(String),
}

impl std::fmt::Display for GridDecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GridDecodeError::OddLength => f.write_str("odd number of hex digits"),
            GridDecodeError::NotHex { index, text } => {
                write!(f, "byte {index}: {text:?} is not two hex digits")
            }
            GridDecodeError::Format(reason) => f.write_str(reason),
        }
    }
}

impl std::error::Error for GridDecodeError {}

impl OccupancyGrid {
    /// The grid's bytes ([`OccupancyGrid::to_bytes`]) as lower-case hex.
    pub fn to_hex(&self) -> String {
        self.to_bytes().iter().map(|b| format!("{b:02x}")).collect()
    }

    /// Reads [`OccupancyGrid::to_hex`]'s text.
    pub fn from_hex(hex: &str) -> Result<Self, GridDecodeError> {
        if !hex.len().is_multiple_of(2) {
            return Err(GridDecodeError::OddLength);
        }
        // Pairs of bytes, not of characters: a damaged state may hold any
        // text, and slicing a `str` inside a multi-byte character would panic.
        let digit = |c: u8| (c as char).to_digit(16);
        let bytes = hex
            .as_bytes()
            .chunks_exact(2)
            .enumerate()
            .map(|(index, pair)| match (digit(pair[0]), digit(pair[1])) {
                (Some(h), Some(l)) => Ok((h * 16 + l) as u8),
                _ => Err(GridDecodeError::NotHex {
                    index,
                    text: String::from_utf8_lossy(pair).into_owned(),
                }),
            })
            .collect::<Result<Vec<u8>, _>>()?;
        OccupancyGrid::from_bytes(&bytes).map_err(GridDecodeError::Format)
    }
}
