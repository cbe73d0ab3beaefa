//! The machine the timings run on (its CPU's name, its logical cores) and
//! the clock they are taken with: wall seconds and the cores a closure kept
//! busy.

use std::time::Instant;

/// The CPU's model name from `/proc/cpuinfo`, with its family and model
/// numbers where the name alone is vague ("unknown" elsewhere).
pub(crate) fn cpu_model() -> String {
    let Ok(info) = std::fs::read_to_string("/proc/cpuinfo") else {
        return "unknown".into();
    };
    let field = |key: &str| {
        info.lines()
            .filter_map(|l| l.split_once(':'))
            .find(|(k, _)| k.trim() == key)
            .map(|(_, v)| v.trim().to_string())
    };
    let name = field("model name").unwrap_or_else(|| "unknown".into());
    match (field("cpu family"), field("model")) {
        (Some(f), Some(m)) => format!("{name} (family {f}, model {m})"),
        _ => name,
    }
}

/// Logical CPUs this process may run on.
pub(crate) fn logical_cpus() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// CPU seconds this process has used, user and system, all threads
/// (`/proc/self/stat`, 100 ticks a second); `None` where it cannot be read.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start at the state.
    let rest = stat.get(stat.rfind(')')? + 1..)?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i)?.parse::<f64>().ok();
    Some((ticks(11)? + ticks(12)?) / 100.0)
}

/// `f`'s result, wall seconds and cores kept busy (CPU seconds / wall
/// seconds; `None` without `/proc`).
pub(crate) fn timed<T>(f: impl FnOnce() -> T) -> (T, f64, Option<f64>) {
    let cpu0 = cpu_seconds();
    let start = Instant::now();
    let out = f();
    let wall = start.elapsed().as_secs_f64();
    let busy = cpu0
        .zip(cpu_seconds())
        .map(|(a, b)| (b - a) / wall.max(1e-9));
    (out, wall, busy)
}
