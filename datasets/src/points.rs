//! Point clouds: PLY reading (ascii and binary little endian) and writing,
//! per-point label files and class-id maps.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

use crate::error::DatasetError;

/// Class index of points without a known class.
pub const IGNORE_LABEL: u32 = u32::MAX;

/// Property names recognised as a per-point label, in order of preference.
const LABEL_NAMES: [&str; 8] = [
    "label",
    "class",
    "semantic",
    "semantic_id",
    "class_id",
    "category_id",
    "object_id",
    "instance",
];

/// Points with optional colours and raw label ids.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointCloud {
    /// Positions, metres.
    pub positions: Vec<[f64; 3]>,
    /// 8-bit colours, when the file has them.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Raw label ids as stored in the file.
    pub labels: Option<Vec<i64>>,
}

/// Scalar types a PLY property may have.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Self::F32 | Self::F64)
    }

    /// Decodes one little-endian value (`b.len() == self.size()`).
    fn decode_le(self, b: &[u8]) -> f64 {
        match self {
            Self::I8 => b[0] as i8 as f64,
            Self::U8 => b[0] as f64,
            Self::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Self::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Self::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Self::F64 => {
                let mut a = [0u8; 8];
                a.copy_from_slice(b);
                f64::from_le_bytes(a)
            }
        }
    }
}

/// One element declaration of a PLY header.
struct Element {
    name: String,
    count: usize,
    /// Scalar properties; `None` type marks a list property.
    props: Vec<(String, Option<Scalar>)>,
}

#[derive(PartialEq)]
enum Format {
    Ascii,
    BinaryLe,
}

fn parse_header(path: &Path, r: &mut impl BufRead) -> Result<(Format, Vec<Element>), DatasetError> {
    let bad = |m: String| DatasetError::invalid(path, m);
    let mut line = String::new();
    let mut next = |line: &mut String| -> Result<bool, DatasetError> {
        line.clear();
        let n = r.read_line(line).map_err(|e| DatasetError::io(path, e))?;
        Ok(n > 0)
    };
    if !next(&mut line)? || line.trim() != "ply" {
        return Err(bad("not a PLY file (missing 'ply' magic)".into()));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if !next(&mut line)? {
            return Err(bad("PLY header has no end_header".into()));
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            ["format", "ascii", _] => format = Some(Format::Ascii),
            ["format", "binary_little_endian", _] => format = Some(Format::BinaryLe),
            ["format", other, ..] => return Err(bad(format!("unsupported PLY format '{other}'"))),
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| bad(format!("bad element count '{count}'")))?,
                props: Vec::new(),
            }),
            ["property", "list", _, _, name] => match elements.last_mut() {
                Some(e) => e.props.push((name.to_string(), None)),
                None => return Err(bad("property before any element".into())),
            },
            ["property", ty, name] => {
                let s = Scalar::parse(ty)
                    .ok_or_else(|| bad(format!("unknown property type '{ty}'")))?;
                match elements.last_mut() {
                    Some(e) => e.props.push((name.to_string(), Some(s))),
                    None => return Err(bad("property before any element".into())),
                }
            }
            _ => {
                return Err(bad(format!(
                    "unrecognised PLY header line '{}'",
                    line.trim()
                )));
            }
        }
    }
    let format = format.ok_or_else(|| bad("PLY header has no format line".into()))?;
    Ok((format, elements))
}

