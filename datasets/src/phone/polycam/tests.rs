//! Polycam exports written by the tests.

use std::path::{Path, PathBuf};

use super::read_capture;

/// Frame `stamp`'s camera-to-world: distinct numbers in every cell (not a
/// rotation: rigidity is checked when the scene is assembled).
fn pose(stamp: u64, shift: f64) -> [[f64; 4]; 3] {
    std::array::from_fn(|r| {
        std::array::from_fn(|c| (stamp * 100 + 10 * r as u64 + c as u64) as f64 / 7.0 + shift)
    })
}

fn camera_json(stamp: u64, shift: f64) -> String {
    let mut keys = vec![
        r#""fx": 700.5, "fy": 702.25, "cx": 511.5, "cy": 383.75, "width": 1024, "height": 768,
           "blur_score": 12.5"#
            .to_string(),
    ];
    for (r, row) in pose(stamp, shift).iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            keys.push(format!(r#""t_{r}{c}": {v}"#));
        }
    }
    format!("{{{}}}", keys.join(", "))
}

fn write(path: &Path, bytes: &[u8]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

fn png8(path: &Path, values: Vec<u8>) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let w = values.len() as u32;
    image::GrayImage::from_raw(w, 1, values)
        .unwrap()
        .save(path)
        .unwrap();
}

/// An export with raw and corrected keyframes for `stamps` (raw poses
/// shifted by 1), depth and confidence for all but the last stamp.
fn export(dir: &Path, stamps: &[u64]) -> PathBuf {
    let k = dir.join("keyframes");
    let jpeg = {
        let mut bytes = std::io::Cursor::new(Vec::new());
        image::RgbImage::new(8, 6)
            .write_to(&mut bytes, image::ImageFormat::Jpeg)
            .unwrap();
        bytes.into_inner()
    };
    for (n, &s) in stamps.iter().enumerate() {
        for (images, cameras, shift) in [
            ("images", "cameras", 1.0),
            ("corrected_images", "corrected_cameras", 0.0),
        ] {
            write(&k.join(images).join(format!("{s}.jpg")), &jpeg);
            write(
                &k.join(cameras).join(format!("{s}.json")),
                camera_json(s, shift).as_bytes(),
            );
        }
        if n + 1 < stamps.len() {
            let depth =
                image::ImageBuffer::<image::Luma<u16>, _>::from_raw(4, 3, vec![1500u16; 12])
                    .unwrap();
            std::fs::create_dir_all(k.join("depth")).unwrap();
            depth
                .save(k.join("depth").join(format!("{s}.png")))
                .unwrap();
            png8(
                &k.join("confidence").join(format!("{s}.png")),
                vec![0, 1, 2, 2],
            );
        }
    }
    k
}

#[test]
fn corrected_keyframes_are_preferred_and_read_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let keyframes = export(tmp.path(), &[10, 9, 100]);
    let capture = read_capture(tmp.path()).unwrap();
    assert!(
        capture.notes[0].contains("corrected"),
        "{:?}",
        capture.notes
    );
    assert!(
        capture
            .notes
            .iter()
            .any(|n| n.contains("1 of 3 frames have no depth")),
        "{:?}",
        capture.notes
    );
    let names: Vec<&str> = capture.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["frame_9", "frame_10", "frame_100"]);
    let f = &capture.frames[0];
    let want = pose(9, 0.0);
    assert_eq!(f.pose, [want[0], want[1], want[2], [0.0, 0.0, 0.0, 1.0]]);
    assert_eq!(f.pose_file, keyframes.join("corrected_cameras/9.json"));
    assert_eq!(f.image.path(), keyframes.join("corrected_images/9.jpg"));
    let k = f.intrinsics;
    assert_eq!(
        (k.width, k.height, k.fx, k.fy, k.cx, k.cy),
        (1024, 768, 700.5, 702.25, 511.5, 383.75)
    );
    assert_eq!(f.blur_score, Some(12.5));
    let d = f.depth.as_ref().unwrap().load().unwrap();
    assert_eq!((d.width, d.height, d.value(0)), (4, 3, 1.5));
    assert!(capture.frames[2].depth.is_none() && capture.mesh.is_none());
    // The keyframes directory itself, and the raw keyframes without the
    // corrected ones.
    std::fs::remove_dir_all(keyframes.join("corrected_cameras")).unwrap();
    let raw = read_capture(&keyframes).unwrap();
    assert!(
        raw.notes[0].contains("not bundle-adjusted"),
        "{:?}",
        raw.notes
    );
    let want = pose(9, 1.0);
    assert_eq!(raw.frames[0].pose[..3], want);
    assert_eq!(raw.frames[0].image.path(), keyframes.join("images/9.jpg"));
}

#[test]
fn confidence_is_levels_or_scaled_levels() {
    let tmp = tempfile::tempdir().unwrap();
    let load = |values: Vec<u8>| {
        let p = tmp.path().join("c.png");
        png8(&p, values.clone());
        super::ConfidenceSource::PngScaled(p).load((values.len() as u32, 1))
    };
    assert_eq!(load(vec![0, 1, 2, 1]).unwrap(), [0, 1, 2, 1]);
    assert_eq!(load(vec![0, 127, 255, 128, 0]).unwrap(), [0, 1, 2, 1, 0]);
    for bad in [vec![0, 1, 255], vec![0, 100, 255]] {
        let e = load(bad).unwrap_err().to_string();
        assert!(
            e.contains("c.png: confidence value") && e.contains("neither"),
            "{e}"
        );
    }
}

#[test]
fn bad_exports_are_refused_with_the_file_named() {
    let tmp = tempfile::tempdir().unwrap();
    let keyframes = export(tmp.path(), &[1, 2]);
    // A missing camera JSON.
    std::fs::remove_file(keyframes.join("corrected_cameras/2.json")).unwrap();
    let e = read_capture(tmp.path()).unwrap_err().to_string();
    assert!(
        e.contains("corrected_images/2.jpg: no camera") && e.contains("2.json"),
        "{e}"
    );
    // A missing key.
    let json = camera_json(2, 0.0).replace(r#""t_13""#, r#""t_xx""#);
    write(&keyframes.join("corrected_cameras/2.json"), json.as_bytes());
    let e = read_capture(tmp.path()).unwrap_err().to_string();
    assert!(e.contains("corrected_cameras/2.json: no `t_13`"), "{e}");
    // Not JSON.
    write(&keyframes.join("corrected_cameras/2.json"), b"{");
    let e = read_capture(tmp.path()).unwrap_err().to_string();
    assert!(e.contains("2.json: not a camera JSON"), "{e}");
    // No images.
    for dir in ["corrected_images", "images"] {
        std::fs::remove_dir_all(keyframes.join(dir)).unwrap();
        std::fs::create_dir_all(keyframes.join(dir)).unwrap();
    }
    let e = read_capture(tmp.path()).unwrap_err().to_string();
    assert!(e.contains("corrected_images: no images"), "{e}");
    // Not an export.
    let e = read_capture(&keyframes.join("depth"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a Polycam raw-data export"), "{e}");
}
