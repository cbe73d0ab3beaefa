//! `train`: trains an OpenNeRF field and writes a run directory.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = train::cli::Cli::parse();
    match train::run_cli(&cli) {
        Ok(outcome) => {
            let s = &outcome.summary;
            println!(
                "done: {} iterations, held-out PSNR {:.2} dB{}{}, {:.0} rays/s, {:.1} s",
                s.iterations,
                s.heldout_psnr,
                s.heldout_depth_mae
                    .map(|d| format!(", depth MAE {d:.3} m"))
                    .unwrap_or_default(),
                s.heldout_feature_cosine
                    .map(|c| format!(", feature cosine {c:.3}"))
                    .unwrap_or_default(),
                s.rays_per_second,
                s.wall_seconds
            );
            println!("results in {}", outcome.dir.display());
            println!(
                "  summary.json, metrics.jsonl, renders/, model.bpk (evaluate with the eval crate)"
            );
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
