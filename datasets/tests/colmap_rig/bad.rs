//! Bad input: every error names the file and the problem.

use super::depth::{depth_dir, encode, write_depth_maps};
use super::*;

/// The rig's directory with one of its model files edited.
fn edited(part: usize, edit: impl Fn(&str) -> String) -> tempfile::TempDir {
    let cams = rig();
    let dir = rig_dir(&cams);
    let mut text = rig_text(&cams, &rig_points());
    text[part] = edit(&text[part]);
    write_model(dir.path(), &text);
    dir
}

fn load_err(dir: &Path, opts: &ColmapOptions) -> String {
    match load_colmap(dir, opts) {
        Ok(_) => panic!("expected an error"),
        Err(e) => {
            assert!(matches!(
                e,
                DatasetError::Invalid { .. } | DatasetError::Io { .. }
            ));
            e.to_string()
        }
    }
}

fn assert_mentions(msg: &str, words: &[&str]) {
    for w in words {
        assert!(msg.contains(w), "error {msg:?} does not mention {w:?}");
    }
}

#[test]
fn an_image_refers_to_a_camera_that_does_not_exist() {
    // Image 5 (cam0.png) was taken with camera 1: point it at camera 99.
    let dir = edited(1, |t| t.replace(" 1 cam0.png", " 99 cam0.png"));
    let msg = load_err(dir.path(), &ColmapOptions::default());
    assert_mentions(&msg, &["images.txt", "image 5 (cam0.png)", "camera 99"]);
}

#[test]
fn unsupported_camera_models_point_to_the_undistorter() {
    let dir = edited(0, |t| {
        t.replace(
            "OPENCV 40 30 38 37 21 14.5 -0.05 0.01 0.002 -0.001",
            "OPENCV_FISHEYE 40 30 38 37 21 14.5 -0.05 0.01 0.002 -0.001",
        )
    });
    let msg = load_err(dir.path(), &ColmapOptions::default());
    assert_mentions(
        &msg,
        &[
            "cameras.txt",
            "camera 5",
            "OPENCV_FISHEYE",
            "image_undistorter",
        ],
    );
    let dir = edited(0, |t| t.replace("SIMPLE_PINHOLE", "PINHOLE_X"));
    let msg = load_err(dir.path(), &ColmapOptions::default());
    assert_mentions(&msg, &["cameras.txt", "line 2", "unknown camera model"]);
}

#[test]
fn a_missing_image_file_is_named() {
    let cams = rig();
    let dir = rig_dir(&cams);
    std::fs::remove_file(dir.path().join("images").join("cam3.png")).expect("rm");
    let msg = load_err(dir.path(), &ColmapOptions::default());
    assert_mentions(&msg, &["cam3.png", "not found", "image 2"]);
}

#[test]
fn a_point_with_a_nan_coordinate_is_named() {
    let dir = edited(2, |t| {
        let mut lines: Vec<String> = t.lines().map(String::from).collect();
        lines[8] = "7 1.0 NaN 2.0 1 2 3 0.5".into();
        lines.join("\n")
    });
    let msg = load_err(dir.path(), &ColmapOptions::default());
    assert_mentions(&msg, &["points3D.txt", "point 7", "non-finite"]);
}

#[test]
fn bad_depth_maps_are_named() {
    let cams = rig();
    let dir = rig_dir(&cams);
    let opts = ColmapOptions {
        depth: true,
        ..Default::default()
    };
    // Missing entirely.
    let msg = load_err(dir.path(), &opts);
    assert_mentions(&msg, &["cam0.png.geometric.bin"]);
    write_depth_maps(dir.path(), &cams);
    let path = depth_dir(dir.path()).join("cam2.png.geometric.bin");
    // Width and height swapped: the wrong aspect ratio.
    std::fs::write(&path, encode(30, 40, &[1.0; 1200])).expect("write");
    let msg = load_err(dir.path(), &opts);
    assert_mentions(&msg, &["cam2.png.geometric.bin", "aspect ratio", "30x40"]);
    // Cut short.
    let bytes = encode(40, 30, &[1.0; 1200]);
    std::fs::write(&path, &bytes[..bytes.len() - 10]).expect("write");
    let msg = load_err(dir.path(), &opts);
    assert_mentions(&msg, &["cam2.png.geometric.bin", "truncated"]);
    // Not a depth map at all.
    std::fs::write(&path, b"PNG...").expect("write");
    let msg = load_err(dir.path(), &opts);
    assert_mentions(&msg, &["cam2.png.geometric.bin", "not a COLMAP depth map"]);
}

#[test]
fn a_directory_without_a_model_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let msg = load_err(dir.path(), &ColmapOptions::default());
    assert_mentions(&msg, &["sparse", "no COLMAP model"]);
    let zero = ColmapOptions {
        selection: FrameSelection {
            stride: 0,
            ..FrameSelection::default()
        },
        ..Default::default()
    };
    let cams = rig();
    let dir = rig_dir(&cams);
    assert_mentions(&load_err(dir.path(), &zero), &["stride"]);
}
