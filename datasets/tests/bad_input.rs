//! Every kind of bad input gives an error naming the file and the problem.

use std::path::{Path, PathBuf};

use datasets::DatasetError;
use datasets::blender::{BlenderOptions, load_blender};
use datasets::features::{FeatureSource, PcaSetting, load_features};
use datasets::llff::{LlffOptions, load_llff};
use datasets::npy::{NpyInfo, write_npy_f16, write_npy_f32};
use datasets::options::{FeatureInput, FrameSelection};
use datasets::points::{read_labels_txt, read_ply};
use datasets::replica::{ReplicaOptions, load_replica};
use datasets::text::TextEmbeddings;
use half::f16;

const IDENTITY: &str = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";

/// Asserts `r` is an error whose message names `file` and contains every `words`.
fn assert_err<T>(r: Result<T, DatasetError>, file: &str, words: &[&str]) {
    let msg = match r {
        Ok(_) => panic!("expected an error mentioning {file}"),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains(file), "error {msg:?} does not name {file}");
    for w in words {
        assert!(msg.contains(w), "error {msg:?} does not mention {w:?}");
    }
}

/// A tiny Nice-SLAM scene: `n` frames of 8x6 pixels, identity-ish poses.
fn replica_dir(n: usize, poses: &[String]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("temp dir");
    let results = dir.path().join("results");
    std::fs::create_dir(&results).expect("mkdir");
    std::fs::write(
        dir.path().join("cam_params.json"),
        r#"{"camera": {"w": 8, "h": 6, "fx": 5.0, "fy": 5.0, "cx": 3.5, "cy": 2.5, "scale": 1000.0}}"#,
    )
    .expect("write");
    for i in 0..n {
        image::RgbImage::from_pixel(8, 6, image::Rgb([100, 150, 200]))
            .save(results.join(format!("frame{i:06}.png")))
            .expect("png");
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(8, 6, image::Luma([2000]))
            .save(results.join(format!("depth{i:06}.png")))
            .expect("png");
    }
    std::fs::write(dir.path().join("traj.txt"), poses.join("\n")).expect("write");
    dir
}

fn identity_poses(n: usize) -> Vec<String> {
    vec![IDENTITY.to_string(); n]
}

#[test]
fn replica_sane_scene_loads() {
    // Guards the other tests: the fixture itself is valid.
    let dir = replica_dir(2, &identity_poses(2));
    let scene = load_replica(dir.path(), &ReplicaOptions::default()).expect("valid scene");
    assert_eq!(scene.frames.len(), 2);
    let d = scene.frames[0].depth.as_ref().expect("depth");
    assert!((d.get(3, 3) - 2.0).abs() < 1e-6);
    // Stride 2 of 3 frames keeps frames 0 and 2; features index the kept frames.
    let feats = dir.path().join("feats.npy");
    write_npy_f16(&feats, &[2, 3, 4, 2], &[f16::ONE; 48]).expect("npy");
    let dir3 = replica_dir(3, &identity_poses(3));
    let opts = ReplicaOptions {
        selection: FrameSelection {
            stride: 2,
            ..FrameSelection::default()
        },
        feature_input: FeatureInput {
            features: Some(feats),
            ..FeatureInput::default()
        },
        ..Default::default()
    };
    let s = load_replica(dir3.path(), &opts).expect("strided scene");
    let names: Vec<&str> = s.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["frame000000", "frame000002"]);
    assert_eq!(s.features.expect("features").maps.len(), 2);
}

#[test]
fn replica_missing_frame() {
    let dir = replica_dir(3, &identity_poses(3));
    std::fs::remove_file(dir.path().join("results/frame000001.png")).expect("rm");
    assert_err(
        load_replica(dir.path(), &ReplicaOptions::default()),
        "frame000001",
        &["missing"],
    );
}

#[test]
fn replica_missing_depth() {
    let dir = replica_dir(2, &identity_poses(2));
    std::fs::remove_file(dir.path().join("results/depth000001.png")).expect("rm");
    assert_err(
        load_replica(dir.path(), &ReplicaOptions::default()),
        "depth000001.png",
        &["missing"],
    );
}

#[test]
fn replica_pose_count_disagrees_with_images() {
    let dir = replica_dir(2, &identity_poses(3));
    assert_err(
        load_replica(dir.path(), &ReplicaOptions::default()),
        "traj.txt",
        &["3 poses", "2 frames"],
    );
}

