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
//! `cargo run -p train --release --bin bench -- [--quick] [--steps N] [--peer PYTHON]`

mod ball;
mod peer;

use std::path::PathBuf;
use std::time::Instant;

use burn::module::Module;
use burn::optim::AdamConfig;
use burn::tensor::{Device, Distribution, Tensor, TensorData};
use clap::Parser;
use field_ops::render::render_rays_with;
use model::geometry::NormalizedRay;
use model::{
    FeatureHeadConfig, FeatureMode, MipMlp, MipMlpConfig, OccupancyConfig, OccupancyGrid,
    OpenNerfConfig, Rays, Termination,
};
use train::backend::{BackendKind, device, peak_memory_bytes};
use train::batch::{BatchTensors, FeatureTargets};
use train::config::LossConfig;
use train::step::{StepRates, train_step_from};

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Benchmark options.
#[derive(Debug, Parser)]
#[command(name = "bench", about = "Training-step throughput on the CPU backends")]
struct Args {
    /// Small sizes (256 rays x 16+16 samples, width 64, 64-d head) for a quick check.
    #[arg(long)]
    quick: bool,
    /// Timed steps per case (after one untimed warm-up step).
    #[arg(long, default_value_t = 2)]
    steps: usize,
    /// Samples per ray at each level [default: 32, i.e. 64 per ray over coarse
    /// and fine, the reference step's 64 samples; 16 with --quick].
    #[arg(long)]
    samples: Option<usize>,
    /// Samples whose weights feed the head in the composited path.
    #[arg(long, default_value_t = 16)]
    top_k: usize,
    /// Backends to measure.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [BackendKind::Flex, BackendKind::Ndarray])]
    backends: Vec<BackendKind>,
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
    /// Cases to run (all by default), e.g. `--cases plain` to profile one.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [CaseName::Composited, CaseName::Plain, CaseName::Grid])]
    cases: Vec<CaseName>,
    /// Samples evaluated between two checks of the early ray termination.
    #[arg(long, default_value_t = Termination::default().segment)]
    segment: usize,
}

/// The cases `--cases` names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum CaseName {
    /// Composited hidden activations with the top-k head.
    Composited,
    /// The per-sample head (the plain formulation, JAX's).
    Plain,
    /// Composited + top-k behind the occupancy grid.
    Grid,
}

/// Sizes of one case.
#[derive(Debug, Clone, Copy)]
struct Size {
    rays: usize,
    samples: usize,
    width: usize,
    depth: usize,
    head_width: usize,
    feature_dim: usize,
}

impl Size {
    /// Multiply-add FLOPs (x2) of one forward pass of the MLP and head over
    /// both levels; the backward pass costs twice that, hence x3 per step.
    fn step_flops(&self, mlp: &MipMlpConfig, path: FeatureMode, top_k: usize) -> f64 {
        let (w, s, n) = (self.width as f64, self.samples as f64, self.rays as f64);
        let input = mlp.input_dim() as f64;
        let view = mlp.view_dim() as f64;
        let mut per_sample = input * w + (self.depth as f64 - 1.0) * w * w; // trunk
        if mlp.skip_layer > 0 && mlp.skip_layer < self.depth {
            per_sample += input * w; // skip injection
        }
        per_sample += w + w * w + w * (w / 2.0) + (w / 2.0) * 3.0; // density, bottleneck, view, rgb
        let per_ray_view = view * (w / 2.0);
        let hw = self.head_width as f64;
        let hidden = w * hw + hw * hw; // two hidden head layers
        let head = match path {
            FeatureMode::None => 0.0,
            FeatureMode::PerSample => s * n * (hidden + hw * self.feature_dim as f64),
            FeatureMode::Composited => {
                let k = if top_k > 0 { (top_k as f64).min(s) } else { s };
                k * n * hidden + n * hw * self.feature_dim as f64
            }
        };
        3.0 * 2.0 * (2.0 * (n * s * per_sample + n * per_ray_view) + head)
    }
}

fn rays(n: usize, seed: u64) -> Vec<NormalizedRay> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 33) as f64 / (1u64 << 31) as f64) as f32
    };
    let v: Vec<NormalizedRay> = (0..n)
        .map(|_| NormalizedRay {
            origin: [next() * 2.0 - 1.0, next() * 2.0 - 1.0, -2.5],
            direction: [next() - 0.5, next() - 0.5, 1.0],
            radius: 0.003,
            near: 0.2,
            far: 4.5,
        })
        .collect();
    v
}

/// A grid holding a ball of radius 1.2 at the centre of the box (an object
/// in empty space, as in the Blender scenes).
fn object_grid() -> OccupancyGrid {
    let mut grid = OccupancyGrid::new(&OccupancyConfig::new());
    let density: Vec<f32> = grid
        .sample_points(0)
        .iter()
        .map(|p| {
            let r2: f32 = p.iter().map(|v| v * v).sum();
            if r2 < 1.44 { 100.0 } else { 0.0 }
        })
        .collect();
    grid.update(&density);
    grid
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
        samples: args.samples.unwrap_or(size.samples),
        ..size
    }
}

