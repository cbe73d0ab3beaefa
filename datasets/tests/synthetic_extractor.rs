//! The external-command extractor, driven by small shell scripts.

use std::path::Path;

use datasets::extractor::{CommandExtractor, FeatureExtractor};
use datasets::npy::{write_npy_f16, write_npy_f32};
use datasets::scene::RgbImage;

fn image(w: u32, h: u32) -> RgbImage {
    RgbImage {
        width: w,
        height: h,
        data: datasets::RgbData::F32((0..w * h * 3).map(|i| (i % 7) as f32 / 7.0).collect()),
    }
}

/// A script that copies the prepared `.npy` (its first argument) to
/// `<output_dir>/<name>.npy` for every `<name>.png` in the input directory,
/// and also records the PNG sizes it saw.
fn copy_script(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("extract.sh");
    std::fs::write(
        &path,
        "#!/bin/sh\nset -e\nsrc=\"$1\"; in=\"$2\"; out=\"$3\"\n\
         for f in \"$in\"/*.png; do n=$(basename \"$f\" .png); cp \"$src\" \"$out/$n.npy\"; done\n",
    )
    .unwrap();
    path
}

#[test]
fn reads_back_the_maps_the_command_writes() {
    let tmp = tempfile::tempdir().unwrap();
    let script = copy_script(tmp.path());
    let (h, w, d) = (3usize, 4usize, 5usize);
    let values: Vec<f32> = (0..h * w * d).map(|i| i as f32 * 0.25 - 3.0).collect();
    for (name, f16) in [("f32.npy", false), ("f16.npy", true)] {
        let npy = tmp.path().join(name);
        if f16 {
            let v: Vec<half::f16> = values.iter().map(|&x| half::f16::from_f32(x)).collect();
            write_npy_f16(&npy, &[h, w, d], &v).unwrap();
        } else {
            write_npy_f32(&npy, &[h, w, d], &values).unwrap();
        }
        let ex = CommandExtractor::new(
            "sh",
            vec![script.display().to_string(), npy.display().to_string()],
            d,
        );
        assert_eq!(ex.dim(), d);
        let map = ex.extract(&image(16, 12)).unwrap();
        assert_eq!((map.height, map.width, map.dim), (h as u32, w as u32, d));
        let got: Vec<f32> = map.data.iter().map(|v| v.to_f32()).collect();
        assert_eq!(got, values, "values are multiples of 1/4: exact in f16");
        let two = ex
            .extract_many(&[("a", &image(16, 12)), ("b", &image(16, 12))])
            .unwrap();
        assert_eq!(two.len(), 2);
        assert_eq!(two[0], map);
    }
}

#[test]
fn the_command_sees_the_images_as_pngs() {
    let tmp = tempfile::tempdir().unwrap();
    // Fails unless the input is a PNG of the right size (checked by its header bytes).
    let script = tmp.path().join("check.sh");
    let npy = tmp.path().join("m.npy");
    write_npy_f32(&npy, &[1, 1, 2], &[1.0, 2.0]).unwrap();
    std::fs::write(
        &script,
        "#!/bin/sh\nset -e\nsrc=\"$1\"; in=\"$2\"; out=\"$3\"\n\
         f=\"$in/image.png\"\n\
         head -c 8 \"$f\" | od -An -tx1 | tr -d ' \\n' | grep -q '^89504e470d0a1a0a$'\n\
         cp \"$src\" \"$out/image.npy\"\n",
    )
    .unwrap();
    let ex = CommandExtractor::new(
        "sh",
        vec![script.display().to_string(), npy.display().to_string()],
        2,
    );
    let map = ex.extract(&image(5, 3)).unwrap();
    assert_eq!(
        map.data.iter().map(|v| v.to_f32()).collect::<Vec<_>>(),
        vec![1.0, 2.0]
    );
}

#[test]
fn clear_errors_for_missing_command_failure_and_missing_output() {
    let tmp = tempfile::tempdir().unwrap();
    let img = image(8, 6);

    let missing = CommandExtractor::new(tmp.path().join("no-such-extractor"), vec![], 4);
    let e = missing.extract(&img).unwrap_err().to_string();
    assert!(
        e.contains("no-such-extractor") && e.contains("cannot run"),
        "{e}"
    );

    let failing = tmp.path().join("fail.sh");
    std::fs::write(
        &failing,
        "#!/bin/sh\necho 'model weights not found' >&2\nexit 3\n",
    )
    .unwrap();
    let ex = CommandExtractor::new("sh", vec![failing.display().to_string()], 4);
    let e = ex.extract(&img).unwrap_err().to_string();
    assert!(
        e.contains("model weights not found") && e.contains('3'),
        "{e}"
    );

    let silent = tmp.path().join("silent.sh");
    std::fs::write(&silent, "#!/bin/sh\nexit 0\n").unwrap();
    let ex = CommandExtractor::new("sh", vec![silent.display().to_string()], 4);
    let e = ex.extract(&img).unwrap_err().to_string();
    assert!(
        e.contains("image.npy") && e.contains("no feature map"),
        "{e}"
    );

    // Wrong feature dimension.
    let script = copy_script(tmp.path());
    let npy = tmp.path().join("m.npy");
    write_npy_f32(&npy, &[1, 1, 3], &[0.0; 3]).unwrap();
    let ex = CommandExtractor::new(
        "sh",
        vec![script.display().to_string(), npy.display().to_string()],
        4,
    );
    let e = ex.extract(&img).unwrap_err().to_string();
    assert!(e.contains("dim 4"), "{e}");
}

#[test]
fn a_batch_runs_the_command_once_and_keeps_the_images_order() {
    let tmp = tempfile::tempdir().unwrap();
    // Counts its runs, and writes each image's map with its size in it, so
    // that maps coming back in another order would show.
    let script = tmp.path().join("count.sh");
    let runs = tmp.path().join("runs.txt");
    std::fs::write(
        &script,
        "#!/bin/sh\nset -e\nruns=\"$1\"; npydir=\"$2\"; in=\"$3\"; out=\"$4\"\necho run >> \"$runs\"\n\
         for f in \"$in\"/*.png; do n=$(basename \"$f\" .png); \
         w=$(od -An -tu1 -j16 -N4 \"$f\" | awk '{print $4}'); \
         cp \"$npydir/w$w.npy\" \"$out/$n.npy\"; done\n",
    )
    .unwrap();
    for w in [16u32, 17, 18] {
        write_npy_f32(
            &tmp.path().join(format!("w{w}.npy")),
            &[1, 1, 1],
            &[w as f32],
        )
        .unwrap();
    }
    let ex = CommandExtractor::new(
        "sh",
        vec![
            script.display().to_string(),
            runs.display().to_string(),
            tmp.path().display().to_string(),
        ],
        1,
    );
    let images = [image(18, 12), image(16, 12), image(17, 12)];
    let refs: Vec<&RgbImage> = images.iter().collect();
    let maps = ex.extract_batch(&refs).unwrap();
    let widths: Vec<f32> = maps.iter().map(|m| m.data[0].to_f32()).collect();
    assert_eq!(widths, vec![18.0, 16.0, 17.0]);
    assert_eq!(std::fs::read_to_string(&runs).unwrap().lines().count(), 1);
    assert!(ex.extract_batch(&[]).unwrap().is_empty());
    assert_eq!(std::fs::read_to_string(&runs).unwrap().lines().count(), 1);
}
