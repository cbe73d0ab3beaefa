//! Training-step benchmark: rays/s, peak memory and achieved GFLOP/s of the
//! MLP on flex and ndarray side by side, against a plain matrix-product
//! ceiling measured in the same run, for the composited-hidden feature path
//! with top-k head evaluation, for the plain per-sample path, and for the
//! composited path behind an occupancy grid (the host-side clipping of the
//! batch included in the step time; an object in the middle of the box, so
//! a share of the rays is skipped and the rest sampled over a shorter span).
//!
//! With `--peer PYTHON` (a Python with jax) it first runs
//! `scripts/peer_step_jax.py`, the plain per-sample step written in JAX, with
//! the same sizes, prints it as a `jax` row and every row's step time as a
//! multiple of JAX's (`scripts/bench-peer.sh` makes such a Python).
//!
//! `cargo run -p bench --release --bin bench -- [--quick] [--steps N] [--peer PYTHON]`

mod ball;
mod cases;
mod peer;
mod profile;
mod report;

use cases::{CaseName, Setup, Timing, object_grid, time_case};
use report::Row;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use burn::tensor::{Device, Distribution, Tensor};
use clap::Parser;
use field_ops::backend::{BackendKind, BackendListArgs};
use model::{FeatureHeadConfig, FeatureMode, MipMlpConfig, OpenNerfConfig, Termination};
use train::backend::peak_memory_bytes;

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Benchmark options.
#[derive(Debug, Parser)]
#[command(name = "bench", about = "Training-step throughput per backend")]
struct Args {
    /// Small sizes (256 rays x 16+16 samples, width 64, 64-d head) for a quick check.
    #[arg(long)]
    quick: bool,
    /// Timed steps per case (after one untimed warm-up step).
    #[arg(long, default_value_t = 2)]
    steps: usize,
    /// Rays a training step [default: 1024; 256 with --quick].
    #[arg(long)]
    rays: Option<usize>,
    /// Samples per ray at each level [default: 32, i.e. 64 per ray over coarse
    /// and fine, the reference step's 64 samples; 16 with --quick].
    #[arg(long)]
    samples: Option<usize>,
    /// Samples whose weights feed the head in the composited path.
    #[arg(long, default_value_t = 16)]
    top_k: usize,
    /// Backends to measure (`--backend`, comma-separated) and wgpu's
    /// adapter (`--device`).
    #[command(flatten)]
    compute: BackendListArgs,
    /// A Python interpreter with jax: first times `scripts/peer_step_jax.py`
    /// (the plain per-sample step in JAX on the CPU) with the same sizes,
    /// prints it as a `jax` row and adds a "vs JAX" column (each row's step
    /// time divided by JAX's) to every row.
    #[arg(long, value_name = "PYTHON")]
    peer: Option<PathBuf>,
    /// Adam steps fitting the field's density to a ball of radius 1.2 before
    /// the timed steps, so that inference renders rays that end on a
    /// surface (0: the untrained field, a fog no ray ends in).
    #[arg(long, default_value_t = 60)]
    fit_steps: usize,
    /// Compute with subnormal floats as the CPU does by default instead of
    /// flushing them to zero as the workspace's binaries do (x86-64), to
    /// time what flushing saves.
    #[arg(long)]
    keep_subnormals: bool,
    /// Cases to run (all by default), e.g. `--cases plain` to profile one.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [CaseName::Composited, CaseName::Plain, CaseName::Grid, CaseName::Proposal, CaseName::Fast, CaseName::FastProposal])]
    cases: Vec<CaseName>,
    /// Samples evaluated between two checks of the early ray termination.
    #[arg(long, default_value_t = Termination::default().segment)]
    segment: usize,
    /// perf's control FIFO: `enable` is written to it before each case's
    /// timed steps and `disable` after them, so that `perf record -D -1
    /// --control fifo:FIFO` profiles the training steps alone
    /// (`scripts/profile-step.sh`).
    #[arg(long, value_name = "FIFO")]
    perf_control: Option<PathBuf>,
}

/// Sizes of one case.
#[derive(Debug, Clone, Copy)]
pub struct Size {
    rays: usize,
    samples: usize,
    width: usize,
    depth: usize,
    head_width: usize,
    feature_dim: usize,
}

