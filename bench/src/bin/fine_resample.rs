//! The fine level's blur-resample in its two forms side by side, in one
//! run: with tensor ops (`resample_t_vals_on_device`: every quantile
//! compared with every CDF end, nothing read back) and on the host
//! (`resample_t_vals_on_host`: the posts and weights read back, one pass a
//! ray, the new posts uploaded), the CPU backends' form. The forms
//! alternate, step by step, so that a change in the machine's speed falls
//! on both alike; both draw jittered quantiles, as a training step does.
//!
//! `cargo run -p bench --release --bin fine_resample -- [--rays N] [--samples N] [--steps N] [--backend flex,ndarray]`

use std::time::Instant;

use anyhow::Result;
use burn::tensor::{Device, Distribution, Tensor};
use clap::Parser;
use field_ops::backend::BackendListArgs;
use model::stepfun::{resample_t_vals_on_device, resample_t_vals_on_host};

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Options.
#[derive(Debug, Parser)]
#[command(
    name = "fine_resample",
    about = "The fine level's resampling with tensor ops against on the host"
)]
struct Args {
    /// Rays a step [default: 256, the built-in batch].
    #[arg(long, default_value_t = 256)]
    rays: usize,
    /// Samples a ray at the coarse level [default: 48, the built-in
    /// number].
    #[arg(long, default_value_t = 48)]
    samples: usize,
    /// Timed steps of each form (after one untimed warm-up step each).
    #[arg(long, default_value_t = 20)]
    steps: usize,
    /// Backends to measure and wgpu's adapter.
    #[command(flatten)]
    compute: BackendListArgs,
}

/// One resampling in `host` form or not, waited for.
fn step(t: &Tensor<2>, w: &Tensor<2>, host: bool) {
    let posts = if host {
        resample_t_vals_on_host(t.clone(), w.clone(), 0.01, true)
    } else {
        resample_t_vals_on_device(t.clone(), w.clone(), 0.01, true)
    };
    posts.device().sync().expect("the device finishes its work");
}

/// Milliseconds a step of the tensor form and of the host form on
/// `device`, alternating.
fn measure(device: &Device, args: &Args) -> (f64, f64) {
    let (rays, n) = (args.rays, args.samples);
    // Sorted posts in [0, 1] and weights with empty stretches.
    let t = Tensor::<2>::random([rays, n + 1], Distribution::Uniform(0.0, 1.0), device)
        .sort(1)
        .detach();
    let w = Tensor::<2>::random([rays, n], Distribution::Uniform(-0.5, 1.0), device)
        .clamp_min(0.0)
        .detach();
    step(&t, &w, false);
    step(&t, &w, true);
    let (mut tensor_s, mut host_s) = (0.0, 0.0);
    for _ in 0..args.steps {
        let start = Instant::now();
        step(&t, &w, false);
        tensor_s += start.elapsed().as_secs_f64();
        let start = Instant::now();
        step(&t, &w, true);
        host_s += start.elapsed().as_secs_f64();
    }
    let per = 1e3 / args.steps as f64;
    (tensor_s * per, host_s * per)
}

fn main() -> Result<()> {
    let args = Args::parse();
    field_ops::subnormals::flush_to_zero();
    args.compute.check().map_err(anyhow::Error::msg)?;
    for (flag, value) in [
        ("--rays", args.rays),
        ("--samples", args.samples),
        ("--steps", args.steps),
    ] {
        if value == 0 {
            anyhow::bail!("{flag} 0: at least 1");
        }
    }
    println!(
        "the fine level's resampling: {} rays x {} samples, {} timed steps of each form",
        args.rays, args.samples, args.steps
    );
    println!("| backend | tensor ops, ms | host, ms | host / tensor ops |");
    println!("|---|---|---|---|");
    for &kind in &args.compute.backend {
        let device: Device = args.compute.of(kind).device();
        device.seed(1);
        let (tensor_ms, host_ms) = measure(&device, &args);
        println!(
            "| {} | {tensor_ms:.2} | {host_ms:.2} | {:.2} |",
            kind.name(),
            host_ms / tensor_ms
        );
    }
    Ok(())
}