/// Reads the vertex element of a PLY file: `x`, `y`, `z` (required), `red`,
/// `green`, `blue` (optional) and a label property (`label`, `class`,
/// `semantic`, `object_id`, ...; optional).
pub fn read_ply(path: &Path) -> Result<PointCloud, DatasetError> {
    let file = std::fs::File::open(path).map_err(|e| DatasetError::io(path, e))?;
    let mut r = BufReader::new(file);
    let (format, elements) = parse_header(path, &mut r)?;
    let bad = |m: String| DatasetError::invalid(path, m);
    let vi = elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| bad("PLY file has no vertex element".into()))?;
    // Skip elements stored before the vertices.
    for e in &elements[..vi] {
        skip_element(path, &mut r, e, &format)?;
    }
    let v = &elements[vi];
    if v.props.iter().any(|(_, t)| t.is_none()) {
        return Err(bad(
            "vertex element has a list property (unsupported)".into()
        ));
    }
    let find = |n: &str| v.props.iter().position(|(p, _)| p.as_str() == n);
    let xyz = ["x", "y", "z"].map(find);
    if let Some(k) = xyz.iter().position(|i| i.is_none()) {
        return Err(bad(format!(
            "vertex element has no '{}' property",
            ["x", "y", "z"][k]
        )));
    }
    let rgb = ["red", "green", "blue"].map(find);
    let has_rgb = rgb.iter().all(|i| i.is_some());
    let label = LABEL_NAMES.iter().find_map(|n| find(n));
    let types: Vec<Scalar> = v.props.iter().filter_map(|(_, t)| *t).collect();
    let mut values = vec![0f64; types.len()];
    let mut cloud = PointCloud {
        positions: Vec::with_capacity(v.count),
        colors: has_rgb.then(|| Vec::with_capacity(v.count)),
        labels: label.map(|_| Vec::with_capacity(v.count)),
    };
    let mut line = String::new();
    let row_size: usize = types.iter().map(|t| t.size()).sum();
    let mut buf = vec![0u8; row_size];
    for row in 0..v.count {
        if format == Format::Ascii {
            line.clear();
            let n = r
                .read_line(&mut line)
                .map_err(|e| DatasetError::io(path, e))?;
            let words: Vec<&str> = line.split_whitespace().collect();
            if n == 0 || words.len() < types.len() {
                return Err(bad(format!(
                    "vertex {row}: expected {} values, file ends or line is short",
                    types.len()
                )));
            }
            for (k, w) in words.iter().take(types.len()).enumerate() {
                values[k] = w
                    .parse()
                    .map_err(|_| bad(format!("vertex {row}: '{w}' is not a number")))?;
            }
        } else {
            r.read_exact(&mut buf)
                .map_err(|_| bad(format!("file is truncated at vertex {row} of {}", v.count)))?;
            let mut off = 0;
            for (k, t) in types.iter().enumerate() {
                values[k] = t.decode_le(&buf[off..off + t.size()]);
                off += t.size();
            }
        }
        let p = xyz.map(|i| values[i.unwrap_or(0)]);
        if p.iter().any(|c| !c.is_finite()) {
            return Err(bad(format!("vertex {row} has a non-finite coordinate")));
        }
        cloud.positions.push(p);
        if let Some(colors) = cloud.colors.as_mut() {
            colors.push(rgb.map(|i| {
                let i = i.unwrap_or(0);
                let c = if types[i].is_float() {
                    values[i] * 255.0
                } else {
                    values[i]
                };
                c.round().clamp(0.0, 255.0) as u8
            }));
        }
        if let (Some(labels), Some(i)) = (cloud.labels.as_mut(), label) {
            labels.push(values[i] as i64);
        }
    }
    Ok(cloud)
}

fn skip_element(
    path: &Path,
    r: &mut impl BufRead,
    e: &Element,
    format: &Format,
) -> Result<(), DatasetError> {
    if *format == Format::Ascii {
        let mut line = String::new();
        for _ in 0..e.count {
            line.clear();
            r.read_line(&mut line)
                .map_err(|err| DatasetError::io(path, err))?;
        }
        return Ok(());
    }
    let mut size = 0usize;
    for (name, t) in &e.props {
        match t {
            Some(t) => size += t.size(),
            None => {
                return Err(DatasetError::invalid(
                    path,
                    format!("cannot skip list property '{name}' stored before the vertices"),
                ));
            }
        }
    }
    let n = (size * e.count) as u64;
    let copied = std::io::copy(&mut r.take(n), &mut std::io::sink())
        .map_err(|err| DatasetError::io(path, err))?;
    if copied != n {
        return Err(DatasetError::invalid(path, "file is truncated"));
    }
    Ok(())
}

