//! Format round trips and closed-form checks: npy, PLY, labels, PCA, lazy
//! feature maps.

use datasets::FeatureMap;
use datasets::features::{FeatureSet, FeatureSource, PcaBasis, PcaSetting, load_features};
use datasets::npy::{NpyDtype, NpyInfo, read_npy_f32, write_npy_f16, write_npy_f32};
use datasets::points::{PointCloud, read_labels_txt, read_ply, write_ply};
use datasets::text::TextEmbeddings;
use half::f16;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn npy_round_trip_and_alignment() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("a.npy");
    let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
    write_npy_f32(&p, &[2, 3, 4], &data).expect("write");
    let info = NpyInfo::open(&p).expect("header");
    assert_eq!(
        (info.dtype, info.shape.clone(), info.data_offset % 64),
        (NpyDtype::F32, vec![2, 3, 4], 0)
    );
    assert_eq!(read_npy_f32(&p).expect("read").1, data);
    // A slice from the middle.
    assert_eq!(
        info.read_f32_range(13, 3).expect("range"),
        data[13..16].to_vec()
    );
    let q = dir.path().join("h.npy");
    let halfs: Vec<f16> = data.iter().map(|&v| f16::from_f32(v)).collect();
    write_npy_f16(&q, &[24], &halfs).expect("write");
    let (shape, back) = read_npy_f32(&q).expect("read");
    assert_eq!((shape, back), (vec![24], data.clone()));
    assert!(write_npy_f32(&p, &[5], &data).is_err());
}

#[test]
fn npy_reads_numpy_written_bytes() {
    // Bytes of `np.save(f, np.array([[1.5, -2.0]], dtype='<f8'))` (header by hand).
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("np.npy");
    let mut dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 2), }".to_string();
    while !(10 + dict.len() + 1).is_multiple_of(64) {
        dict.push(' ');
    }
    dict.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    bytes.extend_from_slice(&1.5f64.to_le_bytes());
    bytes.extend_from_slice(&(-2.0f64).to_le_bytes());
    std::fs::write(&p, bytes).expect("write");
    assert_eq!(
        read_npy_f32(&p).expect("read"),
        (vec![1, 2], vec![1.5, -2.0])
    );
}

#[test]
fn text_embeddings_round_trip() {
    let dir = tempfile::tempdir().expect("tmp");
    let t = TextEmbeddings {
        names: vec!["a b".into(), "c".into()],
        dim: 3,
        data: vec![1., 2., 3., 4., 5., 6.],
    };
    let (n, l) = (dir.path().join("e.npy"), dir.path().join("l.txt"));
    t.save(&n, &l).expect("save");
    let back = TextEmbeddings::load(&n, &l).expect("load");
    assert_eq!(back, t);
    assert_eq!(back.row(1), &[4., 5., 6.]);
    assert_eq!(back.index_of("a b"), Some(0));
}

#[test]
fn ply_binary_round_trip_and_ascii() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("c.ply");
    let cloud = PointCloud {
        positions: vec![[0.5, -1.0, 2.25], [3.0, 4.0, -5.5]],
        colors: Some(vec![[1, 2, 3], [250, 128, 0]]),
        labels: Some(vec![7, -1]),
    };
    write_ply(&p, &cloud, &[("relevancy", &[0.25, 0.75])]).expect("write");
    assert_eq!(read_ply(&p).expect("read"), cloud);
    assert!(write_ply(&p, &cloud, &[("r", &[1.0])]).is_err());

    let a = dir.path().join("a.ply");
    std::fs::write(
        &a,
        "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 2\nproperty double x\nproperty double y\n\
         property double z\nproperty float red\nproperty float green\nproperty float blue\nproperty ushort semantic\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n\
         1 2 3 1.0 0.5 0.0 40\n-1 -2 -3 0 0 1 93\n3 0 1 1\n",
    )
    .expect("write");
    let c = read_ply(&a).expect("ascii");
    assert_eq!(c.positions, vec![[1.0, 2.0, 3.0], [-1.0, -2.0, -3.0]]);
    assert_eq!(c.colors, Some(vec![[255, 128, 0], [0, 0, 255]]));
    assert_eq!(c.labels, Some(vec![40, 93]));
}

#[test]
fn labels_txt_reads_integers() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("l.txt");
    std::fs::write(&p, "3\n-1\n\n40\n").expect("write");
    assert_eq!(read_labels_txt(&p, 3).expect("labels"), vec![3, -1, 40]);
}

/// Samples with known principal axes: variances 9, 4, 1 along an orthonormal
/// basis rotated into 6 dimensions, plus a tiny isotropic noise.
fn known_samples(n: usize) -> (Vec<f32>, [[f32; 6]; 3], Vec<f32>) {
    let s = 0.5f32.sqrt();
    let axes = [
        [s, s, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.6, 0.8, 0.0, 0.0],
        [s, -s, 0.0, 0.0, 0.0, 0.0],
    ];
    let mean = vec![1.0, -2.0, 0.5, 0.0, 3.0, 1.0];
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut out = Vec::new();
    for _ in 0..n {
        let c = [3.0, 2.0, 1.0].map(|sd: f32| sd * (rng.random::<f32>() * 2.0 - 1.0) * 3f32.sqrt());
        for (d, m) in mean.iter().enumerate() {
            let v: f32 = c.iter().zip(&axes).map(|(ck, axis)| ck * axis[d]).sum();
            out.push(m + v + 1e-3 * (rng.random::<f32>() - 0.5));
        }
    }
    (out, axes, mean)
}

