//! The multiresolution hash encoding's two forms side by side, in one
//! run: the corners computed on the points' device with tensor ops
//! (`HashGrid::forward_device`, no read-back) and the CPU backends'
//! one-pass encoding (`forward_fused`:
//! level by level, no corner array, its backward a scatter-add of the same
//! kind), each timed as one training step's work on the encoding (forward,
//! backward into the tables), on every backend asked for. The forms
//! alternate, step by step, so that a change in the machine's speed falls
//! on all alike. Last, Adam's update of the tables alone (every row):
//! Burn's Adam against the one-pass Adam the training uses.
//!
//! The points are drawn uniformly in the grid's cube, or, as a training
//! step orders them, ray by ray (`--layout rays`): consecutive points a
//! short step apart along a ray, so that at the coarse levels many of them
//! fall in one cell.
//!
//! `cargo run -p bench --release --bin hash_encoding -- [--points N] [--steps N] [--layout uniform|rays] [--backend flex,ndarray]`

use std::time::Instant;

use anyhow::Result;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Distribution, Tensor};
use clap::Parser;
use field_ops::backend::BackendListArgs;
use model::mip::points_along;
use model::{FusedAdamConfig, HashGrid, HashGridConfig};

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Options.
#[derive(Debug, Parser)]
#[command(
    name = "hash_encoding",
    about = "The hash encoding with its corners on the device against in one pass on the CPU"
)]
struct Args {
    /// Points encoded a step [default: 8192, 64 rays x 64 samples x 2
    /// levels, the COLMAP default's batch].
    #[arg(long, default_value_t = 8192)]
    points: usize,
    /// Timed steps of each form (after one untimed warm-up step each).
    #[arg(long, default_value_t = 20)]
    steps: usize,
    /// Grid levels.
    #[arg(long, default_value_t = 16)]
    levels: usize,
    /// Rows of each level's table, as a power of two.
    #[arg(long, default_value_t = 15)]
    log2_table: usize,
    /// Where the points lie: `uniform` in the grid's cube, or `rays`:
    /// `--samples` points a ray, ray after ray, evenly spaced along a
    /// random line through the cube (the order of a training step's
    /// samples).
    #[arg(long, value_enum, default_value_t = Layout::Uniform)]
    layout: Layout,
    /// Points a ray with `--layout rays` (the bench room's field samples
    /// 48 a ray).
    #[arg(long, default_value_t = 48)]
    samples: usize,
    /// Backends to measure and wgpu's adapter.
    #[command(flatten)]
    compute: BackendListArgs,
}

/// Where the points lie.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Layout {
    /// Uniformly in the grid's cube.
    Uniform,
    /// Ray by ray, a ray's points in order along it.
    Rays,
}

/// `n` points of `layout` (`samples` a ray for [`Layout::Rays`]) in the
/// cube of half side `half`.
///
/// # Shapes
/// - output: `[n, 3]`.
fn draw_points(layout: Layout, n: usize, samples: usize, half: f32, device: &Device) -> Tensor<2> {
    let uniform = Distribution::Uniform(-half as f64, half as f64);
    match layout {
        Layout::Uniform => Tensor::<2>::random([n, 3], uniform, device),
        Layout::Rays => {
            let s = samples.min(n);
            let rays = n.div_ceil(s);
            // From a point inside the cube, along a random direction, one
            // side's length in even steps.
            let origins = Tensor::<2>::random([rays, 3], uniform, device);
            let dirs = Tensor::<2>::random([rays, 3], Distribution::Normal(0.0, 1.0), device);
            let dirs = dirs
                .clone()
                .div(dirs.square().sum_dim(1).sqrt().clamp_min(1e-6));
            let steps: Vec<f32> = (0..s).map(|i| 2.0 * half * i as f32 / s as f32).collect();
            let t = Tensor::<1>::from_floats(steps.as_slice(), device)
                .reshape([1, s])
                .expand([rays, s]);
            points_along(origins, dirs, t)
                .reshape([rays * s, 3])
                .narrow(0, 0, n)
        }
    }
}

/// A form of the encoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Form {
    Device,
    Fused,
}

/// One step of the encoding's work: the encoding of `points`, a weighted
/// sum as the loss, its gradient into the table (waited for).
fn step(grid: &HashGrid, points: &Tensor<2>, weights: &Tensor<2>, form: Form) {
    let enc = match form {
        Form::Device => grid.forward_device(points.clone()),
        Form::Fused => grid.forward_fused(points.clone()),
    };
    let grads = enc.mul(weights.clone()).sum().backward();
    let g = grid
        .table
        .val()
        .grad(&grads)
        .expect("the table gets a gradient");
    g.device().sync().expect("the device finishes its work");
}

