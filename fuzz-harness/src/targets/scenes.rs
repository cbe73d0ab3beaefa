//! Targets of the scene formats: `.npy`, LLFF, PLY, label lists,
//! transforms files, Replica and ScanNet.

use std::path::Path;

use datasets::points::{PointCloud, read_ply, write_ply};
use datasets::{blender, llff, npy, points, replica, scannet};
use half::f16;

use super::{Seeds, Target, no_setup, present, written};

const NPY_TOKENS: &[&str] = &[
    "\u{93}NUMPY",
    "'descr': '<f4'",
    "'descr': '<f2'",
    "'descr': '>f8'",
    "'descr': '<i8'",
    "'fortran_order': True",
    "'shape': (",
    "(4294967296, 4294967296, 4294967296)",
    "(0,)",
    "()",
    ", 17)",
];

const PLY_TOKENS: &[&str] = &[
    "ply\n",
    "format ascii 1.0\n",
    "format binary_little_endian 1.0\n",
    "format binary_big_endian 1.0\n",
    "element vertex 4294967295\n",
    "element face 3\n",
    "property float x\n",
    "property double y\n",
    "property uchar red\n",
    "property int label\n",
    "property list uchar int vertex_indices\n",
    "property list uint float data\n",
    "end_header\n",
    "comment ",
];

const TEXT_TOKENS: &[&str] = &[
    "1 0 0 0", "0 0 0 1", "nan", "-inf", "1e400", "w", "h", "fx", "scale",
];

const JSON_CAMERA_TOKENS: &[&str] = &[
    "\"frames\"",
    "\"transform_matrix\"",
    "\"camera_angle_x\"",
    "\"fl_x\"",
    "\"w\"",
    "\"h\"",
    "\"k1\"",
    "\"file_path\"",
    "\"camera\"",
    "\"scale\"",
    "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]",
    "1e999",
    "-0.0",
];

fn npy_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    let f16s: Vec<f16> = (0..12).map(|i| f16::from_f32(i as f32 * 0.25)).collect();
    let f32s: Vec<f32> = (0..24).map(|i| i as f32 - 3.5).collect();
    present([
        s.data_file("llff_fern/poses_bounds.npy"),
        Some(written("a.npy", |p| {
            npy::write_npy_f16(p, &[3, 4], &f16s).map_err(|e| e.to_string())
        })),
        Some(written("b.npy", |p| {
            npy::write_npy_f32(p, &[2, 3, 4], &f32s).map_err(|e| e.to_string())
        })),
        s.data_file("clip_text/scannet200_vitb_512.npy"),
    ])
}

fn run_npy(path: &Path) {
    let _ = npy::read_npy_f32(path);
    if let Ok(info) = npy::NpyInfo::open(path) {
        let _ = info.read_f16_range(info.len() / 2, info.len() - info.len() / 2);
    }
    let _ = eval::query::embedding_from_npy(path);
}

fn llff_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    present([s.data_file("llff_fern/poses_bounds.npy")])
}

fn run_llff(path: &Path) {
    let _ = llff::read_poses_bounds(path);
}

const ASCII_PLY: &str = "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 3\n\
property float x\nproperty float y\nproperty float z\nproperty uchar red\n\
property uchar green\nproperty uchar blue\nproperty int label\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0 1\n1 0 0 0 255 0 2\n\
0 1 0 0 0 255 3\n3 0 1 2\n";

const FACE_FIRST_PLY: &str = "ply\nformat ascii 1.0\nelement face 1\n\
property list uchar int vertex_indices\nelement vertex 2\nproperty double x\n\
property double y\nproperty double z\nproperty short object_id\nend_header\n\
3 0 1 1\n0.5 0.25 -1 7\n2 2 2 -3\n";

fn ply_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    let cloud = PointCloud {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.5, -2.0], [0.25, 3.0, 1.0]],
        colors: Some(vec![[255, 0, 0], [0, 255, 0], [0, 0, 255]]),
        labels: Some(vec![1, 2, -1]),
    };
    let scores = [0.5f32, 0.25, 1.0];
    let mut big_endian = ASCII_PLY.replace("format ascii", "format binary_big_endian");
    big_endian.truncate(big_endian.find("end_header\n").unwrap_or(0) + 11);
    let mut be = big_endian.into_bytes();
    for (i, p) in cloud.positions.iter().enumerate() {
        p.iter().for_each(|c| be.extend((*c as f32).to_be_bytes()));
        be.extend([i as u8, 0, 255]);
        be.extend((i as i32).to_be_bytes());
    }
    be.extend([3u8]);
    [0i32, 1, 2].iter().for_each(|v| be.extend(v.to_be_bytes()));
    present([
        Some(written("a.ply", |p| {
            write_ply(p, &cloud, &[("relevancy", &scores)]).map_err(|e| e.to_string())
        })),
        Some(ASCII_PLY.as_bytes().to_vec()),
        Some(FACE_FIRST_PLY.as_bytes().to_vec()),
        Some(be),
    ])
}

fn run_ply(path: &Path) {
    let _ = read_ply(path);
}

fn labels_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    present([
        s.data_file("replica_classes/replica_class_id_to_names.txt"),
        Some(b"-1 undefined\n0 wall\n3 chair\n12 table lamp\n".to_vec()),
        Some(b"1\n2\n3\n0\n-1\n\n7\n".to_vec()),
    ])
}

fn run_labels(path: &Path) {
    let _ = points::ClassMap::load_replica(path);
    let _ = points::read_labels_txt(path, 6);
}