#[test]
fn pca_recovers_known_axes() {
    let (x, axes, mean) = known_samples(20000);
    let pca = PcaBasis::fit(&x, 6, PcaSetting::Components(3)).expect("fit");
    for (a, b) in pca.mean.iter().zip(&mean) {
        assert!((a - b).abs() < 0.08, "mean {:?}", pca.mean);
    }
    for (k, axis) in axes.iter().enumerate() {
        let row = &pca.components[k * 6..(k + 1) * 6];
        let dot: f32 = row.iter().zip(axis).map(|(a, b)| a * b).sum();
        assert!(dot.abs() > 0.995, "component {k}: {row:?}");
    }
    assert!(pca.explained_variance_ratio > 0.9999);
    // Variance target: 9 / 14 = 0.64, 13 / 14 = 0.93.
    assert_eq!(
        PcaBasis::fit(&x, 6, PcaSetting::ExplainedVariance(0.6))
            .expect("fit")
            .k,
        1
    );
    assert_eq!(
        PcaBasis::fit(&x, 6, PcaSetting::ExplainedVariance(0.9))
            .expect("fit")
            .k,
        2
    );
    assert_eq!(
        PcaBasis::fit(&x, 6, PcaSetting::ExplainedVariance(0.99))
            .expect("fit")
            .k,
        3
    );
    // In-subspace vectors survive project -> lift.
    let v: Vec<f32> = (0..6)
        .map(|d| mean[d] + 2.0 * axes[0][d] - 1.5 * axes[2][d])
        .collect();
    let c = pca.project(&v);
    assert_eq!(c.len(), 3);
    for (a, b) in pca.lift(&c).iter().zip(&v) {
        assert!((a - b).abs() < 1e-3);
    }
    assert!(PcaBasis::fit(&x, 6, PcaSetting::Components(7)).is_err());
    assert!(PcaBasis::fit(&x[..6], 6, PcaSetting::Components(1)).is_err());
}

fn random_maps(n: usize, w: u32, h: u32, dim: usize) -> Vec<FeatureMap> {
    let (x, _, _) = known_samples(n * (w * h) as usize);
    let mut maps = Vec::new();
    for i in 0..n {
        let per = (w * h) as usize * dim;
        // Pad the 6-d samples into `dim` channels.
        let data = (0..per)
            .map(|j| {
                let (p, d) = (j / dim, j % dim);
                f16::from_f32(if d < 6 {
                    x[(i * (w * h) as usize + p) * 6 + d]
                } else {
                    0.0
                })
            })
            .collect();
        maps.push(FeatureMap {
            width: w,
            height: h,
            dim,
            data,
        });
    }
    maps
}

#[test]
fn lazy_features_match_in_memory_ones() {
    let dir = tempfile::tempdir().expect("tmp");
    let maps = random_maps(3, 16, 12, 8);
    // Stacked f16 file and per-frame f32 files hold the same values.
    let stacked = dir.path().join("all.npy");
    let all: Vec<f16> = maps.iter().flat_map(|m| m.data.clone()).collect();
    write_npy_f16(&stacked, &[3, 12, 16, 8], &all).expect("npy");
    let names: Vec<String> = (0..3).map(|i| format!("frame{i:06}")).collect();
    let per_dir = dir.path().join("per");
    std::fs::create_dir(&per_dir).expect("mkdir");
    for (m, n) in maps.iter().zip(&names) {
        let v: Vec<f32> = m.data.iter().map(|h| h.to_f32()).collect();
        write_npy_f32(&per_dir.join(format!("{n}.npy")), &[12, 16, 8], &v).expect("npy");
    }
    let sizes = [(64, 48); 3];
    let src_stacked = FeatureSource::discover(&stacked, &names).expect("stacked");
    let src_per = FeatureSource::discover(&per_dir, &names).expect("per frame");
    assert!(matches!(src_per, FeatureSource::PerFrame(ref v) if v.len() == 3));
    let full = load_features(&src_stacked, &sizes, PcaSetting::Off, 0).expect("load");
    assert_eq!(full.maps, maps);
    assert_eq!((full.dim(), full.full_dim), (8, 8));
    let target = PcaSetting::Components(3);
    let lazy = load_features(&src_per, &sizes, target, 5).expect("pca load");
    let memory = FeatureSet::from_maps(maps.clone(), target, 5).expect("pca");
    assert_eq!(lazy, memory);
    assert_eq!((lazy.dim(), lazy.full_dim), (3, 8));
    // Compressed maps lift back close to the originals (noise ~1e-3, f16).
    let pca = lazy.pca.as_ref().expect("pca");
    let c: Vec<f32> = lazy.maps[1]
        .pixel(4, 7)
        .iter()
        .map(|h| h.to_f32())
        .collect();
    let orig: Vec<f32> = maps[1].pixel(4, 7).iter().map(|h| h.to_f32()).collect();
    for (a, b) in pca.lift(&c).iter().zip(&orig) {
        assert!((a - b).abs() < 0.02, "{a} vs {b}");
    }
}
