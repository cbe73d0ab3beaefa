//! Parity of the vision tower with the reference implementations, on the
//! fixtures `tests/clip_vision_reference.py` wrote: tiny random CLIP models
//! saved by `transformers` (Hugging Face naming) and `open_clip` (OpenAI's
//! layout: packed attention, a `visual.proj` matrix, quick-GELU), their
//! pooled image embeddings, the three dense variants at a 5x7 patch grid
//! (position embeddings stretched from the native 4x4), the image resizing
//! both ways and the sliding-window assembly, computed in PyTorch from the
//! formulas.

use std::path::{Path, PathBuf};

use burn::tensor::{Device, Tensor, TensorData};
use clip::vision::{DenseOptions, VisionModel};
use model::clip::DenseVariant;
use serde_json::Value;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/vision")
}

fn devices() -> Vec<(&'static str, Device)> {
    #[allow(deprecated)] // ndarray is the reference backend
    let ndarray = Device::ndarray();
    vec![("flex", Device::flex()), ("ndarray", ndarray)]
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn floats(v: &Value) -> Vec<f32> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number") as f32)
        .collect()
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "lengths");
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            if x.is_finite() {
                (x - y).abs()
            } else {
                f32::INFINITY
            }
        })
        .fold(0.0, f32::max)
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
        let shrunk = model::clip::sliding::WindowPlan {
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
