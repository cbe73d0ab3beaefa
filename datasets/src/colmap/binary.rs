//! COLMAP's binary sparse model (`cameras.bin`, `images.bin`,
//! `points3D.bin`), little-endian, as `colmap/scene/reconstruction_io.cc`
//! writes it:
//!
//! ```text
//! cameras.bin   u64 count, per camera: u32 id, i32 model, u64 width,
//!               u64 height, f64 params[n(model)]
//! images.bin    u64 count, per image: u32 id, f64 qw qx qy qz, f64 tx ty tz,
//!               u32 camera id, NUL-terminated name, u64 n,
//!               n x (f64 x, f64 y, u64 point3D id; u64::MAX = none)
//! points3D.bin  u64 count, per point: u64 id, f64 xyz, u8 rgb, f64 error,
//!               u64 track length, track x (u32 image id, u32 point2D index)
//! ```
//!
//! Counts are never trusted for allocation: preallocation is capped by
//! what the rest of the file can hold, and a record that runs past the end
//! is reported as a truncated file.

use std::collections::BTreeMap;
use std::path::Path;

use super::model::{Camera, CameraModel, Image, Point2D, Point3D, check_point, insert_camera};
use crate::error::DatasetError;

/// A read position in a file's bytes; every read is `None` past the end.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len())?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Some(s)
    }

    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        self.take(N)?.try_into().ok()
    }

    fn u8(&mut self) -> Option<u8> {
        Some(self.array::<1>()?[0])
    }

    fn u32(&mut self) -> Option<u32> {
        self.array().map(u32::from_le_bytes)
    }

    fn i32(&mut self) -> Option<i32> {
        self.array().map(i32::from_le_bytes)
    }

    fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }

    fn f64(&mut self) -> Option<f64> {
        self.array().map(f64::from_le_bytes)
    }

    fn f64s<const N: usize>(&mut self) -> Option<[f64; N]> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64()?;
        }
        Some(out)
    }

    /// A NUL-terminated string (the NUL is consumed).
    fn c_string(&mut self) -> Option<&'a [u8]> {
        let len = self.bytes[self.pos..].iter().position(|&b| b == 0)?;
        let s = self.take(len)?;
        self.pos += 1;
        Some(s)
    }

    /// `count` records of at least `min_size` bytes each: is there room?
    /// Returns a safe capacity to preallocate.
    fn capacity(&self, count: u64, min_size: usize) -> Option<usize> {
        let fits = (self.remaining() / min_size.max(1)) as u64;
        (count <= fits).then_some(count as usize)
    }
}

/// Reads a whole file.
fn read_bytes(path: &Path) -> Result<Vec<u8>, DatasetError> {
    std::fs::read(path).map_err(|e| DatasetError::io(path, e))
}

/// The "truncated" error of record `i` (0-based) of `count`.
fn truncated(path: &Path, what: &str, i: u64, count: u64) -> DatasetError {
    DatasetError::invalid(
        path,
        format!(
            "truncated: {what} {} of {count} ends past the end of the file",
            i + 1
        ),
    )
}

/// The record count at the start of a file, with a capacity safe to
/// preallocate for records of at least `min_size` bytes.
fn header(
    path: &Path,
    cur: &mut Cursor<'_>,
    what: &str,
    min_size: usize,
) -> Result<(u64, usize), DatasetError> {
    let count = cur.u64().ok_or_else(|| {
        DatasetError::invalid(path, "truncated: the file is shorter than its 8-byte count")
    })?;
    let cap = cur.capacity(count, min_size).ok_or_else(|| {
        DatasetError::invalid(
            path,
            format!(
                "truncated: the header announces {count} {what}s but only {} bytes follow",
                cur.remaining()
            ),
        )
    })?;
    Ok((count, cap))
}

/// Refuses bytes after the last record (a wrong or corrupted file).
fn expect_end(path: &Path, cur: &Cursor<'_>, what: &str, count: u64) -> Result<(), DatasetError> {
    match cur.remaining() {
        0 => Ok(()),
        n => Err(DatasetError::invalid(
            path,
            format!("{n} unexpected bytes after the last of {count} {what}s"),
        )),
    }
}

/// Reads `cameras.bin`.
pub fn read_cameras(path: &Path) -> Result<BTreeMap<u32, Camera>, DatasetError> {
    let bytes = read_bytes(path)?;
    let mut cur = Cursor::new(&bytes);
    let (count, _) = header(path, &mut cur, "camera", 24)?;
    let mut cameras = BTreeMap::new();
    for i in 0..count {
        let fixed = (|| Some((cur.u32()?, cur.i32()?, cur.u64()?, cur.u64()?)))();
        let (id, model_id, width, height) =
            fixed.ok_or_else(|| truncated(path, "camera", i, count))?;
        let model = CameraModel::from_id(model_id).ok_or_else(|| {
            DatasetError::invalid(
                path,
                format!("camera {id}: unknown camera model id {model_id}"),
            )
        })?;
        let params = (0..model.num_params())
            .map(|_| cur.f64())
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| truncated(path, "camera", i, count))?;
        let camera = Camera {
            id,
            model,
            width,
            height,
            params,
        };
        insert_camera(path, &mut cameras, camera)?;
    }
    expect_end(path, &cur, "camera", count)?;
    Ok(cameras)
}

