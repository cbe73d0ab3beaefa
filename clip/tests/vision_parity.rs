//! Parity of the vision tower with the reference implementations, on the
//! fixtures `tests/clip_vision_reference.py` wrote: tiny random CLIP models
//! saved by `transformers` (Hugging Face naming) and `open_clip` (OpenAI's
//! layout: packed attention, a `visual.proj` matrix, quick-GELU), their
//! pooled image embeddings, the three dense variants at a 5x7 patch grid
//! (position embeddings stretched from the native 4x4), the image resizing
//! both ways and the sliding-window assembly, computed in PyTorch from the
//! formulas. Two more tests need Python packages and are ignored by default
//! (see the README's testing section); run with `--ignored`, a missing
//! package fails them rather than skips them.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use burn::tensor::{Tensor, TensorData};
use clip::tower::DenseVariant;
use clip::vision::{DenseOptions, VisionModel};

mod common;
use common::{devices, floats, max_abs_diff, python, read_json, require_python};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/vision")
}

fn check(what: &str, dir: &Path, backend: &str, got: &[f32], want: &[f32]) {
    let diff = max_abs_diff(got, want);
    println!(
        "{}: {backend}: {what}: max abs difference {diff:.2e}",
        dir.display()
    );
    assert!(
        diff <= 1e-4,
        "{backend}: {what}: max abs difference {diff} on {}",
        dir.display()
    );
}

fn check_model(dir: &Path) {
    let r = read_json(&dir.join("reference.json"));
    for (backend, device) in devices() {
        let m = VisionModel::load(dir, &device).unwrap_or_else(|e| panic!("{backend}: {e}"));
        assert!(m.notes.is_empty(), "nothing assumed: {:?}", m.notes);
        // CLIP's pooled image embedding at the native size.
        let px = floats(&r["native_pixels"]);
        let t = Tensor::<4>::from_data(TensorData::new(px, [2, 3, 32, 32]), &device);
        let got = m.encoder.forward(t).try_into_vec_as::<f32>().expect("read");
        check(
            "image_embeds",
            dir,
            backend,
            &got,
            &floats(&r["image_embeds"]),
        );
        // The three dense variants at a 5x7 grid.
        for v in DenseVariant::ALL {
            let got = m
                .dense_pixels(floats(&r["dense_pixels"]), [1, 3, 40, 56], v)
                .expect("dense");
            check(
                &format!("dense {v}"),
                dir,
                backend,
                &got,
                &floats(&r["dense"][v.name()]),
            );
        }
        // Sliding windows over a 45x70 image at short side 48.
        let s = &r["sliding"];
        let (h, w) = (
            s["height"].as_u64().unwrap() as usize,
            s["width"].as_u64().unwrap() as usize,
        );
        let rgb: Vec<f32> = s["image_rgb"]
            .as_array()
            .expect("image")
            .iter()
            .map(|x| x.as_f64().expect("byte") as f32 / 255.0)
            .collect();
        let options = DenseOptions {
            short_side: Some(s["short_side"].as_u64().unwrap() as usize),
            ..DenseOptions::default()
        };
        let plan = m.plan((h, w), &options).expect("plan");
        check(
            "resized (growing)",
            dir,
            backend,
            &m.preprocess(&rgb, (h, w), &plan),
            &floats(&s["resized"]),
        );
        // Shrinking (the antialiased path) to short side 16: below the
        // model's input, so no windows; the resizing alone.
        let down = &r["resize_down"];
        assert_eq!(down["short_side"].as_u64(), Some(16));
        let shrunk = clip::tower::sliding::WindowPlan {
            resized: (16, 24),
            ..plan.clone()
        };
        check(
            "resized (shrinking)",
            dir,
            backend,
            &m.preprocess(&rgb, (h, w), &shrunk),
            &floats(&down["resized"]),
        );
        let map = m.dense_map(&rgb, (h, w), &options).expect("map");
        let grid: Vec<usize> = s["grid"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap() as usize)
            .collect();
        assert_eq!((map.rows, map.cols), (grid[0], grid[1]));
        check(
            "sliding naclip",
            dir,
            backend,
            &map.data,
            &floats(&s["features"]),
        );
    }
}

