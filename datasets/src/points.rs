//! Point clouds: PLY reading (ascii and binary) and writing through
//! `ply-rs-bw`, per-point label files and class-id maps.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult,
    PropertyDef, PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

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

/// Header lines read ahead of the crate's parser to check for repeated
/// element or property names (see [`check_header_names`]).
const MAX_HEADER_LINES: usize = 10_000;

/// Points preallocated before the file's data has been seen (a header may
/// claim any count).
const MAX_PREALLOCATED_POINTS: usize = 1 << 20;

/// Rejects a header that names an element twice, or a property twice within
/// an element. `ply-rs-bw` keeps such declarations in a map, so a repeated
/// name silently replaces the earlier declaration (or moves a property to
/// another element) and the rows are then misread; this reads the header
/// lines (up to `end_header`) ahead of it to refuse such files.
fn check_header_names(path: &Path) -> Result<(), DatasetError> {
    let file = std::fs::File::open(path).map_err(|e| DatasetError::io(path, e))?;
    let mut elements: Vec<(String, Vec<String>)> = Vec::new();
    let mut line = Vec::new();
    let mut r = BufReader::new(file);
    for _ in 0..MAX_HEADER_LINES {
        line.clear();
        if r.read_until(b'\n', &mut line)
            .map_err(|e| DatasetError::io(path, e))?
            == 0
        {
            break;
        }
        let text = String::from_utf8_lossy(&line);
        let words: Vec<&str> = text.split_whitespace().collect();
        let dup = |what: &str, name: &str| {
            Err(DatasetError::invalid(
                path,
                format!("PLY header declares {what} '{name}' twice"),
            ))
        };
        match words.as_slice() {
            ["end_header"] => break,
            ["element", name, ..] => {
                if elements.iter().any(|(e, _)| e == name) {
                    return dup("element", name);
                }
                elements.push((name.to_string(), Vec::new()));
            }
            ["property", .., name] => {
                if let Some((element, props)) = elements.last_mut() {
                    if props.iter().any(|p| p == name) {
                        return dup(&format!("{element} property"), name);
                    }
                    props.push(name.to_string());
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// One vertex as read: every scalar property is widened to `f64`; list
/// properties and unknown names are ignored.
#[derive(Debug, Default)]
struct VertexIn {
    xyz: [f64; 3],
    /// Colour channels, already scaled to `[0, 255]` (float channels are
    /// given in `[0, 1]`).
    rgb: [f64; 3],
    /// Value of the preferred label property seen so far, with its rank in
    /// [`LABEL_NAMES`].
    label: Option<(usize, f64)>,
}

impl PropertyAccess for VertexIn {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let (v, is_float) = match property {
            Property::Char(v) => (v as f64, false),
            Property::UChar(v) => (v as f64, false),
            Property::Short(v) => (v as f64, false),
            Property::UShort(v) => (v as f64, false),
            Property::Int(v) => (v as f64, false),
            Property::UInt(v) => (v as f64, false),
            Property::Float(v) => (v as f64, true),
            Property::Double(v) => (v, true),
            _ => return PropertyAccessResult::Ignored,
        };
        let colour = if is_float { v * 255.0 } else { v };
        match name {
            "x" => self.xyz[0] = v,
            "y" => self.xyz[1] = v,
            "z" => self.xyz[2] = v,
            "red" => self.rgb[0] = colour,
            "green" => self.rgb[1] = colour,
            "blue" => self.rgb[2] = colour,
            _ => match LABEL_NAMES.iter().position(|&n| n == name) {
                Some(rank) if self.label.is_none_or(|(r, _)| rank < r) => {
                    self.label = Some((rank, v));
                }
                _ => return PropertyAccessResult::Ignored,
            },
        }
        PropertyAccessResult::Set
    }
}

/// An element read only to move past it.
struct Skipped;

impl PropertyAccess for Skipped {
    fn new() -> Self {
        Self
    }
}

/// Reads the vertex element of a PLY file (ascii, binary little or big
/// endian): `x`, `y`, `z` (required), `red`, `green`, `blue` (optional) and
/// a label property (`label`, `class`, `semantic`, `object_id`, ...;
/// optional).
pub fn read_ply(path: &Path) -> Result<PointCloud, DatasetError> {
    let bad = |m: String| DatasetError::invalid(path, m);
    check_header_names(path)?;
    let file = std::fs::File::open(path).map_err(|e| DatasetError::io(path, e))?;
    let mut reader = Reader::new(BufReader::new(file));
    let parser = Parser::<VertexIn>::new();
    let header = parser
        .read_header(&mut reader)
        .map_err(|e| bad(format!("bad PLY header: {e}")))?;
    let Some(vi) = header.elements.get_index_of("vertex") else {
        return Err(bad("PLY file has no vertex element".into()));
    };
    // Skip elements stored before the vertices.
    let skip = Parser::<Skipped>::new();
    for (name, e) in header.elements.iter().take(vi) {
        skip.read_payload_for_element(&mut reader, e, &header)
            .map_err(|err| bad(format!("cannot read element '{name}': {err}")))?;
    }
    let v = &header.elements[vi];
    if v.properties
        .values()
        .any(|p| matches!(p.data_type, PropertyType::List(..)))
    {
        return Err(bad(
            "vertex element has a list property (unsupported)".into()
        ));
    }
    let has = |n: &str| v.properties.contains_key(n);
    if let Some(k) = ["x", "y", "z"].into_iter().find(|&n| !has(n)) {
        return Err(bad(format!("vertex element has no '{k}' property")));
    }
    let has_rgb = ["red", "green", "blue"].into_iter().all(has);
    let has_label = LABEL_NAMES.into_iter().any(has);
    let capacity = v.count.min(MAX_PREALLOCATED_POINTS);
    let mut cloud = PointCloud {
        positions: Vec::with_capacity(capacity),
        colors: has_rgb.then(|| Vec::with_capacity(capacity)),
        labels: has_label.then(|| Vec::with_capacity(capacity)),
    };
    let mut line = String::new();
    for row in 0..v.count {
        let r = reader.get_mut();
        let vertex = match header.encoding {
            Encoding::Ascii => {
                line.clear();
                let n = r
                    .read_line(&mut line)
                    .map_err(|e| DatasetError::io(path, e))?;
                if n == 0 {
                    return Err(bad(format!(
                        "vertex {row}: expected {} values, file ends",
                        v.properties.len()
                    )));
                }
                parser.read_ascii_element(&line, v)
            }
            Encoding::BinaryLittleEndian => parser.read_little_endian_element(r, v),
            Encoding::BinaryBigEndian => parser.read_big_endian_element(r, v),
        }
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => {
                bad(format!("file is truncated at vertex {row} of {}", v.count))
            }
            _ => bad(format!("vertex {row}: {e}")),
        })?;
        if vertex.xyz.iter().any(|c| !c.is_finite()) {
            return Err(bad(format!("vertex {row} has a non-finite coordinate")));
        }
        cloud.positions.push(vertex.xyz);
        if let Some(colors) = cloud.colors.as_mut() {
            colors.push(vertex.rgb.map(|c| c.round().clamp(0.0, 255.0) as u8));
        }
        if let Some(labels) = cloud.labels.as_mut() {
            labels.push(vertex.label.map_or(0, |(_, l)| l as i64));
        }
    }
    Ok(cloud)
}

/// One vertex of `cloud` as written: a view of point `index` and its
/// `scalars`.
struct VertexOut<'a> {
    cloud: Option<&'a PointCloud>,
    scalars: &'a [(&'a str, &'a [f32])],
    index: usize,
}

impl PropertyAccess for VertexOut<'_> {
    fn new() -> Self {
        Self {
            cloud: None,
            scalars: &[],
            index: 0,
        }
    }

    fn get_float(&self, name: &str) -> Option<f32> {
        let i = self.index;
        match name {
            "x" => self.cloud.map(|c| c.positions[i][0] as f32),
            "y" => self.cloud.map(|c| c.positions[i][1] as f32),
            "z" => self.cloud.map(|c| c.positions[i][2] as f32),
            _ => self
                .scalars
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, s)| s[i]),
        }
    }

    fn get_uchar(&self, name: &str) -> Option<u8> {
        let k = ["red", "green", "blue"].iter().position(|&n| n == name)?;
        Some(self.cloud?.colors.as_ref()?[self.index][k])
    }

    fn get_int(&self, name: &str) -> Option<i32> {
        if name != "label" {
            return None;
        }
        Some(self.cloud?.labels.as_ref()?[self.index] as i32)
    }
}