/// One image record, `None` when it runs past the end.
fn image_record(path: &Path, cur: &mut Cursor<'_>) -> Option<Result<Image, DatasetError>> {
    let id = cur.u32()?;
    let qvec = cur.f64s::<4>()?;
    let tvec = cur.f64s::<3>()?;
    let camera_id = cur.u32()?;
    let name = match String::from_utf8(cur.c_string()?.to_vec()) {
        Ok(n) => n,
        Err(_) => {
            let msg = format!("image {id}: the name is not UTF-8");
            return Some(Err(DatasetError::invalid(path, msg)));
        }
    };
    let n = cur.u64()?;
    let mut points2d = Vec::with_capacity(cur.capacity(n, 24)?);
    for _ in 0..n {
        let xy = cur.f64s::<2>()?;
        let id3 = cur.u64()?;
        points2d.push(Point2D {
            xy,
            point3d_id: (id3 != u64::MAX).then_some(id3),
        });
    }
    Some(Ok(Image {
        id,
        qvec,
        tvec,
        camera_id,
        name,
        points2d,
    }))
}

/// Reads `images.bin`.
pub fn read_images(path: &Path) -> Result<Vec<Image>, DatasetError> {
    let bytes = read_bytes(path)?;
    let mut cur = Cursor::new(&bytes);
    let (count, cap) = header(path, &mut cur, "image", 73)?;
    let mut images = Vec::with_capacity(cap);
    for i in 0..count {
        let image =
            image_record(path, &mut cur).ok_or_else(|| truncated(path, "image", i, count))??;
        if image.name.is_empty() {
            return Err(DatasetError::invalid(
                path,
                format!("image {} has an empty name", image.id),
            ));
        }
        images.push(image);
    }
    expect_end(path, &cur, "image", count)?;
    Ok(images)
}

/// One point record, `None` when it runs past the end.
fn point_record(cur: &mut Cursor<'_>) -> Option<Point3D> {
    let id = cur.u64()?;
    let xyz = cur.f64s::<3>()?;
    let rgb = [cur.u8()?, cur.u8()?, cur.u8()?];
    let error = cur.f64()?;
    let n = cur.u64()?;
    let mut track = Vec::with_capacity(cur.capacity(n, 8)?);
    for _ in 0..n {
        track.push((cur.u32()?, cur.u32()?));
    }
    Some(Point3D {
        id,
        xyz,
        rgb,
        error,
        track,
    })
}

/// Reads `points3D.bin`; a point with a non-finite coordinate is an error.
pub fn read_points(path: &Path) -> Result<Vec<Point3D>, DatasetError> {
    let bytes = read_bytes(path)?;
    let mut cur = Cursor::new(&bytes);
    let (count, cap) = header(path, &mut cur, "point", 43)?;
    let mut points = Vec::with_capacity(cap);
    for i in 0..count {
        let p = point_record(&mut cur).ok_or_else(|| truncated(path, "point", i, count))?;
        check_point(path, &p)?;
        points.push(p);
    }
    expect_end(path, &cur, "point", count)?;
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).expect("write");
        p
    }

    fn camera_bytes() -> Vec<u8> {
        let mut b = 1u64.to_le_bytes().to_vec();
        b.extend(7u32.to_le_bytes());
        b.extend(1i32.to_le_bytes());
        b.extend(64u64.to_le_bytes());
        b.extend(48u64.to_le_bytes());
        for v in [50.0f64, 51.0, 32.0, 24.0] {
            b.extend(v.to_le_bytes());
        }
        b
    }

    #[test]
    fn reads_a_camera_and_refuses_cut_or_padded_files() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = write(dir.path(), "cameras.bin", &camera_bytes());
        let cams = read_cameras(&p).expect("valid");
        assert_eq!(cams[&7].params, [50.0, 51.0, 32.0, 24.0]);
        assert_eq!((cams[&7].width, cams[&7].height), (64, 48));
        let full = camera_bytes();
        let p = write(dir.path(), "cut.bin", &full[..full.len() - 3]);
        let msg = read_cameras(&p).expect_err("cut").to_string();
        assert!(msg.contains("truncated: camera 1 of 1"), "{msg}");
        let mut padded = full.clone();
        padded.push(0);
        let p = write(dir.path(), "pad.bin", &padded);
        assert!(read_cameras(&p).is_err());
    }

    #[test]
    fn huge_counts_are_refused_before_allocating() {
        let dir = tempfile::tempdir().expect("tmp");
        let mut b = u64::MAX.to_le_bytes().to_vec();
        b.extend([0u8; 100]);
        let p = write(dir.path(), "images.bin", &b);
        let msg = read_images(&p).expect_err("huge").to_string();
        assert!(
            msg.contains("truncated") && msg.contains("announces"),
            "{msg}"
        );
        // A point whose track length is huge.
        let mut b = 1u64.to_le_bytes().to_vec();
        b.extend(1u64.to_le_bytes());
        b.extend([0u8; 24 + 3 + 8]);
        b.extend(u64::MAX.to_le_bytes());
        let p = write(dir.path(), "points3D.bin", &b);
        let msg = read_points(&p).expect_err("huge").to_string();
        assert!(msg.contains("truncated: point 1 of 1"), "{msg}");
    }
}
