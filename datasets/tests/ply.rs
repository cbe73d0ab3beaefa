//! PLY files through `ply-rs-bw`: the bytes written, the extra scalar
//! properties, and malformed files giving typed errors that name the file.

use std::path::Path;

use datasets::DatasetError;
use datasets::points::{PointCloud, read_ply, write_ply};

fn assert_err<T: std::fmt::Debug>(r: Result<T, DatasetError>, file: &str, words: &[&str]) {
    let msg = r.expect_err("an error").to_string();
    assert!(msg.contains(file), "error {msg:?} does not name {file}");
    for w in words {
        assert!(msg.contains(w), "error {msg:?} does not mention {w:?}");
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write");
    p
}

#[test]
fn written_bytes_are_the_documented_layout() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("u.ply");
    let cloud = PointCloud {
        positions: vec![[0.5, -1.0, 2.25], [3.0, 4.0, -5.5]],
        colors: Some(vec![[1, 2, 3], [250, 128, 0]]),
        labels: Some(vec![7, -1]),
    };
    // As the uncertainty report writes it.
    let u = [0.25f32, 0.75];
    let views = [3.0f32, 0.0];
    write_ply(&p, &cloud, &[("uncertainty", &u), ("views", &views)]).expect("write");
    let mut want = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\n\
        property float x\nproperty float y\nproperty float z\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        property int label\nproperty float uncertainty\nproperty float views\nend_header\n"
        .to_vec();
    for i in 0..2 {
        for c in cloud.positions[i] {
            want.extend_from_slice(&(c as f32).to_le_bytes());
        }
        want.extend_from_slice(&cloud.colors.as_ref().unwrap()[i]);
        want.extend_from_slice(&(cloud.labels.as_ref().unwrap()[i] as i32).to_le_bytes());
        want.extend_from_slice(&u[i].to_le_bytes());
        want.extend_from_slice(&views[i].to_le_bytes());
    }
    assert_eq!(std::fs::read(&p).expect("read"), want);
    assert_eq!(read_ply(&p).expect("read back"), cloud);
    // Positions only.
    let bare = PointCloud {
        positions: vec![[1.0, 2.0, 3.0]],
        ..PointCloud::default()
    };
    write_ply(&p, &bare, &[]).expect("write");
    assert_eq!(read_ply(&p).expect("read back"), bare);
    // Property names that could not be read back are refused.
    assert_err(
        write_ply(&p, &bare, &[("two words", &[1.0])]),
        "u.ply",
        &["two words"],
    );
    assert_err(
        write_ply(&p, &bare, &[("x", &[1.0])]),
        "u.ply",
        &["'x'", "twice"],
    );
}

#[test]
fn big_endian_and_elements_before_the_vertices_read() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut bytes = b"ply\nformat binary_big_endian 1.0\ncomment c\nelement face 1\n\
        property list uchar int vertex_indices\nelement vertex 1\n\
        property double x\nproperty double y\nproperty double z\nproperty short class\nend_header\n"
        .to_vec();
    bytes.push(2);
    bytes.extend_from_slice(&5i32.to_be_bytes());
    bytes.extend_from_slice(&6i32.to_be_bytes());
    for c in [1.5f64, -2.0, 3.0] {
        bytes.extend_from_slice(&c.to_be_bytes());
    }
    bytes.extend_from_slice(&(-4i16).to_be_bytes());
    let p = write(dir.path(), "be.ply", &bytes);
    let c = read_ply(&p).expect("big endian");
    assert_eq!(c.positions, vec![[1.5, -2.0, 3.0]]);
    assert_eq!(c.labels, Some(vec![-4]));
    assert_eq!(c.colors, None);
}

#[test]
fn malformed_files_are_typed_errors_not_panics() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let header = |body: &str| format!("ply\nformat ascii 1.0\n{body}end_header\n");
    let xyz = "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n";
    let cases: Vec<(&str, Vec<u8>, &[&str])> = vec![
        ("magic.ply", b"obj\n".to_vec(), &["header"]),
        ("empty.ply", Vec::new(), &["header"]),
        (
            "noend.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\n".to_vec(),
            &["end_header"],
        ),
        (
            "noformat.ply",
            b"ply\nelement vertex 0\nend_header\n".to_vec(),
            &["format"],
        ),
        (
            "nov.ply",
            header("element face 0\n").into_bytes(),
            &["no vertex element"],
        ),
        (
            "list.ply",
            header(&format!("{xyz}property list uchar int idx\n")).into_bytes(),
            &["list property"],
        ),
        (
            "short.ply",
            format!("{}1 2\n", header(xyz)).into_bytes(),
            &["vertex 0"],
        ),
        (
            "word.ply",
            format!("{}1 2 abc\n", header(xyz)).into_bytes(),
            &["vertex 0"],
        ),
        (
            "ends.ply",
            header(xyz).into_bytes(),
            &["vertex 0", "file ends"],
        ),
        (
            "dup.ply",
            format!("{}1 2 3 4\n", header(&format!("{xyz}property float x\n"))).into_bytes(),
            &["vertex property 'x' twice"],
        ),
        (
            "dupelem.ply",
            header(&format!("{xyz}element face 0\nelement vertex 0\n")).into_bytes(),
            &["element 'vertex' twice"],
        ),
        (
            "huge.ply",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n\
              property float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0"
                .to_vec(),
            &["truncated", "vertex 0"],
        ),
        (
            "inf.ply",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n\
              property float x\nproperty float y\nproperty float z\nend_header\n\
              \0\0\x80\x7f\0\0\0\0\0\0\0\0"
                .to_vec(),
            &["non-finite"],
        ),
        (
            "badtype.ply",
            header("element vertex 1\nproperty float128 x\n").into_bytes(),
            &["header"],
        ),
    ];
    for (name, bytes, words) in cases {
        let p = write(d, name, &bytes);
        assert_err(read_ply(&p), name, words);
    }
    assert_err(read_ply(&d.join("missing.ply")), "missing.ply", &[]);
}

/// What `ply-rs-bw` does not read: its ascii grammar has no `nan` or `inf`
/// (nor `.5` or `5.`), so such values, which the hand-written reader took
/// where they were not coordinates, now make the file an error (a typed
/// one, naming the file and the vertex).
#[test]
fn ascii_nan_is_refused_by_the_crate() {
    let dir = tempfile::tempdir().expect("tmp");
    let body = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                property float z\nproperty float u\nend_header\n";
    for value in ["nan", "inf", ".5"] {
        let p = write(
            dir.path(),
            "nan.ply",
            format!("{body}1 2 3 {value}\n").as_bytes(),
        );
        assert_err(read_ply(&p), "nan.ply", &["vertex 0"]);
    }
    let p = write(
        dir.path(),
        "ok.ply",
        format!("{body}1 2 3 0.5\n").as_bytes(),
    );
    assert_eq!(
        read_ply(&p).expect("plain numbers").positions,
        vec![[1.0, 2.0, 3.0]]
    );
}