/// Writes a binary little-endian PLY with `x y z` (float), `red green blue`
/// (uchar) and `label` (int) when present, and one float property per entry
/// of `scalars` (e.g. relevancy scores), each with one value per point.
pub fn write_ply(
    path: &Path,
    cloud: &PointCloud,
    scalars: &[(&str, &[f32])],
) -> Result<(), DatasetError> {
    let n = cloud.positions.len();
    let bad_len = |what: &str, len: usize| {
        DatasetError::invalid(path, format!("{what} has {len} values for {n} points"))
    };
    if let Some(c) = &cloud.colors
        && c.len() != n
    {
        return Err(bad_len("colors", c.len()));
    }
    if let Some(l) = &cloud.labels
        && l.len() != n
    {
        return Err(bad_len("labels", l.len()));
    }
    for (name, s) in scalars {
        if s.len() != n {
            return Err(bad_len(name, s.len()));
        }
    }
    let mut header = format!("ply\nformat binary_little_endian 1.0\nelement vertex {n}\n");
    header.push_str("property float x\nproperty float y\nproperty float z\n");
    if cloud.colors.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    if cloud.labels.is_some() {
        header.push_str("property int label\n");
    }
    for (name, _) in scalars {
        header.push_str(&format!("property float {name}\n"));
    }
    header.push_str("end_header\n");
    let mut out = Vec::with_capacity(header.len() + n * (16 + 4 * scalars.len()));
    out.extend_from_slice(header.as_bytes());
    for i in 0..n {
        for c in cloud.positions[i] {
            out.extend_from_slice(&(c as f32).to_le_bytes());
        }
        if let Some(c) = &cloud.colors {
            out.extend_from_slice(&c[i]);
        }
        if let Some(l) = &cloud.labels {
            out.extend_from_slice(&(l[i] as i32).to_le_bytes());
        }
        for (_, s) in scalars {
            out.extend_from_slice(&s[i].to_le_bytes());
        }
    }
    let mut f = std::fs::File::create(path).map_err(|e| DatasetError::io(path, e))?;
    f.write_all(&out).map_err(|e| DatasetError::io(path, e))
}

/// Reads one integer label per line (blank lines skipped); the count must be
/// `expected_len` (the number of points).
pub fn read_labels_txt(path: &Path, expected_len: usize) -> Result<Vec<i64>, DatasetError> {
    let lines = crate::text::read_lines(path)?;
    if lines.len() != expected_len {
        return Err(DatasetError::invalid(
            path,
            format!(
                "{} labels but the point cloud has {expected_len} points",
                lines.len()
            ),
        ));
    }
    lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            l.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && v.fract() == 0.0)
                .map(|v| v as i64)
                .ok_or_else(|| {
                    DatasetError::invalid(
                        path,
                        format!("line {}: '{l}' is not an integer label", i + 1),
                    )
                })
        })
        .collect()
}

/// Maps raw label ids to class indices into `names`.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassMap {
    /// Class names; a class index is a position in this list.
    pub names: Vec<String>,
    index: HashMap<i64, u32>,
}

impl ClassMap {
    /// Reads Replica's `replica_class_id_to_names.txt` (`id name` per line);
    /// negative ids (`-1 undefined`) are left out, so they map to
    /// [`IGNORE_LABEL`].
    pub fn load_replica(path: &Path) -> Result<Self, DatasetError> {
        let mut names = Vec::new();
        let mut index = HashMap::new();
        for (i, line) in crate::text::read_lines(path)?.iter().enumerate() {
            let (id, name) = line.split_once(char::is_whitespace).ok_or_else(|| {
                DatasetError::invalid(path, format!("line {}: expected 'id name'", i + 1))
            })?;
            let id: i64 = id.parse().map_err(|_| {
                DatasetError::invalid(path, format!("line {}: '{id}' is not an integer id", i + 1))
            })?;
            if id < 0 {
                continue;
            }
            if index.insert(id, names.len() as u32).is_some() {
                return Err(DatasetError::invalid(
                    path,
                    format!("class id {id} appears twice"),
                ));
            }
            names.push(name.trim().to_string());
        }
        Ok(Self { names, index })
    }

    /// Ids `0..names.len()` map to themselves.
    pub fn identity(names: Vec<String>) -> Self {
        let index = (0..names.len()).map(|i| (i as i64, i as u32)).collect();
        Self { names, index }
    }

    /// Class index of every id ([`IGNORE_LABEL`] for unknown ids).
    pub fn map(&self, ids: &[i64]) -> Vec<u32> {
        ids.iter()
            .map(|id| self.index.get(id).copied().unwrap_or(IGNORE_LABEL))
            .collect()
    }
}