fn transforms_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    let small = br#"{"camera_angle_x": 0.69, "w": 80, "h": 60, "k1": 0.01,
 "frames": [{"file_path": "./train/r_0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]},
 {"file_path": "images/b.png", "fl_x": 70, "fl_y": 71, "cx": 40, "cy": 30,
  "transform_matrix": [[0,-1,0,1],[1,0,0,0],[0,0,1,4],[0,0,0,1]]}]}"#;
    present([
        Some(small.to_vec()),
        s.data_file("lego_train/transforms_train.json"),
    ])
}

fn run_transforms(path: &Path) {
    let _ = blender::read_cameras(path);
}

fn cam_params_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    present([
        s.data_file("replica_room0_20f/cam_params.json"),
        Some(br#"{"camera": {"w": 1200, "h": 680, "fx": 600.0, "fy": 600.0, "cx": 599.5, "cy": 339.5, "scale": 6553.5}}"#.to_vec()),
    ])
}

fn run_cam_params(path: &Path) {
    let _ = replica::read_cam_params(path);
}

fn traj_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    present([
        s.data_file("replica_room0_20f/traj.txt"),
        Some(b"1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n\n0 -1 0 1 1 0 0 2 0 0 1 3 0 0 0 1\n".to_vec()),
    ])
}

fn run_traj(path: &Path) {
    let _ = replica::read_trajectory(path);
}

fn scannet_intrinsic_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    vec![
        b"577.870605 0.000000 319.500000 0.000000\n0.000000 577.870605 239.500000 0.000000\n\
0.000000 0.000000 1.000000 0.000000\n0.000000 0.000000 0.000000 1.000000\n"
            .to_vec(),
        b"1169.6 0 646.3 0\n0 1167.1 489.9 0\n0 0 1 0\n0 0 0 1".to_vec(),
    ]
}

fn run_scannet_intrinsics(path: &Path) {
    let _ = scannet::read_intrinsics(path, (640, 480));
}

fn scannet_pose_seeds(s: &Seeds) -> Vec<Vec<u8>> {
    // The first Replica pose, four numbers a line as ScanNet writes it.
    let from_replica = s.data_file("replica_room0_20f/traj.txt").map(|t| {
        let text = String::from_utf8_lossy(&t).into_owned();
        let nums: Vec<&str> = text.split_whitespace().take(16).collect();
        nums.chunks(4)
            .map(|r| r.join(" ") + "\n")
            .collect::<String>()
            .into_bytes()
    });
    present([
        from_replica,
        Some(
            b"-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n"
                .to_vec(),
        ),
        Some(b"0.9 0.1 0 1.5\n-0.1 0.9 0 2.5\n0 0 1 1.2\n0 0 0 1\n".to_vec()),
    ])
}

fn run_scannet_pose(path: &Path) {
    let _ = scannet::read_pose(path);
}

/// The targets of this module.
pub(super) fn targets() -> Vec<Target> {
    vec![
        Target {
            name: "npy",
            about: "npy::read_npy_f32, NpyInfo::read_f16_range, eval::query::embedding_from_npy",
            file: "array.npy",
            tokens: NPY_TOKENS,
            seeds: npy_seeds,
            setup: no_setup,
            run: run_npy,
        },
        Target {
            name: "llff-poses",
            about: "llff::read_poses_bounds (poses_bounds.npy)",
            file: "poses_bounds.npy",
            tokens: NPY_TOKENS,
            seeds: llff_seeds,
            setup: no_setup,
            run: run_llff,
        },
        Target {
            name: "ply",
            about: "points::read_ply (ASCII, binary little and big endian)",
            file: "cloud.ply",
            tokens: PLY_TOKENS,
            seeds: ply_seeds,
            setup: no_setup,
            run: run_ply,
        },
        Target {
            name: "labels",
            about: "points::ClassMap::load_replica, points::read_labels_txt",
            file: "labels.txt",
            tokens: TEXT_TOKENS,
            seeds: labels_seeds,
            setup: no_setup,
            run: run_labels,
        },
        Target {
            name: "transforms-json",
            about: "blender::read_cameras (Blender / nerfstudio transforms.json)",
            file: "transforms.json",
            tokens: JSON_CAMERA_TOKENS,
            seeds: transforms_seeds,
            setup: no_setup,
            run: run_transforms,
        },
        Target {
            name: "replica-cam-params",
            about: "replica::read_cam_params (cam_params.json)",
            file: "cam_params.json",
            tokens: JSON_CAMERA_TOKENS,
            seeds: cam_params_seeds,
            setup: no_setup,
            run: run_cam_params,
        },
        Target {
            name: "replica-traj",
            about: "replica::read_trajectory (traj.txt)",
            file: "traj.txt",
            tokens: TEXT_TOKENS,
            seeds: traj_seeds,
            setup: no_setup,
            run: run_traj,
        },
        Target {
            name: "scannet-intrinsics",
            about: "scannet::read_intrinsics (intrinsic_color.txt)",
            file: "intrinsic_color.txt",
            tokens: TEXT_TOKENS,
            seeds: scannet_intrinsic_seeds,
            setup: no_setup,
            run: run_scannet_intrinsics,
        },
        Target {
            name: "scannet-pose",
            about: "scannet::read_pose (pose/<i>.txt)",
            file: "0.txt",
            tokens: TEXT_TOKENS,
            seeds: scannet_pose_seeds,
            setup: no_setup,
            run: run_scannet_pose,
        },
    ]
}
