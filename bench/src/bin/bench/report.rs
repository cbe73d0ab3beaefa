//! The benchmark's table: header, rows and the notes under it.

use crate::Size;
use crate::cases::{Inference, object_grid, rays};
use crate::peer;

/// One row of the table.
pub struct Row {
    pub backend: String,
    pub path: String,
    pub secs: f64,
    pub rays: usize,
    pub flops: f64,
    pub matmul: f64,
    pub peak_mb: f64,
    /// Inference (none for the peer).
    pub infer: Option<Inference>,
}

/// The CPU as `/proc/cpuinfo` names it, with its family and model numbers
/// and vector extensions (a VM's model name alone may say only "AMD
/// EPYC"); else the architecture.
pub fn cpu_model() -> String {
    let Ok(text) = std::fs::read_to_string("/proc/cpuinfo") else {
        return std::env::consts::ARCH.to_string();
    };
    let field = |key: &str| {
        text.lines()
            .find(|l| l.split(':').next().is_some_and(|k| k.trim() == key))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
    };
    let Some(name) = field("model name") else {
        return std::env::consts::ARCH.to_string();
    };
    let flags = field("flags").unwrap_or_default();
    let has = |f: &str| flags.split_whitespace().any(|x| x == f);
    let vector = match (has("avx512f"), has("avx2")) {
        (true, _) => "AVX-512",
        (false, true) => "AVX2, no AVX-512",
        _ => "no AVX2",
    };
    match (field("cpu family"), field("model")) {
        (Some(family), Some(model)) => format!("{name} (family {family}, model {model}; {vector})"),
        _ => format!("{name} ({vector})"),
    }
}

/// Prints the machine, then the header (and the ratio's convention when
/// there is a peer).
pub fn print_header(peer: Option<&peer::Peer>) {
    println!(
        "cpu: {} ({} threads available)",
        cpu_model(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    if let Some(p) = peer {
        println!(
            "vs JAX: this row's step time / the JAX step time (jax {}, {} threads): \
             1.49x = takes 1.49 times as long as JAX, below 1 = faster",
            p.version, p.threads
        );
    }
    print!(
        "{:<8} {:<28} {:>9} {:>10} {:>9} {:>10} {:>10} {:>9} {:>7}",
        "backend",
        "feature path",
        "step s",
        "rays/s",
        "GFLOP",
        "GFLOP/s",
        "matmul",
        "of matmul",
        "peak MB"
    );
    print!(
        " {:>12} {:>8} {:>10} {:>9}",
        "infer rays/s", "x train", "all-sample", "samples %"
    );
    println!("{}", if peer.is_some() { "   vs JAX" } else { "" });
}

/// Prints `row`, with its step time over the peer's when there is one.
pub fn print_row(row: &Row, peer: Option<&peer::Peer>) {
    print!(
        "{:<8} {:<28} {:>9.3} {:>10.0} {:>9.1} {:>10.1} {:>10.1} {:>8.0}% {:>7.0}",
        row.backend,
        row.path,
        row.secs,
        row.rays as f64 / row.secs,
        row.flops / 1e9,
        row.flops / row.secs / 1e9,
        row.matmul,
        100.0 * row.flops / row.secs / 1e9 / row.matmul,
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

/// The notes under the table: what the columns and the grid case are.
pub fn print_notes(size: Size, fit_steps: usize, with_peer: bool) {
    println!(
        "matmul: GFLOP/s of a [4096,{w}] x [{w},{w}] product loop on the same device; \
         of matmul: the step's GFLOP/s as a share of it (100% = every FLOP at the product \
         loop's rate, nothing else costing time)",
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
        fit_steps
    );
    if with_peer {
        println!(
            "jax: the plain per-sample step in JAX (scripts/peer_step_jax.py, one jit of \
             forward, grad and Adam), its peak MB the whole Python process's"
        );
    }
}