impl Size {
    /// Multiply-add FLOPs (x2) of one forward pass of the field (the
    /// Mip-NeRF MLP, or the fast field's MLPs: its hash lookups are not
    /// counted) and head over both levels (with a proposal sampler: the
    /// field's one level and the proposal network's rounds); the backward
    /// pass costs twice that, hence x3 per step.
    fn step_flops(&self, config: &model::OpenNerfConfig, path: FeatureMode, top_k: usize) -> f64 {
        let (s, n) = (self.samples as f64, self.rays as f64);
        let (per_sample, per_ray_view, trunk) = match &config.fast {
            None => {
                let mlp = &config.mlp;
                let w = self.width as f64;
                let input = mlp.input_dim() as f64;
                let mut per_sample = input * w + (self.depth as f64 - 1.0) * w * w; // trunk
                if mlp.skip_layer > 0 && mlp.skip_layer < self.depth {
                    per_sample += input * w; // skip injection
                }
                per_sample += w + w * w + w * (w / 2.0) + (w / 2.0) * 3.0; // density, bottleneck, view, rgb
                (per_sample, mlp.view_dim() as f64 * (w / 2.0), w)
            }
            Some(f) => {
                let (dw, cw) = (f.density_width as f64, f.color_width as f64);
                let (enc, geo) = (f.grid.output_dim() as f64, f.geo_features as f64);
                let density = if f.density_layers == 0 {
                    enc * (1.0 + geo)
                } else {
                    enc * dw + (f.density_layers as f64 - 1.0) * dw * dw + dw * (1.0 + geo)
                };
                let color = geo * cw + (f.color_layers.max(1) as f64 - 1.0) * cw * cw + cw * 3.0;
                (density + color, f.view_dim() as f64 * cw, geo)
            }
        };
        let hw = self.head_width as f64;
        let hidden = trunk * hw + hw * hw; // two hidden head layers
        let head = match path {
            FeatureMode::None => 0.0,
            FeatureMode::PerSample => s * n * (hidden + hw * self.feature_dim as f64),
            FeatureMode::Composited => {
                let k = if top_k > 0 { (top_k as f64).min(s) } else { s };
                k * n * hidden + n * hw * self.feature_dim as f64
            }
        };
        let (levels, proposal_flops) = match &config.proposal {
            None => (2.0, 0.0),
            Some(p) => {
                let pw = p.width as f64;
                let pin = match &p.hash {
                    Some(h) => h.output_dim() as f64,
                    None => model::mip::ipe_dim(p.min_deg, p.max_deg) as f64,
                };
                let per = pin * pw + (p.depth.max(1) as f64 - 1.0) * pw * pw + pw;
                let samples: usize = p.samples.iter().sum();
                (1.0, n * samples as f64 * per)
            }
        };
        3.0 * 2.0 * (levels * (n * s * per_sample + n * per_ray_view) + head + proposal_flops)
    }
}

