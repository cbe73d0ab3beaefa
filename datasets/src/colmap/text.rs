//! COLMAP's text sparse model (`cameras.txt`, `images.txt`,
//! `points3D.txt`), as `colmap/scene/reconstruction_io.cc` writes it:
//!
//! ```text
//! cameras.txt   CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]
//! images.txt    IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME
//!               POINTS2D[] as (X, Y, POINT3D_ID; -1 = none)
//! points3D.txt  POINT3D_ID X Y Z R G B ERROR TRACK[] as (IMAGE_ID, POINT2D_IDX)
//! ```
//!
//! Empty lines and lines starting with `#` are skipped, except that the
//! line after an image's line is always its (possibly empty) 2D points, as
//! COLMAP reads it.

use std::collections::BTreeMap;
use std::path::Path;
use std::str::FromStr;

use super::model::{Camera, CameraModel, Image, Point2D, Point3D, check_point, insert_camera};
use crate::error::DatasetError;

/// Reads a whole file as text.
fn read_text(path: &Path) -> Result<String, DatasetError> {
    std::fs::read_to_string(path).map_err(|e| DatasetError::io(path, e))
}

/// A content error at 1-based line `line`.
fn at(path: &Path, line: usize, message: impl std::fmt::Display) -> DatasetError {
    DatasetError::invalid(path, format!("line {line}: {message}"))
}

/// Parses token `what` of a line.
fn parse<T: FromStr>(
    path: &Path,
    line: usize,
    what: &str,
    tok: Option<&str>,
) -> Result<T, DatasetError> {
    let tok = tok.ok_or_else(|| at(path, line, format!("missing {what}")))?;
    tok.parse()
        .map_err(|_| at(path, line, format!("bad {what} {tok:?}")))
}

/// The lines that carry data: `(1-based number, trimmed text)`.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// Refuses tokens left over at the end of a line.
fn expect_end<'a>(
    path: &Path,
    line: usize,
    mut toks: impl Iterator<Item = &'a str>,
) -> Result<(), DatasetError> {
    match toks.next() {
        None => Ok(()),
        Some(t) => Err(at(
            path,
            line,
            format!("unexpected {t:?} at the end of the line"),
        )),
    }
}

/// Reads `cameras.txt`.
pub fn read_cameras(path: &Path) -> Result<BTreeMap<u32, Camera>, DatasetError> {
    let text = read_text(path)?;
    let mut cameras = BTreeMap::new();
    for (n, line) in data_lines(&text) {
        let mut toks = line.split_whitespace();
        let id = parse(path, n, "camera id", toks.next())?;
        let name = toks.next().unwrap_or_default();
        let model = CameraModel::from_name(name).ok_or_else(|| {
            at(
                path,
                n,
                format!("camera {id}: unknown camera model {name:?}"),
            )
        })?;
        let width = parse(path, n, "width", toks.next())?;
        let height = parse(path, n, "height", toks.next())?;
        let params = (0..model.num_params())
            .map(|k| {
                parse(
                    path,
                    n,
                    &format!("{} parameter {}", model.name(), k + 1),
                    toks.next(),
                )
            })
            .collect::<Result<Vec<f64>, _>>()?;
        expect_end(path, n, toks)?;
        let camera = Camera {
            id,
            model,
            width,
            height,
            params,
        };
        insert_camera(path, &mut cameras, camera)?;
    }
    Ok(cameras)
}

/// An image's line, without its 2D points.
fn image_line(path: &Path, n: usize, line: &str) -> Result<Image, DatasetError> {
    let mut toks = line.split_whitespace();
    let id = parse(path, n, "image id", toks.next())?;
    let mut q = [0.0; 4];
    for (v, what) in q.iter_mut().zip(["QW", "QX", "QY", "QZ"]) {
        *v = parse(path, n, what, toks.next())?;
    }
    let mut t = [0.0; 3];
    for (v, what) in t.iter_mut().zip(["TX", "TY", "TZ"]) {
        *v = parse(path, n, what, toks.next())?;
    }
    let camera_id = parse(path, n, "camera id", toks.next())?;
    let name: Vec<&str> = toks.collect();
    if name.is_empty() {
        return Err(at(path, n, format!("image {id} has no name")));
    }
    Ok(Image {
        id,
        qvec: q,
        tvec: t,
        camera_id,
        name: name.join(" "),
        points2d: Vec::new(),
    })
}

