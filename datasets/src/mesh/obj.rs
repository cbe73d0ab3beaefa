//! Wavefront OBJ reading through `tobj`: every object of the file merged
//! into one triangle mesh, checked, with the line at fault named when the
//! file is malformed.

use std::cell::RefCell;
use std::io::Cursor;
use std::path::Path;

use super::texture::{self, MtlFailure};
use super::{MeshFile, TriangleMesh};
use crate::error::DatasetError;

/// Reads a Wavefront OBJ file (polygons triangulated as fans, all objects
/// merged into one mesh), colouring the vertices from the diffuse texture
/// (`map_Kd`) of their material at their UV, else from the file's vertex
/// colours. What the mesh lacks (a missing material library or texture, so
/// no colour) is said once in [`MeshFile::notes`]; a malformed file (a face
/// index past the vertex list, no faces, a non-finite coordinate) is an
/// error naming the file and the problem.
pub fn read_obj(path: &Path) -> Result<MeshFile, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let failures: RefCell<Vec<MtlFailure>> = RefCell::new(Vec::new());
    // The update stays for the fields that tobj's `merging` and
    // `reordering` features add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        // Stray points and lines would become degenerate triangles.
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let loaded = tobj::load_obj_buf(&mut Cursor::new(&bytes), &options, |name| {
        let full = dir.join(name);
        // Read here rather than by tobj, which keeps no reason for a failure.
        let result = std::fs::read(&full)
            .map_err(|e| {
                let reason = match e.kind() {
                    std::io::ErrorKind::NotFound => "not found".to_string(),
                    _ => format!("cannot be read ({e})"),
                };
                (reason, tobj::LoadError::OpenFileFailed)
            })
            .and_then(|b| {
                tobj::load_mtl_buf(&mut Cursor::new(b))
                    .map_err(|e| (format!("cannot be parsed ({e})"), e))
            });
        result.map_err(|(reason, e)| {
            failures
                .borrow_mut()
                .push(MtlFailure { path: full, reason });
            e
        })
    });
    let (models, materials) = loaded.map_err(|e| describe_load_error(path, &bytes, e))?;
    // A failed library is already in `failures`; tobj returns the error
    // only when no other library loaded.
    let materials = materials.unwrap_or_default();
    let mut mesh = TriangleMesh::default();
    for model in &models {
        let m = &model.mesh;
        if mesh.positions.len() + m.positions.len() / 3 > u32::MAX as usize {
            return Err(DatasetError::invalid(path, "more than 2^32 vertices"));
        }
        let offset = mesh.positions.len() as u32;
        mesh.positions
            .extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        mesh.triangles.extend(
            m.indices
                .chunks_exact(3)
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }
    if mesh.triangles.is_empty() {
        return Err(DatasetError::invalid(
            path,
            format!(
                "the file has no faces ({}, no triangles or polygons): not a mesh",
                counted(count_lines(&bytes, "v") as i64, ("vertex", "vertices"))
            ),
        ));
    }
    if mesh.positions.iter().flatten().any(|x| !x.is_finite()) {
        let what = first_non_finite_vertex(&bytes)
            .unwrap_or_else(|| "a vertex has a non-finite coordinate".into());
        return Err(DatasetError::invalid(path, what));
    }
    let failures = failures.into_inner();
    let (colors, notes) = texture::colour(path, &dir, &models, &materials, &failures);
    mesh.colors = colors;
    Ok(MeshFile { mesh, notes })
}

/// The file's lines, numbered from 1, split into words.
fn lines(bytes: &[u8]) -> impl Iterator<Item = (usize, Vec<&str>)> {
    bytes.split(|&b| b == b'\n').enumerate().map(|(i, line)| {
        let words = std::str::from_utf8(line)
            .map(|l| l.split_whitespace().collect())
            .unwrap_or_default();
        (i + 1, words)
    })
}

/// Lines starting with `keyword`.
fn count_lines(bytes: &[u8], keyword: &str) -> usize {
    lines(bytes)
        .filter(|(_, w)| w.first() == Some(&keyword))
        .count()
}

