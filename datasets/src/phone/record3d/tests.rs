//! Record3D exports written by the tests: EXR + JPG, R3D as a ZIP archive
//! and unzipped, and broken ones.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::read_capture;
use crate::options::{LoaderOptions, PhoneOptions};
use crate::phone::{Capture, assemble};

/// Colour and depth sizes of the synthetic exports.
const W: u32 = 8;
const H: u32 = 6;
const DW: u32 = 4;
const DH: u32 = 3;

/// Frame `i`'s depth: distinct float32 values, with a NaN, an infinity and
/// a negative value (all no depth once loaded).
fn depth(i: usize) -> Vec<f32> {
    let mut d: Vec<f32> = (0..DW * DH)
        .map(|p| 0.5 + 0.123_457 * p as f32 + i as f32)
        .collect();
    d[1] = f32::NAN;
    d[2] = f32::INFINITY;
    d[3] = -1.0;
    d
}

fn confidence(i: usize) -> Vec<u8> {
    (0..DW * DH).map(|p| ((p as usize + i) % 3) as u8).collect()
}

fn jpeg(i: usize) -> Vec<u8> {
    let img = image::RgbImage::from_fn(W, H, |x, y| {
        image::Rgb([x as u8 * 30, y as u8 * 40, i as u8 * 100])
    });
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Jpeg).unwrap();
    bytes.into_inner()
}

fn metadata(k_len: usize, poses: usize) -> String {
    let k = [7.0, 0.0, 0.0, 0.0, 6.5, 0.0, 3.9, 2.8, 1.0];
    let s = (0.35f64).sin();
    let c = (0.35f64).cos();
    let all = [
        format!("[0, 0, {s}, {c}, 0.1, 0.2, 0.3]"),
        format!("[{s}, 0, 0, {c}, -1, 0.5, 2]"),
    ];
    format!(
        r#"{{"w": {W}, "h": {H}, "dw": {DW}, "dh": {DH}, "fps": 60, "K": {:?},
            "initPose": [0, 0, 0, 1, 0, 0, 0], "poses": [{}]}}"#,
        &k[..k_len],
        all[..poses].join(", ")
    )
}

fn lzfse(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    lzfse_rust::encode_bytes(bytes, &mut out).unwrap();
    out
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|d| d.to_le_bytes()).collect()
}