/// An image's 2D points line.
fn points2d_line(path: &Path, n: usize, line: &str) -> Result<Vec<Point2D>, DatasetError> {
    let toks: Vec<&str> = line.split_whitespace().collect();
    if !toks.len().is_multiple_of(3) {
        return Err(at(
            path,
            n,
            format!(
                "2D points come in triples (X Y POINT3D_ID), found {} values",
                toks.len()
            ),
        ));
    }
    toks.chunks_exact(3)
        .map(|c| {
            let x = parse(path, n, "2D point x", Some(c[0]))?;
            let y = parse(path, n, "2D point y", Some(c[1]))?;
            let id: i64 = parse(path, n, "3D point id", Some(c[2]))?;
            Ok(Point2D {
                xy: [x, y],
                point3d_id: u64::try_from(id).ok(),
            })
        })
        .collect()
}

/// Reads `images.txt` (two lines per image).
pub fn read_images(path: &Path) -> Result<Vec<Image>, DatasetError> {
    let text = read_text(path)?;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let mut images = Vec::new();
    while let Some((n, line)) = lines.next() {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut image = image_line(path, n, line)?;
        if let Some((n2, points)) = lines.next() {
            image.points2d = points2d_line(path, n2, points)?;
        }
        images.push(image);
    }
    Ok(images)
}

/// Reads `points3D.txt`; a point with a non-finite coordinate is an error.
pub fn read_points(path: &Path) -> Result<Vec<Point3D>, DatasetError> {
    let text = read_text(path)?;
    let mut points = Vec::new();
    for (n, line) in data_lines(&text) {
        let toks: Vec<&str> = line.split_whitespace().collect();
        let tok = |i: usize| toks.get(i).copied();
        let id = parse(path, n, "point id", tok(0))?;
        let xyz = [
            parse(path, n, "X", tok(1))?,
            parse(path, n, "Y", tok(2))?,
            parse(path, n, "Z", tok(3))?,
        ];
        let rgb = [
            parse(path, n, "R", tok(4))?,
            parse(path, n, "G", tok(5))?,
            parse(path, n, "B", tok(6))?,
        ];
        let error = parse(path, n, "error", tok(7))?;
        let rest = toks.get(8..).unwrap_or_default();
        if !rest.len().is_multiple_of(2) {
            return Err(at(
                path,
                n,
                format!("point {id}: the track has an odd number of values"),
            ));
        }
        let track = rest
            .chunks_exact(2)
            .map(|c| {
                Ok((
                    parse(path, n, "track image id", Some(c[0]))?,
                    parse(path, n, "track point index", Some(c[1]))?,
                ))
            })
            .collect::<Result<Vec<_>, DatasetError>>()?;
        let p = Point3D {
            id,
            xyz,
            rgb,
            error,
            track,
        };
        check_point(path, &p)?;
        points.push(p);
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_keep_their_empty_points_line_and_names_with_spaces() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("images.txt");
        std::fs::write(
            &p,
            "# header\n1 1 0 0 0 0 0 0 3 a b.png\n\n\
             2 1 0 0 0 1 2 3 3 c.png\n1.5 2.5 -1 3 4 7\n",
        )
        .expect("write");
        let images = read_images(&p).expect("valid");
        assert_eq!(images.len(), 2);
        assert_eq!(images[0].name, "a b.png");
        assert!(images[0].points2d.is_empty());
        assert_eq!(images[1].tvec, [1.0, 2.0, 3.0]);
        assert_eq!(images[1].points2d[0].point3d_id, None);
        assert_eq!(images[1].points2d[1].point3d_id, Some(7));
    }

    #[test]
    fn bad_tokens_name_the_line() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("cameras.txt");
        std::fs::write(&p, "# c\n1 PINHOLE 10 8 5 5 4.5\n").expect("write");
        let msg = read_cameras(&p).expect_err("short").to_string();
        assert!(
            msg.contains("line 2") && msg.contains("PINHOLE parameter 4"),
            "{msg}"
        );
        std::fs::write(&p, "1 PINHOLE 10 8 5 5 4.5 3.5 9\n").expect("write");
        assert!(read_cameras(&p).is_err());
        let p = dir.path().join("points3D.txt");
        std::fs::write(&p, "4 0 nan 1 255 0 0 0.5 1 0\n").expect("write");
        let msg = read_points(&p).expect_err("nan").to_string();
        assert!(msg.contains("point 4"), "{msg}");
    }
}