/// Whether `name` can be read back as a property name by [`read_ply`]
/// (`ply-rs-bw`'s header grammar: a letter or `_`, then letters, digits,
/// `_` or `-`).
fn is_property_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
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
    let bad = |m: String| DatasetError::invalid(path, m);
    let bad_len = |what: &str, len: usize| bad(format!("{what} has {len} values for {n} points"));
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
    let scalar = |name: &str, t: ScalarType| PropertyDef::new(name.into(), PropertyType::Scalar(t));
    let mut vertex = ElementDef::new("vertex".into());
    vertex.count = n;
    let mut props = vec![
        scalar("x", ScalarType::Float),
        scalar("y", ScalarType::Float),
        scalar("z", ScalarType::Float),
    ];
    if cloud.colors.is_some() {
        for c in ["red", "green", "blue"] {
            props.push(scalar(c, ScalarType::UChar));
        }
    }
    if cloud.labels.is_some() {
        props.push(scalar("label", ScalarType::Int));
    }
    for (name, _) in scalars {
        if !is_property_name(name) {
            return Err(bad(format!("'{name}' is not a valid PLY property name")));
        }
        if props.iter().any(|p| p.name == *name) {
            return Err(bad(format!("property '{name}' is given twice")));
        }
        props.push(scalar(name, ScalarType::Float));
    }
    for p in props {
        vertex.properties.add(p);
    }
    let mut header = Header::new();
    header.encoding = Encoding::BinaryLittleEndian;
    header.elements.add(vertex.clone());
    let io = |e: std::io::Error| DatasetError::io(path, e);
    let file = std::fs::File::create(path).map_err(io)?;
    let mut out = std::io::BufWriter::new(file);
    let writer = Writer::<VertexOut<'_>>::new();
    writer.write_header(&mut out, &header).map_err(io)?;
    let mut row = VertexOut {
        cloud: Some(cloud),
        scalars,
        index: 0,
    };
    for i in 0..n {
        row.index = i;
        writer
            .write_little_endian_element(&mut out, &row, &vertex)
            .map_err(io)?;
    }
    out.flush().map_err(io)
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