/// Resets the peak-RSS counter (Linux `clear_refs` 5; ignored elsewhere)
/// after returning the pages the allocator keeps to the OS, so that each
/// row's peak is its own.
fn reset_peak() {
    field_ops::allocator::release_freed_pages();
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// GFLOP/s of a `[4096, w] x [w, w]` product loop on `device`.
fn matmul_ceiling(device: &Device, w: usize) -> f64 {
    let a = Tensor::<2>::random([4096, w], Distribution::Default, device);
    let b = Tensor::<2>::random([w, w], Distribution::Default, device);
    let _ = a.clone().matmul(b.clone()).sum().into_scalar::<f32>();
    let reps = 20;
    let start = Instant::now();
    let mut acc = Tensor::<1>::zeros([1], device);
    for _ in 0..reps {
        acc = acc + a.clone().matmul(b.clone()).sum();
    }
    let _ = acc.into_scalar::<f32>();
    let secs = start.elapsed().as_secs_f64();
    reps as f64 * 2.0 * 4096.0 * (w * w) as f64 / secs / 1e9
}

/// The sizes asked for by `args`.
fn size_of(args: &Args) -> Size {
    let size = if args.quick {
        Size {
            rays: 256,
            samples: 16,
            width: 64,
            depth: 4,
            head_width: 64,
            feature_dim: 64,
        }
    } else {
        // The reference step: 1024 rays x 64 samples (32 coarse + 32 fine).
        Size {
            rays: 1024,
            samples: 32,
            width: 256,
            depth: 8,
            head_width: 256,
            feature_dim: 768,
        }
    };
    Size {
        rays: args.rays.unwrap_or(size.rays),
        samples: args.samples.unwrap_or(size.samples),
        ..size
    }
}

/// Times every case asked for on `backend` and prints its rows.
fn run_backend(
    args: &Args,
    size: Size,
    mlp: &MipMlpConfig,
    backend: BackendKind,
    peer: Option<&peer::Peer>,
) {
    let plain = args.compute.of(backend).device();
    let ceiling = matmul_ceiling(&plain, size.width);
    let ad = plain.clone().autodiff();
    let grid = object_grid();
    ad.seed(0);
    let base = OpenNerfConfig::new(FeatureHeadConfig::new(size.feature_dim))
        .with_mlp(mlp.clone())
        .init(&ad);
    let fit_start = Instant::now();
    let (fitted, fit_loss) = ball::fit(base, args.fit_steps, 8192, &ad);
    eprintln!(
        "{}: density fitted to the ball in {} steps ({:.1} s), relative squared error {:.3}",
        backend.name(),
        args.fit_steps,
        fit_start.elapsed().as_secs_f64(),
        fit_loss
    );
    let fast_asked = args
        .cases
        .iter()
        .any(|c| matches!(c, CaseName::Fast | CaseName::FastProposal));
    let fitted_fast = fast_asked.then(|| {
        let (_, case) = cases::cases(args.top_k)
            .into_iter()
            .find(|(name, _)| *name == CaseName::Fast)
            .expect("the fast case is listed");
        let fast = case.config(mlp, size).init(&ad);
        let (field, loss) = ball::fit(fast, args.fit_steps, 8192, &ad);
        eprintln!(
            "{}: the fast field's density fitted to the ball, relative squared error {loss:.3}",
            backend.name()
        );
        field
    });
    let setup = Setup {
        ad: &ad,
        size,
        mlp,
        fitted: &fitted,
        fitted_fast: fitted_fast.as_ref(),
        grid: &grid,
        steps: args.steps,
        segment: args.segment,
    };
    for (name, case) in cases::cases(args.top_k) {
        if !args.cases.contains(&name) {
            continue;
        }
        reset_peak();
        let Timing {
            secs,
            rendered,
            infer,
        } = time_case(&setup, case);
        let flops = Size {
            rays: rendered,
            ..size
        }
        .step_flops(&case.config(mlp, size), case.path, case.top_k);
        let row = Row {
            backend: backend.name().to_string(),
            path: if case.top_k > 0 {
                format!("{} (k={})", case.label, case.top_k)
            } else {
                case.label.to_string()
            },
            secs,
            rays: size.rays,
            flops,
            matmul: ceiling,
            peak_mb: peak_memory_bytes().unwrap_or(0) as f64 / 1e6,
            infer: Some(infer),
        };
        report::print_row(&row, peer);
    }
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    if args.keep_subnormals {
        eprintln!("subnormals: kept (--keep-subnormals)");
    } else {
        field_ops::subnormals::flush_to_zero();
    }
    args.compute.check().map_err(anyhow::Error::msg)?;
    for (flag, value) in [
        ("--rays", args.rays),
        ("--samples", args.samples),
        ("--steps", Some(args.steps)),
    ] {
        if value == Some(0) {
            anyhow::bail!("{flag} 0: at least 1");
        }
    }
    if let Some(fifo) = &args.perf_control {
        profile::open(fifo)
            .with_context(|| format!("--perf-control {}: cannot open it", fifo.display()))?;
    }
    let size = size_of(&args);
    let skip = if size.depth > 4 { 4 } else { size.depth / 2 };
    let mlp = MipMlpConfig::new()
        .with_width(size.width)
        .with_depth(size.depth)
        .with_skip_layer(skip);
    println!(
        "step: {} rays x {}+{} samples, trunk {} x {}, head 2 x {} -> {}, Adam; {} timed steps",
        size.rays,
        size.samples,
        size.samples,
        size.depth,
        size.width,
        size.head_width,
        size.feature_dim,
        args.steps
    );
    let peer = match &args.peer {
        Some(python) => Some(peer::run(python, size, skip, args.steps)?),
        None => None,
    };
    report::print_header(peer.as_ref());
    if let Some(p) = &peer {
        let config = model::OpenNerfConfig::new(FeatureHeadConfig::new(size.feature_dim))
            .with_mlp(mlp.clone());
        let ours = size.step_flops(&config, FeatureMode::PerSample, 0);
        if (p.flops - ours).abs() > 1e-6 * ours {
            eprintln!(
                "warning: the JAX peer counts {:.3} GFLOP per step, bench {:.3}",
                p.flops / 1e9,
                ours / 1e9
            );
        }
        let row = Row {
            backend: "jax".into(),
            path: "per-sample (plain)".into(),
            secs: p.secs,
            rays: size.rays,
            flops: p.flops,
            matmul: p.matmul,
            peak_mb: p.peak_mb,
            infer: None,
        };
        report::print_row(&row, peer.as_ref());
    }
    for &backend in &args.compute.backend {
        run_backend(&args, size, &mlp, backend, peer.as_ref());
    }
    report::print_notes(size, args.fit_steps, peer.is_some());
    Ok(())
}
