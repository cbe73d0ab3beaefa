//! `train`: trains an OpenNeRF field and writes a run directory.

use clap::Parser;

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

fn main() -> std::process::ExitCode {
    let cli = train::cli::Cli::parse();
    // Subnormals flushed to zero: docs/measurements/cpu-step.md.
    field_ops::subnormals::flush_to_zero();
    let stop = train::interrupt::StopFlag::on_signals().unwrap_or_else(|e| {
        eprintln!("warning: signals will stop the run without a checkpoint: {e}");
        train::interrupt::StopFlag::new()
    });
    match train::run_cli(&cli, &stop) {
        Ok(outcome) => {
            let s = &outcome.summary;
            let h = &s.heldout_interior;
            println!(
                "done: {} iterations, held-out PSNR {:.2} dB on interior pixels{}{}{}{}, {:.0} rays/s training{}, {:.1} s",
                s.iterations,
                h.psnr,
                h.ssim.map(|v| format!(", SSIM {v:.3}")).unwrap_or_default(),
                s.heldout_whole
                    .map(|w| format!(" ({:.2} dB on every pixel)", w.psnr))
                    .unwrap_or_default(),
                h.depth_mae
                    .map(|d| format!(", depth MAE {d:.3} m"))
                    .unwrap_or_default(),
                h.feature_cosine
                    .map(|c| format!(", feature cosine {c:.3}"))
                    .unwrap_or_default(),
                s.rays_per_second,
                s.render_rays_per_second
                    .map(|r| format!(", {r:.0} rays/s final render"))
                    .unwrap_or_default(),
                s.wall_seconds
            );
            println!("results in {}", outcome.dir.display());
            println!("  {}", train::report::result_files(&outcome.dir).join(", "));
            println!("next:");
            if let Some(command) = train::report::resume_command(&outcome.dir, s.iterations) {
                println!("  {command}");
            }
            for command in train::report::next_commands(&outcome.dir) {
                println!("  {command}");
            }
            std::process::ExitCode::SUCCESS
        }
        Err(e @ train::TrainError::Interrupted { .. }) => {
            eprintln!("{e}");
            std::process::ExitCode::from(train::interrupt::EXIT_INTERRUPTED)
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
