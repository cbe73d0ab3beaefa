//! The `eval` command line: its subcommands and [`run`], which the binary
//! and `batch` (the eval steps of a batch's runs) call.

use anyhow::Context;
use clap::{Parser, Subcommand};

use crate::commands::extract::{ExtractArgs, extract_command};
use crate::commands::gather::{GatherArgs, gather_command};
use crate::commands::query::{QueryArgs, query_command};
use crate::commands::render::{RenderArgs, render_command};
use crate::commands::segment::{SegmentArgs, segment_command};
use crate::commands::uncertainty::{UncertaintyArgs, uncertainty_command};
use crate::commands::view::{ViewArgs, view_command};
use field_ops::stages::StageLog;

/// Zero-shot 3D semantic segmentation, relevancy queries and rendering of trained runs.
#[derive(Debug, Parser)]
#[command(name = "eval", version, about)]
pub struct Cli {
    /// The command.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
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
    /// The benchmark table of a batch directory (`batch`'s output, or any
    /// directory of runs): held-out PSNR and mIoU / mAcc (all, head, common,
    /// tail) per scene as mean +- std over its runs, and their mean over
    /// scenes, as CSV, Markdown and a PNG chart; failed and unfinished runs
    /// are listed.
    Gather(GatherArgs),
}

/// Runs one command, printing what it wrote.
pub fn run(cli: Cli) -> anyhow::Result<()> {
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
        Command::Gather(a) => {
            for p in gather_command(&a)? {
                println!("wrote {}", p.display());
            }
        }
        Command::View(a) => {
            let why = view_command(&a)?;
            println!("viewer stopped: {why}");
        }
    }
    Ok(())
}
