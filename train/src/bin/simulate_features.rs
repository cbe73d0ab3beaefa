//! Simulated pixel-aligned feature maps for a capture on disk: the
//! built-in simulated VLM (class probabilities from colour prototypes,
//! mixed from real class text embeddings, at a quarter of the image's
//! resolution, with noise) run on every frame, written as
//! `<frame name>.npy` for `train --features DIR`, and the simulated
//! classes' embeddings as `classes/embeddings.npy` + `classes/names.txt`
//! for `eval segment --embeddings --names`.
//!
//! It stands in for a real 2D open-vocabulary model where none is at hand,
//! so the whole pipeline (training the feature head, `eval segment` on the
//! capture's points) can run on real geometry; the classes it "sees" are
//! the colours given, not objects.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Parser;
use datasets::extractor::{FeatureExtractor, SimulatedExtractor};
use datasets::text::TextEmbeddings;
use datasets::{LoaderOptions, SceneSource};

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Writes simulated feature maps for the frames of a scene on disk.
#[derive(Debug, Parser)]
#[command(name = "simulate_features")]
struct Args {
    /// Scene directory (format detected, default loader options).
    #[arg(long)]
    data: PathBuf,
    /// Class text embeddings (`C x D` .npy).
    #[arg(long)]
    embeddings: PathBuf,
    /// Class names for the embeddings, one per line.
    #[arg(long)]
    names: PathBuf,
    /// The classes to simulate, each with the colour the simulated VLM
    /// takes for it, comma-separated: `paper=#e6e6ea,desk=#a8805a`. Names
    /// must be in --names.
    #[arg(long)]
    classes: String,
    /// Seed of the simulated noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output directory (created; must not hold `.npy` files already).
    #[arg(long)]
    out: PathBuf,
}

/// `#rrggbb` as colours in `[0, 1]`.
fn parse_colour(s: &str) -> Result<[f32; 3]> {
    let hex = s.trim().trim_start_matches('#');
    if hex.len() != 6 || !hex.chars().all(|c| c.is_ascii_hexdigit()) {
        bail!("colour {s:?} is not #rrggbb");
    }
    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map(|v| v as f32 / 255.0);
    Ok([byte(0)?, byte(2)?, byte(4)?])
}

/// The classes of `--classes`: their embedding rows and colours.
fn classes(spec: &str, all: &TextEmbeddings) -> Result<(TextEmbeddings, Vec<[f32; 3]>)> {
    let mut names = Vec::new();
    let mut data = Vec::new();
    let mut colours = Vec::new();
    for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (name, colour) = item
            .split_once('=')
            .with_context(|| format!("--classes: {item:?} is not NAME=#rrggbb"))?;
        let name = name.trim();
        let row = all
            .index_of(name)
            .with_context(|| format!("--classes: {name:?} is not in --names"))?;
        names.push(name.to_string());
        data.extend_from_slice(all.row(row));
        colours.push(parse_colour(colour).with_context(|| format!("--classes: {name}"))?);
    }
    if names.is_empty() {
        bail!("--classes lists no class");
    }
    Ok((
        TextEmbeddings {
            names,
            dim: all.dim,
            data,
        },
        colours,
    ))
}

fn run(args: &Args) -> Result<()> {
    let texts = TextEmbeddings::load(&args.embeddings, &args.names)?;
    let (texts, colours) = classes(&args.classes, &texts)?;
    let extractor = SimulatedExtractor::new(texts.clone(), colours, args.seed)?;
    let format = datasets::detect::detect(&args.data)?.format;
    let loader: LoaderOptions = format.default_loader();
    let scene = datasets::load_scene(&SceneSource::Disk {
        loader,
        path: args.data.clone(),
    })?;
    check_out(&args.out)?;
    let bar = indicatif::ProgressBar::new(scene.frames.len() as u64);
    for frame in &scene.frames {
        let map = extractor.extract(&frame.rgb)?;
        let path = args.out.join(format!("{}.npy", frame.name));
        datasets::npy::write_npy_f16(
            &path,
            &[map.height as usize, map.width as usize, map.dim],
            &map.data,
        )?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let classes = args.out.join("classes");
    std::fs::create_dir_all(&classes)
        .with_context(|| format!("{}: cannot create", classes.display()))?;
    let (npy, names) = (classes.join("embeddings.npy"), classes.join("names.txt"));
    texts.save(&npy, &names)?;
    println!(
        "wrote {} maps of {} channels to {}, and the {} classes' embeddings to {} and {}",
        scene.frames.len(),
        extractor.dim(),
        args.out.display(),
        texts.names.len(),
        npy.display(),
        names.display()
    );
    Ok(())
}

/// Creates `out`, refusing one that already holds feature maps.
fn check_out(out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let taken = std::fs::read_dir(out)
        .with_context(|| format!("{}: cannot list", out.display()))?
        .filter_map(|e| e.ok())
        .any(|e| e.path().extension().is_some_and(|x| x == "npy"));
    if taken {
        bail!(
            "{}: already holds .npy feature maps (choose another --out)",
            out.display()
        );
    }
    Ok(())
}

fn main() -> Result<()> {
    // Subnormals flushed to zero: docs/measurements/cpu-step.md.
    field_ops::subnormals::flush_to_zero();
    run(&Args::parse())
}