/// Milliseconds of one Adam update of `grid`'s tables (the gradient of one
/// encoding step computed beforehand, outside the timing), over `steps`:
/// Burn's Adam (its tensor ops) and the one-pass Adam the training uses,
/// alternating step by step.
fn adam_ms(grid: HashGrid, points: &Tensor<2>, weights: &Tensor<2>, steps: usize) -> [f64; 2] {
    let mut optims: [ModuleOptimizer; 2] =
        [AdamConfig::new().init(), FusedAdamConfig::new().init()];
    let grads = |g: &HashGrid| {
        let enc = g.forward(points.clone());
        GradientsParams::from_grads(enc.mul(weights.clone()).sum().backward(), g)
    };
    // Each step takes its grid by value (no other copy sharing the tables'
    // memory, as in training), so the one-pass form updates it in place.
    let mut grids = [Some(grid.clone()), Some(grid)];
    let mut seconds = [0.0; 2];
    for step in 0..=steps {
        for ((slot, optim), seconds) in grids.iter_mut().zip(&mut optims).zip(&mut seconds) {
            let grid = slot.take().expect("each grid is put back after its step");
            let g = grads(&grid);
            let start = Instant::now();
            let grid = optim.step(1e-3, grid, g);
            grid.table
                .val()
                .device()
                .sync()
                .expect("the device finishes its work");
            // The first step, which creates the moments, is not timed.
            if step > 0 {
                *seconds += start.elapsed().as_secs_f64();
            }
            *slot = Some(grid);
        }
    }
    seconds.map(|s| 1e3 * s / steps.max(1) as f64)
}

fn main() -> Result<()> {
    let args = Args::parse();
    field_ops::subnormals::flush_to_zero();
    args.compute.check().map_err(anyhow::Error::msg)?;
    for (flag, value) in [
        ("--points", args.points),
        ("--steps", args.steps),
        ("--levels", args.levels),
        ("--samples", args.samples),
    ] {
        if value == 0 {
            anyhow::bail!("{flag} 0: at least 1");
        }
    }
    if !(4..=24).contains(&args.log2_table) {
        anyhow::bail!(
            "--log2-table {}: a table of 2^4 to 2^24 rows, as `train` takes",
            args.log2_table
        );
    }
    let layout = match args.layout {
        Layout::Uniform => "uniform in the cube".to_string(),
        Layout::Rays => format!("{} a ray, in order along it", args.samples),
    };
    println!(
        "{} points a step ({layout}), {} levels of 2^{} rows x 2 features, {} timed steps of each form",
        args.points, args.levels, args.log2_table, args.steps
    );
    println!("backend   device (ms/step)   fused (ms/step)   fused / device");
    for &kind in &args.compute.backend {
        let device: Device = args.compute.of(kind).device().autodiff();
        device.seed(1);
        let grid = HashGridConfig::new()
            .with_levels(args.levels)
            .with_log2_table(args.log2_table)
            .init(&device);
        let points = draw_points(args.layout, args.points, args.samples, 3.0, &device);
        let weights = Tensor::<2>::random(
            [args.points, grid.output_dim()],
            Distribution::Uniform(-1.0, 1.0),
            &device,
        );
        // The one-pass form runs on the CPU backends only.
        let cpu = model::host_work::is_cpu_backend(&device);
        let forms: &[Form] = if cpu {
            &[Form::Device, Form::Fused]
        } else {
            &[Form::Device]
        };
        for &form in forms {
            step(&grid, &points, &weights, form);
        }
        let mut seconds = [0.0f64; 2];
        for _ in 0..args.steps {
            for (i, &form) in forms.iter().enumerate() {
                let start = Instant::now();
                step(&grid, &points, &weights, form);
                seconds[i] += start.elapsed().as_secs_f64();
            }
        }
        let ms = seconds.map(|s| 1e3 * s / args.steps as f64);
        let fused = |v: f64| if cpu { format!("{v:.2}") } else { "-".into() };
        println!(
            "{:<9} {:>17.2}   {:>15}   {:>14}",
            kind.name(),
            ms[0],
            fused(ms[1]),
            fused(ms[1] / ms[0]),
        );
        let [burn, fused] = adam_ms(grid, &points, &weights, args.steps);
        println!(
            "{:<9} Adam's update of the tables ({} rows x 2), ms a step: Burn's {burn:.2}, one pass {fused:.2} ({:.2})",
            kind.name(),
            args.levels << args.log2_table,
            fused / burn
        );
    }
    Ok(())
}