fn write(path: &Path, bytes: &[u8]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

fn write_exr(path: &Path, values: Vec<f32>) {
    use exr::prelude::*;
    let channel = AnyChannel::new("Z", FlatSamples::F32(values));
    let layer = Layer::new(
        (DW as usize, DH as usize),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

/// An EXR + JPG export of two frames in `dir`.
fn exr_jpg(dir: &Path) {
    write(&dir.join("metadata.json"), metadata(9, 2).as_bytes());
    for i in 0..2 {
        write(&dir.join(format!("rgb/{i}.jpg")), &jpeg(i));
        std::fs::create_dir_all(dir.join("depth")).unwrap();
        write_exr(&dir.join(format!("depth/{i}.exr")), depth(i));
        let conf = image::GrayImage::from_raw(DW, DH, confidence(i)).unwrap();
        std::fs::create_dir_all(dir.join("conf")).unwrap();
        conf.save(dir.join(format!("conf/{i}.png"))).unwrap();
    }
}

/// The entries of an R3D export of two frames (the depth of frame 0
/// replaced by `depth0` when given).
fn r3d_entries(meta: &str, depth0: Option<Vec<u8>>) -> Vec<(String, Vec<u8>)> {
    let mut entries = vec![("metadata".to_string(), meta.as_bytes().to_vec())];
    for i in 0..2 {
        entries.push((format!("rgbd/{i}.jpg"), jpeg(i)));
        let d = match (&depth0, i) {
            (Some(d), 0) => d.clone(),
            _ => lzfse(&f32_bytes(&depth(i))),
        };
        entries.push((format!("rgbd/{i}.depth"), d));
        entries.push((format!("rgbd/{i}.conf"), lzfse(&confidence(i))));
    }
    entries.push(("icon".into(), vec![1, 2, 3]));
    entries
}

/// `entries` as a ZIP archive at `path`, the images deflated, the rest
/// stored (the app does both).
fn write_zip(path: &Path, entries: &[(String, Vec<u8>)]) {
    use zip::write::SimpleFileOptions;
    let mut zip = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    for (name, bytes) in entries {
        let method = if name.ends_with(".jpg") {
            zip::CompressionMethod::Deflated
        } else {
            zip::CompressionMethod::Stored
        };
        zip.start_file(
            name.as_str(),
            SimpleFileOptions::default().compression_method(method),
        )
        .unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap();
}

fn r3d(dir: &Path, meta: &str, depth0: Option<Vec<u8>>) -> PathBuf {
    let path = dir.join("scan.r3d");
    write_zip(&path, &r3d_entries(meta, depth0));
    path
}

/// The frames' poses, intrinsics, loaded depth (as bits) and confidence.
type Loaded = Vec<(
    [[f64; 4]; 4],
    model::geometry::Intrinsics,
    Vec<u32>,
    Vec<u8>,
)>;

fn loaded(capture: &Capture) -> Loaded {
    capture
        .frames
        .iter()
        .map(|f| {
            let d = f.depth.as_ref().unwrap().load().unwrap();
            assert_eq!((d.width, d.height), (DW, DH));
            let c = f.confidence.as_ref().unwrap().load((DW, DH)).unwrap();
            let bits = d.to_f32().iter().map(|v| v.to_bits()).collect();
            (f.pose, f.intrinsics, bits, c)
        })
        .collect()
}

#[test]
fn exr_jpg_and_r3d_read_the_same() {
    let tmp = tempfile::tempdir().unwrap();
    let exr_dir = tmp.path().join("exr");
    exr_jpg(&exr_dir);
    let exr = read_capture(&exr_dir).unwrap();
    let zip = read_capture(&r3d(tmp.path(), &metadata(9, 2), None)).unwrap();
    let unzipped = tmp.path().join("unzipped");
    for (name, bytes) in r3d_entries(&metadata(9, 2), None) {
        write(&unzipped.join(name), &bytes);
    }
    let dir = read_capture(&unzipped).unwrap();
    assert_eq!(exr.frames.len(), 2);
    assert_eq!(exr.frames[1].name, "frame_00001");
    assert!(exr.mesh.is_none() && zip.mesh.is_none());
    let want = loaded(&exr);
    assert_eq!(loaded(&zip), want);
    assert_eq!(loaded(&dir), want);
    let k = exr.frames[0].intrinsics;
    assert_eq!(
        (k.width, k.height, k.fx, k.fy, k.cx, k.cy),
        (W, H, 7.0, 6.5, 3.9, 2.8)
    );
    // Depth loads as written, invalid values as 0.
    let mut expected = depth(1);
    expected[1..4].fill(0.0);
    let d = zip.frames[1].depth.as_ref().unwrap().load().unwrap();
    assert_eq!(d.to_f32(), expected);
    assert_eq!(
        zip.frames[1]
            .confidence
            .as_ref()
            .unwrap()
            .load((DW, DH))
            .unwrap(),
        confidence(1)
    );
    // Frame 0 rotates by 0.7 rad about z.
    let p = exr.frames[0].pose;
    assert!((p[0][0] - 0.7f64.cos()).abs() < 1e-12 && (p[1][0] - 0.7f64.sin()).abs() < 1e-12);
    assert_eq!([p[0][3], p[1][3], p[2][3]], [0.1, 0.2, 0.3]);
    // Entries are named `archive:entry`.
    let image = &zip.frames[0].image;
    assert!(
        image
            .describe()
            .to_string_lossy()
            .ends_with("scan.r3d:rgbd/0.jpg")
    );
    assert_eq!(image.dimensions().unwrap(), (W, H));
    assert!(
        zip.frames[0]
            .pose_file
            .to_string_lossy()
            .ends_with("scan.r3d:metadata")
    );
}

#[test]
fn r3d_assembles_into_a_scene() {
    let tmp = tempfile::tempdir().unwrap();
    let path = r3d(tmp.path(), &metadata(9, 2), None);
    let options = PhoneOptions::default();
    let loader = LoaderOptions::Record3d(options.clone());
    let scene = assemble(&path, &options, read_capture(&path).unwrap(), &loader)
        .unwrap()
        .scene;
    assert_eq!(scene.frames.len(), 2);
    assert_eq!(
        (scene.frames[0].rgb.width, scene.frames[0].rgb.height),
        (W, H)
    );
    assert!(scene.frames.iter().all(|f| f.depth.is_some()));
}

fn error(path: &Path) -> String {
    read_capture(path).unwrap_err().to_string()
}

#[test]
fn bad_exports_are_refused_with_the_file_named() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // Missing metadata.
    let dir = t.join("no_meta");
    exr_jpg(&dir);
    std::fs::remove_file(dir.join("metadata.json")).unwrap();
    let e = error(&dir);
    assert!(e.contains("metadata.json: missing"), "{e}");
    // K of 8 numbers.
    write(&dir.join("metadata.json"), metadata(8, 2).as_bytes());
    let e = error(&dir);
    assert!(
        e.contains("metadata.json: `K` has 8 numbers, expected 9 (a 3x3 matrix, column-major)"),
        "{e}"
    );
    // One pose for two images.
    write(&dir.join("metadata.json"), metadata(9, 1).as_bytes());
    let e = error(&dir);
    assert!(
        e.contains("metadata.json")
            && e.contains("`poses` has 1 entries")
            && e.contains("1.jpg is frame 1"),
        "{e}"
    );
    // No images.
    let empty = t.join("empty");
    std::fs::create_dir_all(empty.join("rgb")).unwrap();
    write(&empty.join("metadata.json"), metadata(9, 2).as_bytes());
    let e = error(&empty);
    assert!(e.contains("rgb: no images"), "{e}");
    // Neither layout.
    let e = error(t);
    assert!(e.contains("not a Record3D export"), "{e}");
}

#[test]
fn bad_r3d_maps_are_refused_with_the_entry_named() {
    let tmp = tempfile::tempdir().unwrap();
    let stream = lzfse(&f32_bytes(&depth(0)));
    // A truncated LZFSE stream.
    let path = r3d(
        tmp.path(),
        &metadata(9, 2),
        Some(stream[..stream.len() - 6].to_vec()),
    );
    let capture = read_capture(&path).unwrap();
    let e = capture.frames[0]
        .depth
        .as_ref()
        .unwrap()
        .load()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scan.r3d:rgbd/0.depth: not a complete LZFSE stream"),
        "{e}"
    );
    // A map of 4x2 values where the metadata says 4x3.
    let short = lzfse(&f32_bytes(&depth(0)[..8]));
    let path = r3d(tmp.path(), &metadata(9, 2), Some(short.clone()));
    let capture = read_capture(&path).unwrap();
    let e = capture.frames[0]
        .depth
        .as_ref()
        .unwrap()
        .load()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scan.r3d:rgbd/0.depth") && e.contains("32 bytes, expected 48 (4x3"),
        "{e}"
    );
    // Without dw/dh, a length of no known size.
    let meta = metadata(9, 2).replace(r#""dw": 4, "dh": 3,"#, "");
    let path = r3d(tmp.path(), &meta, Some(short));
    let capture = read_capture(&path).unwrap();
    assert!(
        capture.notes.iter().any(|n| n.contains("inferred")),
        "{:?}",
        capture.notes
    );
    let e = capture.frames[0]
        .depth
        .as_ref()
        .unwrap()
        .load()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("rgbd/0.depth") && e.contains("neither 256x192 nor 640x480"),
        "{e}"
    );
    // A confidence map of the wrong length.
    let conf = lzfse(&confidence(0)[..5]);
    let e = super::super::ConfidenceSource::LzfseU8(super::super::source::ByteSource::File(
        write_file(tmp.path(), "0.conf", &conf),
    ))
    .load((DW, DH))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("0.conf") && e.contains("5 bytes, expected 12"),
        "{e}"
    );
    // Not a ZIP archive.
    let e = error(&write_file(tmp.path(), "bad.r3d", b"not a zip"));
    assert!(e.contains("bad.r3d: not a readable ZIP archive"), "{e}");
}

fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    write(&p, bytes);
    p
}
