//! The capture's kind decides its defaults, whatever format it comes in:
//! lego's rendered views written as a COLMAP text model without points
//! train as the rendered object they are, within 1 dB of the same views
//! read through `transforms.json` with the same preset.

mod common;

use common::{s, text, train};

/// Iterations of each run: `LEGO_PRESET_ITERS` (the preset's own 1600 for
/// the figure in docs/reference/capture-defaults.md), 400 by default.
fn iterations() -> String {
    std::env::var("LEGO_PRESET_ITERS").unwrap_or_else(|_| "400".into())
}

fn psnr(run: &std::path::Path) -> f64 {
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("summary.json")).expect("summary"))
            .expect("summary.json parses");
    summary["heldout_interior"]["psnr"]
        .as_f64()
        .expect("held-out PSNR")
}

#[test]
fn lego_through_a_points_less_colmap_model_trains_as_through_transforms_json() {
    let Some(lego) = datasets::shared_dataset("lego_train") else {
        return;
    };
    let tmp = tempfile::tempdir().expect("tmp");
    let opts = datasets::blender::BlenderOptions {
        downscale: 8,
        ..datasets::blender::BlenderOptions::default()
    };
    let scene = datasets::blender::load_blender(&lego, &opts).expect("lego");
    let colmap = tmp.path().join("lego-colmap");
    datasets::writer::write_colmap_text(&scene, &colmap, datasets::writer::ImageFormat::Png)
        .expect("written");
    let iters = iterations();
    let mut results = Vec::new();
    for (name, data) in [
        ("transforms", vec!["--data", s(&lego), "--downscale", "8"]),
        ("colmap", vec!["--data", s(&colmap)]),
    ] {
        let out = tmp.path().join(name);
        let mut args = data.clone();
        args.extend([
            "--preset",
            "fast",
            "--iters",
            &iters,
            "--quiet",
            "--out",
            s(&out),
        ]);
        let o = train(&args);
        let (_, err) = text(&o);
        assert!(o.status.success(), "{err}");
        assert!(err.contains("capture: a rendered object"), "{name}: {err}");
        assert!(
            err.contains("field: box (auto: a rendered object")
                && err.contains("preset fast with the object settings"),
            "{name}: {err}"
        );
        if name == "colmap" {
            assert!(err.contains("background: (1.000, 1.000, 1.000)"), "{err}");
        }
        results.push(psnr(&out));
    }
    eprintln!(
        "lego, --preset fast, {iters} iterations: transforms.json {:.2} dB, COLMAP without \
         points {:.2} dB",
        results[0], results[1]
    );
    assert!(
        (results[0] - results[1]).abs() < 1.0,
        "transforms.json {:.2} dB, COLMAP {:.2} dB",
        results[0],
        results[1]
    );
}
