//! `fuzz-harness`: fuzzes the file parsers and prints a table.
//!
//! ```text
//! cargo run --release -p fuzz-harness -- --target all --seconds 3     # short pass
//! cargo run --release -p fuzz-harness -- --target all --execs 1000000 # long pass
//! cargo run --release -p fuzz-harness -- --list
//! ```

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Parser;
use fuzz_harness::guard::CountingAlloc;
use fuzz_harness::report;
use fuzz_harness::supervisor::{Budget, RunOptions, run_target};
use fuzz_harness::targets::{self, Seeds};
use fuzz_harness::worker::{self, WorkerArgs};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

/// Fuzzes the workspace's file parsers: no panic, no allocation beyond a
/// cap from the input's size, no hang.
#[derive(Debug, Parser)]
#[command(version)]
struct Cli {
    /// Targets to run: `all` or names separated by commas (see --list).
    #[arg(long, default_value = "all")]
    target: String,
    /// Seconds per target (default 3 when --execs is not given).
    #[arg(long)]
    seconds: Option<f64>,
    /// Executions per target.
    #[arg(long)]
    execs: Option<u64>,
    /// Time limit of one execution, milliseconds (longer is a hang).
    #[arg(long, default_value_t = 5000)]
    timeout_ms: u64,
    /// The shared data sets (default: ../shared/data beside the repository).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Where failing inputs are saved.
    #[arg(long)]
    defects: Option<PathBuf>,
    /// Also write the table as CSV to this file.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// List the targets and their entry points, and exit.
    #[arg(long)]
    list: bool,
    /// Internal: run as the worker of this target.
    #[arg(long, hide = true)]
    worker: Option<String>,
    /// Internal: first execution index of the worker.
    #[arg(long, hide = true, default_value_t = 0)]
    from: u64,
    /// Internal: announce every execution.
    #[arg(long, hide = true)]
    trace: bool,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let mut seeds = Seeds::default_paths();
    if let Some(d) = &cli.data {
        seeds.data = d.clone();
    }
    let timeout = Duration::from_millis(cli.timeout_ms.max(1));
    let (execs, seconds) = match (cli.execs, cli.seconds) {
        (None, None) => (u64::MAX, 3.0),
        (e, s) => (e.unwrap_or(u64::MAX), s.unwrap_or(f64::INFINITY)),
    };
    if let Some(target) = cli.worker {
        let args = WorkerArgs {
            target,
            from: cli.from,
            execs,
            seconds,
            timeout,
            trace: cli.trace,
            seeds,
        };
        return worker::run(&args);
    }
    let all = targets::all();
    if cli.list {
        for t in &all {
            println!("{:<22} {} ({})", t.name, t.about, t.file);
        }
        return Ok(());
    }
    let chosen: Vec<_> = if cli.target == "all" {
        all
    } else {
        let names = cli.target.split(',').map(str::trim);
        names
            .map(|n| {
                targets::by_name(n)
                    .with_context(|| format!("no fuzz target called {n:?} (see --list)"))
            })
            .collect::<Result<_>>()?
    };
    if !seeds.data.is_dir() {
        eprintln!(
            "note: {} is missing: the targets start from the fixtures and generated seeds only",
            seeds.data.display()
        );
    }
    let opts = RunOptions {
        exe: std::env::current_exe().context("locating this program")?,
        budget: Budget { execs, seconds },
        timeout,
        seeds,
        defects_dir: cli
            .defects
            .unwrap_or_else(|| std::env::temp_dir().join("opennerf-fuzz-defects")),
    };
    let mut runs = Vec::new();
    for t in &chosen {
        let run = run_target(t, &opts)?;
        eprintln!(
            "{:<22} {:>10} executions in {:>6.1} s, {} defects",
            run.name,
            run.execs,
            run.seconds,
            run.defects.len()
        );
        runs.push(run);
    }
    print!("{}", report::table(&runs));
    if let Some(path) = &cli.csv {
        std::fs::write(path, report::csv(&runs))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let defects: usize = runs.iter().map(|r| r.defects.len()).sum();
    if defects > 0 {
        bail!(
            "{defects} defects found (inputs saved under {})",
            opts.defects_dir.display()
        );
    }
    Ok(())
}
