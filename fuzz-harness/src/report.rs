//! The table of a fuzzing pass: on the terminal and as CSV.

use std::fmt::Write as _;

use crate::supervisor::TargetRun;

/// Executions per second of a run.
fn rate(run: &TargetRun) -> f64 {
    run.execs as f64 / run.seconds.max(1e-9)
}

/// The table: target, seeds, executions, exec/s, defects (signatures and
/// failing executions), then one line per defect.
pub fn table(runs: &[TargetRun]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<22} {:>6} {:>12} {:>10} {:>8} {:>9}",
        "target", "seeds", "executions", "exec/s", "defects", "failures"
    );
    for r in runs {
        let failures: u64 = r.defects.values().map(|d| d.count).sum();
        let _ = writeln!(
            out,
            "{:<22} {:>6} {:>12} {:>10.0} {:>8} {:>9}{}",
            r.name,
            r.seeds,
            r.execs,
            rate(r),
            r.defects.len(),
            failures,
            r.stopped
                .as_ref()
                .map_or(String::new(), |s| format!("  ({s})"))
        );
    }
    for r in runs {
        for (sig, d) in &r.defects {
            let _ = writeln!(
                out,
                "defect {}: {sig} x{} (first at execution {}: {})",
                r.name, d.count, d.first_index, d.detail
            );
            for p in &d.saved {
                let _ = writeln!(out, "    input saved to {}", p.display());
            }
        }
    }
    out
}

/// The table as CSV (`target,seeds,executions,seconds,exec_per_s,defects,failures`).
pub fn csv(runs: &[TargetRun]) -> String {
    let mut out = String::from("target,seeds,executions,seconds,exec_per_s,defects,failures\n");
    for r in runs {
        let failures: u64 = r.defects.values().map(|d| d.count).sum();
        let _ = writeln!(
            out,
            "{},{},{},{:.1},{:.0},{},{}",
            r.name,
            r.seeds,
            r.execs,
            r.seconds,
            rate(r),
            r.defects.len(),
            failures
        );
    }
    out
}
