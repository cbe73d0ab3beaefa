//! Using a trained run from another program, through the libraries' public
//! API only: load the run, render one of its cameras, and find the scene's
//! points that match a class name.
//!
//!     cargo run -p field-ops --release --example query_run -- runs/first sofa
//!
//! (`runs/first` from `cargo run -p train --release -- --out runs/first`.)

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use burn::tensor::Device;
use field_ops::query::{cosine_scores, embedding_by_name};
use field_ops::render::{ViewSettings, render_view};
use field_ops::run_dir::{load_run, load_run_scene};
use field_ops::sample::sampled_features;
use field_ops::similarity::ClassScorer;

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let (Some(run), Some(class)) = (args.next(), args.next()) else {
        bail!("usage: query_run RUN_DIR CLASS_NAME (e.g. runs/first sofa)");
    };
    let device = Device::flex();

    // The field with its weights, configuration and scene metadata.
    let run = load_run(&PathBuf::from(&run), &device).with_context(|| format!("loading {run}"))?;
    let mut split = run.split.clone();
    let scene = load_run_scene(&run.dir, &run.meta, &mut split).context("rebuilding the scene")?;
    println!(
        "{}: {} frames, head of {} channels",
        scene.name,
        scene.frames.len(),
        run.config.head.out_dim
    );

    // One camera of the capture, rendered at a quarter of its size.
    let frame = &scene.frames[split.heldout.first().copied().unwrap_or(0)];
    let k = &frame.camera.intrinsics;
    let camera = frame
        .camera
        .scaled((k.width / 4).max(1), (k.height / 4).max(1));
    let settings = ViewSettings::new(run.meta.background, 4096);
    let view = render_view(&run.model, &camera, &run.meta.scene_box, &settings)
        .expect("never cancelled without an observer");
    let opacity = view.acc.iter().sum::<f32>() / view.pixels() as f32;
    println!(
        "rendered {} ({}x{}): mean opacity {opacity:.3}",
        frame.name, view.width, view.height
    );

    // The scene's points scored against the class's text embedding.
    let (Some(points), Some(classes)) = (&scene.points, &scene.classes) else {
        bail!("the scene has no point cloud or class embeddings to query");
    };
    let positions: Vec<[f64; 3]> = points.positions.clone();
    let features = sampled_features(
        &run.model,
        &positions,
        &run.meta.scene_box,
        0.01,
        8192,
        &device,
    );
    let pca = run.meta.pca.as_ref();
    let query = embedding_by_name(classes, &class)?;
    let scores = cosine_scores(&features, &query, pca)?;
    // The class each point matches best, among all of the scene's classes.
    let scorer = ClassScorer::new(&classes.data, classes.dim, pca)?;
    let wanted = classes.index_of(&class).expect("found above") as u32;
    let k = scorer.dim;
    let matched = features
        .chunks(k)
        .filter(|f| scorer.argmax(f) == wanted)
        .count();
    let best = scores.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    println!(
        "{class}: {matched} of {} points match it best (highest cosine {best:.3})",
        positions.len()
    );
    Ok(())
}