#[test]
fn replica_pose_not_rigid() {
    let mut poses = identity_poses(2);
    poses[1] = "2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1".into();
    let dir = replica_dir(2, &poses);
    assert_err(
        load_replica(dir.path(), &ReplicaOptions::default()),
        "traj.txt",
        &["line 2", "rigid"],
    );
}

#[test]
fn replica_pose_non_finite() {
    let mut poses = identity_poses(2);
    poses[0] = "1 0 0 NaN 0 1 0 0 0 0 1 0 0 0 0 1".into();
    let dir = replica_dir(2, &poses);
    assert_err(
        load_replica(dir.path(), &ReplicaOptions::default()),
        "traj.txt",
        &["line 1", "NaN"],
    );
}

#[test]
fn replica_feature_count_disagrees_with_frames() {
    let dir = replica_dir(2, &identity_poses(2));
    let feats = dir.path().join("feats.npy");
    write_npy_f16(&feats, &[3, 3, 4, 2], &[f16::ZERO; 72]).expect("npy");
    let opts = ReplicaOptions {
        feature_input: FeatureInput {
            features: Some(feats),
            ..FeatureInput::default()
        },
        ..Default::default()
    };
    assert_err(
        load_replica(dir.path(), &opts),
        "feats.npy",
        &["3 feature maps", "2 frames"],
    );
}

#[test]
fn feature_map_aspect_ratio_mismatch() {
    let dir = tempfile::tempdir().expect("tmp");
    let good = dir.path().join("a.npy");
    let bad = dir.path().join("b.npy");
    // Images are 80x60 (4:3): 8x6 fits, 8x8 does not.
    write_npy_f32(&good, &[6, 8, 2], &[0.5; 96]).expect("npy");
    write_npy_f32(&bad, &[8, 8, 2], &[0.5; 128]).expect("npy");
    let src = FeatureSource::PerFrame(vec![good, bad]);
    assert_err(
        load_features(&src, &[(80, 60), (80, 60)], PcaSetting::Off, 0),
        "b.npy",
        &["aspect ratio"],
    );
}

#[test]
fn feature_directory_count_disagrees() {
    let dir = tempfile::tempdir().expect("tmp");
    write_npy_f32(&dir.path().join("x.npy"), &[6, 8, 2], &[0.5; 96]).expect("npy");
    let names = vec!["frame000000".to_string(), "frame000001".to_string()];
    let r = FeatureSource::discover(dir.path(), &names);
    let name = dir
        .path()
        .file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned();
    assert_err(r, &name, &["1 feature maps", "2 frames"]);
}

fn raw_npy(path: &Path, descr: &str, fortran: bool, shape: &str, body: &[u8]) {
    let mut dict = format!(
        "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
        if fortran { "True" } else { "False" }
    );
    while !(10 + dict.len() + 1).is_multiple_of(64) {
        dict.push(' ');
    }
    dict.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    bytes.extend_from_slice(body);
    std::fs::write(path, bytes).expect("write");
}

fn tmp_file(dir: &tempfile::TempDir, name: &str) -> PathBuf {
    dir.path().join(name)
}

#[test]
fn npy_truncated() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = tmp_file(&dir, "trunc.npy");
    raw_npy(&p, "<f4", false, "(4, 3)", &[0u8; 4 * 11]);
    assert_err(NpyInfo::open(&p), "trunc.npy", &["truncated"]);
}

#[test]
fn npy_wrong_dtype() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = tmp_file(&dir, "ints.npy");
    raw_npy(&p, "<i4", false, "(2, 2)", &[0u8; 16]);
    assert_err(NpyInfo::open(&p), "ints.npy", &["dtype"]);
    let q = tmp_file(&dir, "big.npy");
    raw_npy(&q, ">f4", false, "(2, 2)", &[0u8; 16]);
    assert_err(NpyInfo::open(&q), "big.npy", &["dtype"]);
}

#[test]
fn npy_fortran_order() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = tmp_file(&dir, "fortran.npy");
    raw_npy(&p, "<f4", true, "(2, 3)", &[0u8; 24]);
    assert_err(NpyInfo::open(&p), "fortran.npy", &["Fortran"]);
}

#[test]
fn npy_not_npy() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = tmp_file(&dir, "junk.npy");
    std::fs::write(&p, b"hello world, not an array").expect("write");
    assert_err(NpyInfo::open(&p), "junk.npy", &["header"]);
}