/// `n` and the noun in the number it needs.
fn counted(n: i64, (one, many): (&str, &str)) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A file error for tobj's `e`, naming the line at fault where a scan of the
/// file finds it (tobj's errors say only what kind of problem it met).
fn describe_load_error(path: &Path, bytes: &[u8], e: tobj::LoadError) -> DatasetError {
    use tobj::LoadError as E;
    let detail = match e {
        E::FaceVertexOutOfBounds | E::FaceTexCoordOutOfBounds | E::FaceNormalOutOfBounds => {
            bad_face_index(bytes)
        }
        E::PositionParseError => bad_numbers(bytes, "v", 3, "vertex"),
        E::TexcoordParseError => bad_numbers(bytes, "vt", 2, "texture coordinate"),
        E::NormalParseError => bad_numbers(bytes, "vn", 3, "normal"),
        E::FaceParseError => bad_face_syntax(bytes),
        E::FaceColorOutOfBounds => {
            Some("some vertices have colours and others not (an 'r g b' after 'v x y z')".into())
        }
        E::ReadError => Some("cannot read the OBJ as text (is it UTF-8?)".into()),
        _ => None,
    };
    DatasetError::invalid(
        path,
        detail.unwrap_or_else(|| format!("cannot parse the OBJ: {e}")),
    )
}

/// The first face that refers past its list (vertices, texture coordinates
/// or normals), as tobj resolves indices: 1-based, negative ones relative
/// to the entries read so far.
fn bad_face_index(bytes: &[u8]) -> Option<String> {
    const KEYWORDS: [&str; 3] = ["v", "vt", "vn"];
    const NAMES: [(&str, &str); 3] = [
        ("vertex", "vertices"),
        ("texture coordinate", "texture coordinates"),
        ("normal", "normals"),
    ];
    let total = KEYWORDS.map(|k| count_lines(bytes, k) as i64);
    let mut seen = [0i64; 3];
    let mut face = 0usize;
    for (line, words) in lines(bytes) {
        let Some((&first, rest)) = words.split_first() else {
            continue;
        };
        if let Some(k) = KEYWORDS.iter().position(|&w| w == first) {
            seen[k] += 1;
            continue;
        }
        if first != "f" {
            continue;
        }
        face += 1;
        for word in rest {
            for (k, part) in word.split('/').enumerate().take(3) {
                let Ok(x) = part.parse::<i64>() else {
                    continue;
                };
                let at = format!("face {face} (line {line}) uses {} {x}", NAMES[k].0);
                if x == 0 {
                    return Some(format!("{at}, but OBJ indices start at 1"));
                }
                if x > total[k] {
                    return Some(format!(
                        "{at} but the file has {}",
                        counted(total[k], NAMES[k])
                    ));
                }
                if x < 0 && seen[k] + x < 0 {
                    return Some(format!(
                        "{at} (relative) but only {} precede it",
                        counted(seen[k], NAMES[k])
                    ));
                }
            }
        }
    }
    None
}

/// The first face with a corner that is not `v`, `v/vt`, `v//vn` or
/// `v/vt/vn` in integers.
fn bad_face_syntax(bytes: &[u8]) -> Option<String> {
    let mut face = 0;
    lines(bytes).find_map(|(line, words)| {
        if words.first() != Some(&"f") {
            return None;
        }
        face += 1;
        words[1..]
            .iter()
            .find(|w| {
                let parts: Vec<&str> = w.split('/').collect();
                parts.len() > 3
                    || parts[0].parse::<i64>().is_err()
                    || parts[1..]
                        .iter()
                        .any(|p| !p.is_empty() && p.parse::<i64>().is_err())
            })
            .map(|w| format!("face {face} (line {line}) has a malformed corner '{w}'"))
    })
}

/// The first `keyword` line whose `n` numbers do not all parse.
fn bad_numbers(bytes: &[u8], keyword: &str, n: usize, what: &str) -> Option<String> {
    lines(bytes).find_map(|(line, words)| {
        let ok = words.len() > n && words[1..=n].iter().all(|w| w.parse::<f64>().is_ok());
        (words.first() == Some(&keyword) && !ok).then(|| {
            format!(
                "line {line}: a {what} needs {n} numbers, found '{}'",
                words[1..].join(" ")
            )
        })
    })
}

/// The first vertex line with a coordinate that is not finite (tobj reads
/// `nan` and `inf` as numbers), or whose `w` makes one so.
fn first_non_finite_vertex(bytes: &[u8]) -> Option<String> {
    let mut vertex = 0;
    lines(bytes).find_map(|(line, words)| {
        if words.first() != Some(&"v") {
            return None;
        }
        vertex += 1;
        let xyz: Vec<f64> = words
            .iter()
            .skip(1)
            .filter_map(|w| w.parse().ok())
            .collect();
        let w = if xyz.len() == 4 { xyz[3] } else { 1.0 };
        xyz.iter().take(3).any(|x| !(x / w).is_finite()).then(|| {
            format!(
                "line {line}: vertex {vertex} has a non-finite coordinate ('{}')",
                words[1..].join(" ")
            )
        })
    })
}
