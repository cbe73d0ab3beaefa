//! `eval`: segment, query and render trained OpenNeRF runs.

use clap::Parser;

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

fn main() -> std::process::ExitCode {
    // Subnormals flushed to zero: docs/measurements/cpu-step.md.
    field_ops::subnormals::flush_to_zero();
    // Printed as one line per cause (not through `main`'s `Debug`, which adds
    // a backtrace whenever RUST_BACKTRACE is set), like `train`.
    match eval::cli::run(eval::cli::Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