#[test]
fn text_embeddings_wrong_rank_and_count() {
    let dir = tempfile::tempdir().expect("tmp");
    let npy = tmp_file(&dir, "emb.npy");
    let labels = tmp_file(&dir, "labels.txt");
    std::fs::write(&labels, "wall\nchair\nfloor\n").expect("write");
    write_npy_f32(&npy, &[6], &[0.0; 6]).expect("npy");
    assert_err(TextEmbeddings::load(&npy, &labels), "emb.npy", &["rank-2"]);
    write_npy_f32(&npy, &[2, 3], &[0.0; 6]).expect("npy");
    assert_err(
        TextEmbeddings::load(&npy, &labels),
        "labels.txt",
        &["3 labels", "2 embedding rows"],
    );
    write_npy_f32(&npy, &[3, 2], &[0.0, f32::NAN, 0.0, 0.0, 0.0, 0.0]).expect("npy");
    assert_err(TextEmbeddings::load(&npy, &labels), "emb.npy", &["NaN"]);
}

#[test]
fn ply_missing_z() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = tmp_file(&dir, "noz.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nend_header\n0 0\n1 1\n",
    )
    .expect("write");
    assert_err(read_ply(&p), "noz.ply", &["'z'"]);
}

#[test]
fn ply_truncated_binary() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = tmp_file(&dir, "short.ply");
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    bytes.extend_from_slice(&[0u8; 12 * 2 + 5]);
    std::fs::write(&p, bytes).expect("write");
    assert_err(read_ply(&p), "short.ply", &["truncated", "vertex 2"]);
}

#[test]
fn labels_length_differs_from_point_count() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = tmp_file(&dir, "labels.txt");
    std::fs::write(&p, "1\n2\n3\n").expect("write");
    assert_err(
        read_labels_txt(&p, 4),
        "labels.txt",
        &["3 labels", "4 points"],
    );
    std::fs::write(&p, "1\nwall\n3\n4\n").expect("write");
    assert_err(
        read_labels_txt(&p, 4),
        "labels.txt",
        &["line 2", "not an integer"],
    );
}

/// A Blender scene with one 4x4 RGBA view.
fn blender_dir(matrix: &str, with_image: bool) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::write(
        dir.path().join("transforms.json"),
        format!(
            r#"{{"camera_angle_x": 0.7, "frames": [{{"file_path": "./r_0", "transform_matrix": {matrix}}}]}}"#
        ),
    )
    .expect("write");
    if with_image {
        image::RgbaImage::from_pixel(4, 4, image::Rgba([255, 0, 0, 128]))
            .save(dir.path().join("r_0.png"))
            .expect("png");
    }
    dir
}

const GL_POSE: &str = "[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]";

#[test]
fn blender_missing_image() {
    let dir = blender_dir(GL_POSE, false);
    assert_err(
        load_blender(dir.path(), &BlenderOptions::default()),
        "r_0",
        &["missing image"],
    );
}

#[test]
fn blender_pose_not_rigid() {
    let dir = blender_dir("[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,1,1]]", true);
    assert_err(
        load_blender(dir.path(), &BlenderOptions::default()),
        "transforms.json",
        &["frames[0]", "rigid"],
    );
}

#[test]
fn llff_pose_count_disagrees_with_images() {
    let dir = tempfile::tempdir().expect("tmp");
    let imgs = dir.path().join("images_8");
    std::fs::create_dir(&imgs).expect("mkdir");
    // Two views in the file, one image on disk.
    // Columns [down, right, backwards] of an identity OpenCV camera, then
    // hwf = (48, 64, 50) and bounds (0.5, 5).
    let row: [f32; 17] = [
        0., 1., 0., 0., 48., 1., 0., 0., 0., 64., 0., 0., -1., 0., 50., 0.5, 5.0,
    ];
    let data: Vec<f32> = row.iter().chain(row.iter()).copied().collect();
    write_npy_f32(&dir.path().join("poses_bounds.npy"), &[2, 17], &data).expect("npy");
    image::RgbImage::new(8, 6)
        .save(imgs.join("a.png"))
        .expect("png");
    assert_err(
        load_llff(dir.path(), &LlffOptions::default()),
        "poses_bounds.npy",
        &["2 poses", "1 images"],
    );
}
