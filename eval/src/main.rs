//! `eval`: segment, query and render trained OpenNeRF runs.

use anyhow::Context;
use clap::{Parser, Subcommand};
use eval::commands::extract::{ExtractArgs, extract_command};
use eval::commands::query::{QueryArgs, query_command};
use eval::commands::render::{RenderArgs, render_command};
use eval::commands::segment::{SegmentArgs, segment_command};
use eval::commands::uncertainty::{UncertaintyArgs, uncertainty_command};
use eval::commands::view::{ViewArgs, view_command};
use field_ops::stages::StageLog;

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Zero-shot 3D semantic segmentation, relevancy queries and rendering of trained runs.
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Segment a point cloud and score it (mIoU / mAcc, all / head / common / tail).
    Segment(SegmentArgs),
    /// Relevancy images (and per-point relevancy) for a class name or embedding.
    Query(QueryArgs),
    /// Render colour, depth and feature-PCA images at cameras.
    Render(RenderArgs),
    /// Per-point uncertainty of the training feature maps (log det of their
    /// covariance), its correlation with the feature error, a scatter plot
    /// and a point cloud coloured by uncertainty.
    Uncertainty(UncertaintyArgs),
    /// Serve a web page of the run on this machine: the points by class,
    /// error or uncertainty, relevancy of typed text, the cameras, renders
    /// at the browser's camera. Runs until Ctrl-C.
    View(ViewArgs),
    /// Pixel-aligned CLIP feature maps of a capture's frames (dense
    /// NACLIP / ClearCLIP / MaskCLIP features of a CLIP model's vision
    /// tower), as `.npy` with PNG previews; `train --vlm MODEL
    /// --features-out DIR` reuses them.
    Extract(ExtractArgs),
}

fn main() -> std::process::ExitCode {
    // Printed as one line per cause (not through `main`'s `Debug`, which adds
    // a backtrace whenever RUST_BACKTRACE is set), like `train`.
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Segment(a) => {
            let mut stages = StageLog::for_run(&a.run);
            stages.begin("eval segment");
            segment_command(&a)?;
            stages
                .end()
                .context("recording the stage's time and memory")?;
        }
        Command::Query(a) => {
            for p in query_command(&a)? {
                println!("wrote {}", p.display());
            }
        }
        Command::Render(a) => {
            for p in render_command(&a)? {
                println!("wrote {}", p.display());
            }
        }
        Command::Uncertainty(a) => {
            let mut stages = StageLog::for_run(&a.run);
            stages.begin("eval uncertainty");
            let written = uncertainty_command(&a)?;
            stages
                .end()
                .context("recording the stage's time and memory")?;
            for p in written {
                println!("wrote {}", p.display());
            }
        }
        Command::Extract(a) => {
            let written = extract_command(&a)?;
            println!(
                "wrote {} feature maps and previews into {}",
                written
                    .iter()
                    .filter(|p| p.extension().is_some_and(|e| e == "npy"))
                    .count(),
                a.out.display()
            );
        }
        Command::View(a) => {
            let why = view_command(&a)?;
            println!("viewer stopped: {why}");
        }
    }
    Ok(())
}
