//! Inputs whose sizes are wrong in ways that used to panic, abort or pass
//! silently: `.npy` headers whose shape overflows, feature maps too large for
//! memory, and truncated JPEG frames. Each gives an error naming the file.

use std::io::Write;
use std::path::Path;

use datasets::DatasetError;
use datasets::features::{FeatureSource, PcaSetting, load_features};
use datasets::imageio::{jpeg_truncation, load_rgb};
use datasets::replica::{ReplicaOptions, load_replica};

fn assert_err<T>(r: Result<T, DatasetError>, file: &str, words: &[&str]) {
    let msg = match r {
        Ok(_) => panic!("expected an error mentioning {file}"),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains(file), "error {msg:?} does not name {file}");
    for w in words {
        assert!(msg.contains(w), "error {msg:?} does not mention {w:?}");
    }
    // Shown with `--nocapture`: the message a user gets for this input.
    eprintln!("refused: {msg}");
}

/// A float16 `.npy` with the header for `shape` followed by `body` bytes and
/// then extended (sparsely, without writing) to `total_len` bytes.
fn npy_with_shape(path: &Path, shape: &[u64], body: &[u8], total_len: Option<u64>) {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let tuple = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let mut dict = format!("{{'descr': '<f2', 'fortran_order': False, 'shape': {tuple}, }}");
    while !(10 + dict.len() + 1).is_multiple_of(64) {
        dict.push(' ');
    }
    dict.push('\n');
    let mut f = std::fs::File::create(path).expect("create");
    f.write_all(b"\x93NUMPY\x01\x00").expect("write");
    f.write_all(&(dict.len() as u16).to_le_bytes())
        .expect("write");
    f.write_all(dict.as_bytes()).expect("write");
    f.write_all(body).expect("write");
    if let Some(len) = total_len {
        f.set_len(len).expect("a sparse file can be extended");
    }
}

/// Minimised from a fuzzed `.npy`: a version-2/3 header announcing up to
/// 4 GiB of header text in a file of a few bytes. The header parser
/// allocated the announced length before reading any of it.
#[test]
fn npy_header_longer_than_its_file_is_refused_before_allocating() {
    let dir = tempfile::tempdir().expect("tmp");
    for (name, bytes) in [
        ("v3.npy", &b"\x93NUMPY\x03\x00F\x00{'descr': '<f8', }"[..]),
        ("v2.npy", &b"\x93NUMPY\x02\x00\xff\xff\xff\xff{}"[..]),
        ("v1.npy", &b"\x93NUMPY\x01\x00\xff\xff{}"[..]),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).expect("write");
        assert_err(
            datasets::npy::NpyInfo::open(&p),
            name,
            &["header", "announces"],
        );
    }
}

/// A 4:3 map shape (the images are 80x60, and maps must keep the aspect
/// ratio) whose element count is a multiple of 2^64: it wraps to 0.
const WRAPPING_MAP: [u64; 3] = [3 << 60, 1 << 62, 16];

#[test]
fn per_frame_npy_whose_shape_overflows_is_refused() {
    let dir = tempfile::tempdir().expect("tmp");
    let a = dir.path().join("a.npy");
    let b = dir.path().join("b.npy");
    npy_with_shape(&a, &WRAPPING_MAP, &[0; 64], None);
    npy_with_shape(&b, &WRAPPING_MAP, &[0; 64], None);
    let src = FeatureSource::PerFrame(vec![a, b]);
    assert_err(
        load_features(&src, &[(80, 60), (80, 60)], PcaSetting::Off, 0),
        "a.npy",
        &["more elements than can be addressed"],
    );
}

#[test]
fn stacked_npy_whose_shape_overflows_is_refused() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("stacked.npy");
    let mut shape = vec![2];
    shape.extend(WRAPPING_MAP);
    npy_with_shape(&p, &shape, &[0; 64], None);
    let src = FeatureSource::Stacked(p);
    assert_err(
        load_features(&src, &[(80, 60), (80, 60)], PcaSetting::Off, 0),
        "stacked.npy",
        &["more elements than can be addressed"],
    );
}

#[test]
fn feature_map_larger_than_memory_is_an_error_not_an_abort() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("huge.npy");
    // 300000 x 400000 x 16 float16: 3.84 TB, a sparse file that really
    // holds that many bytes, so the header check passes.
    let shape = [300_000u64, 400_000, 16];
    let bytes: u64 = shape.iter().product::<u64>() * 2;
    npy_with_shape(&p, &shape, &[], Some(128 + bytes));
    assert!(datasets::npy::NpyInfo::open(dir.path().join("huge.npy").as_path()).is_ok());
    let src = FeatureSource::PerFrame(vec![p]);
    assert_err(
        load_features(&src, &[(80, 60)], PcaSetting::Off, 0),
        "huge.npy",
        &["GB of memory"],
    );
}

fn jpeg_bytes() -> Vec<u8> {
    // Busy content, so that most of the file is image data after the headers.
    let img = image::RgbImage::from_fn(64, 48, |x, y| {
        image::Rgb([
            (x * 37 % 251) as u8,
            (y * 53 % 241) as u8,
            ((x * y) % 256) as u8,
        ])
    });
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb8(img)
        .write_to(&mut out, image::ImageFormat::Jpeg)
        .expect("encode");
    out.into_inner()
}

#[test]
fn truncated_jpeg_is_refused_and_a_complete_one_loads() {
    let dir = tempfile::tempdir().expect("tmp");
    let bytes = jpeg_bytes();
    assert_eq!(jpeg_truncation(&bytes), None);
    let good = dir.path().join("good.jpg");
    std::fs::write(&good, &bytes).expect("write");
    assert_eq!(
        load_rgb(&good, None, None).expect("complete jpeg").width,
        64
    );
    let cut = dir.path().join("cut.jpg");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).expect("write");
    assert_err(load_rgb(&cut, None, None), "cut.jpg", &["truncated"]);
}

#[test]
fn replica_scene_with_a_truncated_jpeg_frame_is_refused() {
    let dir = tempfile::tempdir().expect("tmp");
    let results = dir.path().join("results");
    std::fs::create_dir(&results).expect("mkdir");
    std::fs::write(
        dir.path().join("cam_params.json"),
        r#"{"camera": {"w": 64, "h": 48, "fx": 50.0, "fy": 50.0, "cx": 31.5, "cy": 23.5, "scale": 1000.0}}"#,
    )
    .expect("write");
    let bytes = jpeg_bytes();
    for i in 0..2 {
        let body = if i == 1 {
            &bytes[..bytes.len() * 3 / 4]
        } else {
            &bytes[..]
        };
        std::fs::write(results.join(format!("frame{i:06}.jpg")), body).expect("jpg");
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(64, 48, image::Luma([2000]))
            .save(results.join(format!("depth{i:06}.png")))
            .expect("png");
    }
    let pose = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
    std::fs::write(dir.path().join("traj.txt"), format!("{pose}\n{pose}\n")).expect("write");
    assert_err(
        load_replica(dir.path(), &ReplicaOptions::default()),
        "frame000001.jpg",
        &["truncated"],
    );
}