/// One case: a feature path, the head's top-k, with or without the grid.
#[derive(Debug, Clone, Copy)]
struct Case {
    label: &'static str,
    path: FeatureMode,
    top_k: usize,
    with_grid: bool,
}

/// What one case measured.
#[derive(Debug, Clone, Copy)]
struct Timing {
    /// Mean seconds of a timed step.
    secs: f64,
    /// Rays rendered per step (fewer than drawn behind the grid).
    rendered: usize,
    /// Rendering the trained model (no autodiff, the same feature path, the
    /// grid when the case has one, as `eval render` does).
    infer: Inference,
}

/// Inference speed of one model, with and without early ray termination.
#[derive(Debug, Clone, Copy)]
struct Inference {
    /// Rays per second with the default termination (what every render uses).
    rays_per_s: f64,
    /// Rays per second evaluating every sample.
    all_samples_rays_per_s: f64,
    /// Share of the samples evaluated with termination.
    samples_share: f64,
}

/// What every case of one backend shares.
struct Setup<'a> {
    /// The autodiff device.
    ad: &'a Device,
    size: Size,
    mlp: &'a MipMlpConfig,
    /// The MLP with its density fitted to the ball.
    fitted: &'a MipMlp,
    grid: &'a OccupancyGrid,
    /// Timed steps.
    steps: usize,
    /// Samples between two termination checks.
    segment: usize,
}

/// Times `steps` steps (after one untimed warm-up step) of `case`.
fn time_case(setup: &Setup<'_>, case: Case) -> Timing {
    let Setup {
        ad,
        size,
        mlp,
        fitted,
        grid,
        steps,
        segment,
    } = *setup;
    ad.seed(0);
    let config =
        OpenNerfConfig::new(FeatureHeadConfig::new(size.feature_dim).with_width(size.head_width))
            .with_mlp(mlp.clone())
            .with_num_samples(size.samples)
            .with_head_top_k((case.top_k > 0).then_some(case.top_k));
    let mut model = config.init(ad);
    model.mlp = fitted.clone();
    let mut optim = AdamConfig::new().init();
    let n = size.rays;
    let host_rays = rays(n, 1);
    let batch_of = |r: &[NormalizedRay]| {
        let m = r.len();
        let target =
            |c: usize| Tensor::<2>::from_data(TensorData::new(vec![0.5f32; m * c], [m, c]), ad);
        BatchTensors {
            rays: Rays::from_normalized(r, ad),
            rgb: target(3),
            depth: None,
            feature: Some(FeatureTargets::dense(target(size.feature_dim))),
        }
    };
    let mut rendered = n;
    let rates = StepRates {
        base: 1e-4,
        head: 1e-4,
    };
    let mut times = Vec::new();
    for step in 0..=steps {
        let start = Instant::now();
        // The grid path clips the host rays every step, as training does.
        let batch = if case.with_grid {
            let clipped = grid.clip(&host_rays);
            rendered = clipped.kept.len();
            batch_of(&clipped.rays)
        } else {
            batch_of(&host_rays)
        };
        let out = model.render_with(&batch.rays, true, None, case.path);
        let (next, report) = train_step_from(
            model,
            &mut optim,
            out,
            &batch,
            &LossConfig::default(),
            rates,
        );
        model = next;
        let secs = start.elapsed().as_secs_f64();
        assert!(report.applied, "benchmark step produced a non-finite loss");
        if step > 0 {
            times.push(secs);
        }
    }
    Timing {
        secs: times.iter().sum::<f64>() / times.len().max(1) as f64,
        rendered,
        infer: inference(&model, case, grid, ad, n, segment),
    }
}

/// Rendering `4 n` fresh rays with `model` in chunks of 4096 on the device
/// without autodiff (after one warm-up chunk), with the default early
/// termination and with every sample evaluated.
fn inference(
    model: &model::OpenNerf,
    case: Case,
    grid: &OccupancyGrid,
    ad: &Device,
    n: usize,
    segment: usize,
) -> Inference {
    let plain = ad.clone().without_autodiff();
    let valid = model.valid();
    let valid = if case.with_grid {
        valid.with_occupancy(Some(grid.clone()))
    } else {
        valid
    };
    let mode = case.path;
    let many = rays(4 * n, 2);
    let time = |termination: Termination| {
        let _ = render_rays_with(&valid, &rays(256, 3), None, 4096, mode, termination, &plain);
        let start = Instant::now();
        let out = render_rays_with(&valid, &many, None, 4096, mode, termination, &plain);
        let secs = start.elapsed().as_secs_f64();
        (many.len() as f64 / secs, out.samples_evaluated)
    };
    let (all_samples_rays_per_s, all) = time(Termination::off());
    let (rays_per_s, evaluated) = time(Termination {
        segment,
        ..Termination::default()
    });
    Inference {
        rays_per_s,
        all_samples_rays_per_s,
        samples_share: evaluated as f64 / all.max(1) as f64,
    }
}