#[test]
fn hugging_face_vision_tower_matches_transformers() {
    check_model(&fixtures().join("hf_tiny"));
}

#[test]
fn open_clip_vision_tower_in_openai_layout_matches_open_clip() {
    check_model(&fixtures().join("openclip_tiny"));
}

const REFERENCE_PACKAGES: &str = "pip install torch transformers open_clip_torch safetensors";

/// Runs `tests/clip_vision_reference.py ARGS`, failing with its stderr.
fn run_reference_script(args: &[&std::ffi::OsStr]) {
    require_python(
        "torch, transformers, open_clip, safetensors",
        REFERENCE_PACKAGES,
    );
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/clip_vision_reference.py");
    let run = Command::new(python())
        .arg(&script)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{}: {e}", python()));
    assert!(
        run.status.success(),
        "{}: {}",
        script.display(),
        String::from_utf8_lossy(&run.stderr)
    );
}

#[test]
#[ignore = "needs torch, transformers and open_clip_torch (several GB of Python packages)"]
fn regenerated_vision_references_match() {
    let out = tempfile::tempdir().expect("tmp");
    run_reference_script(&[out.path().as_os_str()]);
    check_model(&out.path().join("hf_tiny"));
    check_model(&out.path().join("openclip_tiny"));
}

/// A random Hugging Face `CLIPModel` with a ViT-B/16 vision tower (width
/// 768, 12 layers, 224 px, 16-px patches, 512-d) against `transformers`:
/// the pooled image embedding at 224 x 224 and NACLIP's dense features at
/// 224 x 336 (a 14 x 21 grid, position embeddings stretched). Ignored by
/// default (it writes 340 MB): `cargo test --release --workspace --test
/// vision_parity -- --ignored full_size`. `CLIP_VISION_FULL_SIZE_DIR` reuses
/// a directory made by `tests/clip_vision_reference.py --full-size DIR`.
#[test]
#[ignore = "writes and loads a 340 MB model"]
fn full_size_vit_b16_matches_transformers() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = match std::env::var_os("CLIP_VISION_FULL_SIZE_DIR") {
        Some(d) => PathBuf::from(d),
        None => {
            run_reference_script(&["--full-size".as_ref(), tmp.path().as_os_str()]);
            tmp.path().to_path_buf()
        }
    };
    let dir = root.join("hf_vit_b16");
    let r = read_json(&dir.join("reference.json"));
    let native = floats(&r["native_pixels"]);
    let dense = floats(&r["dense_pixels"]);
    for (backend, device) in devices() {
        let start = Instant::now();
        let m = VisionModel::load(&dir, &device).unwrap_or_else(|e| panic!("{backend}: {e}"));
        let loaded = start.elapsed().as_secs_f64();
        assert!(m.notes.is_empty(), "nothing assumed: {:?}", m.notes);
        let c = &m.config;
        assert_eq!(
            (
                c.width,
                c.layers,
                c.heads,
                c.patch_size,
                c.image_size,
                m.dim()
            ),
            (768, 12, 12, 16, 224, 512)
        );
        let start = Instant::now();
        let t = Tensor::<4>::from_data(TensorData::new(native.clone(), [1, 3, 224, 224]), &device);
        let got = m.encoder.forward(t).try_into_vec_as::<f32>().expect("read");
        let pooled = start.elapsed().as_secs_f64();
        let d_pooled = max_abs_diff(&got, &floats(&r["image_embeds"]));
        let start = Instant::now();
        let got = m
            .dense_pixels(dense.clone(), [1, 3, 224, 336], DenseVariant::Naclip)
            .expect("dense");
        let densed = start.elapsed().as_secs_f64();
        let d_dense = max_abs_diff(&got, &floats(&r["dense"]["naclip"]));
        println!(
            "hf_vit_b16, {backend}: load {loaded:.1} s; image_embeds (224x224) {pooled:.2} s, \
             max abs difference {d_pooled:.2e}; dense naclip (224x336, 14x21) {densed:.2} s, \
             max abs difference {d_dense:.2e}"
        );
        assert!(d_pooled <= 1e-4, "{backend}: image_embeds: {d_pooled}");
        assert!(d_dense <= 1e-4, "{backend}: dense naclip: {d_dense}");
    }
}