/// One row of the table.
struct Row {
    backend: String,
    path: String,
    secs: f64,
    rays: usize,
    flops: f64,
    matmul: f64,
    peak_mb: f64,
    /// Inference (none for the peer).
    infer: Option<Inference>,
}

/// Prints the header (and the ratio's convention when there is a peer).
fn print_header(peer: Option<&peer::Peer>) {
    if let Some(p) = peer {
        println!(
            "vs JAX: this row's step time / the JAX step time (jax {}, {} threads): \
             1.49x = takes 1.49 times as long as JAX, below 1 = faster",
            p.version, p.threads
        );
    }
    print!(
        "{:<8} {:<26} {:>9} {:>10} {:>9} {:>10} {:>10} {:>7}",
        "backend", "feature path", "step s", "rays/s", "GFLOP", "GFLOP/s", "matmul", "peak MB"
    );
    print!(
        " {:>12} {:>8} {:>10} {:>9}",
        "infer rays/s", "x train", "all-sample", "samples %"
    );
    println!("{}", if peer.is_some() { "   vs JAX" } else { "" });
}

/// Prints `row`, with its step time over the peer's when there is one.
fn print_row(row: &Row, peer: Option<&peer::Peer>) {
    print!(
        "{:<8} {:<26} {:>9.3} {:>10.0} {:>9.1} {:>10.1} {:>10.1} {:>7.0}",
        row.backend,
        row.path,
        row.secs,
        row.rays as f64 / row.secs,
        row.flops / 1e9,
        row.flops / row.secs / 1e9,
        row.matmul,
        row.peak_mb
    );
    match row.infer {
        Some(i) => print!(
            " {:>12.0} {:>7.1}x {:>10.0} {:>9.1}",
            i.rays_per_s,
            i.rays_per_s * row.secs / row.rays as f64,
            i.all_samples_rays_per_s,
            100.0 * i.samples_share
        ),
        None => print!(" {:>12} {:>8} {:>10} {:>9}", "-", "-", "-", "-"),
    }
    match peer {
        Some(p) => println!(" {:>8.2}x", row.secs / p.secs),
        None => println!(),
    }
}

/// The Burn cases, in the order printed, with their names.
fn cases(top_k: usize) -> [(CaseName, Case); 3] {
    [
        (
            CaseName::Composited,
            Case {
                label: "composited + top-k",
                path: FeatureMode::Composited,
                top_k,
                with_grid: false,
            },
        ),
        (
            CaseName::Plain,
            Case {
                label: "per-sample (plain)",
                path: FeatureMode::PerSample,
                top_k: 0,
                with_grid: false,
            },
        ),
        (
            CaseName::Grid,
            Case {
                label: "composited + grid",
                path: FeatureMode::Composited,
                top_k,
                with_grid: true,
            },
        ),
    ]
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
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
    print_header(peer.as_ref());
    if let Some(p) = &peer {
        let ours = size.step_flops(&mlp, FeatureMode::PerSample, 0);
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
        print_row(&row, peer.as_ref());
    }
    let cases = cases(args.top_k);
    for &backend in &args.backends {
        let plain = device(backend, None);
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
        let setup = Setup {
            ad: &ad,
            size,
            mlp: &mlp,
            fitted: &fitted,
            grid: &grid,
            steps: args.steps,
            segment: args.segment,
        };
        for (name, case) in cases {
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
            .step_flops(&mlp, case.path, case.top_k);
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
            print_row(&row, peer.as_ref());
        }
    }
    println!(
        "matmul: GFLOP/s of a [4096,{w}] x [{w},{w}] product loop on the same device",
        w = size.width
    );
    let grid = object_grid();
    let clipped = grid.clip(&rays(size.rays, 1));
    println!(
        "grid: a ball in a {r}^3 grid ({:.1} % of cells occupied); {} of {} rays rendered, \
         sampled over {:.0} % of their length on average (rays/s counts every ray drawn)",
        100.0 * grid.occupied_fraction(),
        clipped.kept.len(),
        size.rays,
        100.0 * clipped.span_fraction_sum / size.rays as f64,
        r = grid.resolution()
    );
    println!(
        "infer rays/s: the trained model rendering {} fresh rays in chunks of 4096 without \
         autodiff (same feature path, the grid where the case has one), each ray ending once \
         its transmittance is below 1e-4 (checked every 8 samples); x train: over the training \
         rays/s of the same row; all-sample: the same render evaluating every sample; \
         samples %: the share of the samples evaluated with termination. The field's density \
         was fitted to the ball ({} Adam steps) before the timed steps, so rays end on it",
        4 * size.rays,
        args.fit_steps
    );
    if peer.is_some() {
        println!(
            "jax: the plain per-sample step in JAX (scripts/peer_step_jax.py, one jit of \
             forward, grad and Adam), its peak MB the whole Python process's"
        );
    }
    Ok(())
}
