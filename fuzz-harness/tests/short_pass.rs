//! The short fuzzing pass CI runs (every target for a moment), and the
//! harness's own checks: each kind of defect is caught.

use std::process::{Command, Output};

fn harness(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fuzz-harness"))
        .args(args)
        .output()
        .expect("the fuzz-harness binary runs")
}

fn text(out: &Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

#[test]
fn short_pass_over_every_target_finds_no_defect() {
    // 1.5 s a target keeps the pass under a minute on two cores;
    // FUZZ_SECONDS runs it longer.
    let seconds = std::env::var("FUZZ_SECONDS").unwrap_or_else(|_| "1.5".into());
    let dir = tempfile::tempdir().expect("temp dir");
    let defects = dir.path().to_string_lossy().into_owned();
    let out = harness(&[
        "--target",
        "all",
        "--seconds",
        &seconds,
        "--defects",
        &defects,
    ]);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    for t in fuzz_harness::targets::all() {
        let row = all
            .lines()
            .find(|l| l.split_whitespace().next() == Some(t.name))
            .unwrap_or_else(|| panic!("no row for {}: {all}", t.name));
        let execs: u64 = row
            .split_whitespace()
            .nth(2)
            .and_then(|n| n.parse().ok())
            .unwrap_or(0);
        assert!(execs > 10, "{row}");
    }
}

#[test]
fn panics_allocations_over_the_cap_and_hangs_are_defects() {
    let dir = tempfile::tempdir().expect("temp dir");
    let defects = dir.path().to_string_lossy().into_owned();
    let args = [
        "--target",
        "selftest-panic,selftest-alloc,selftest-hang",
        "--execs",
        "3",
        "--timeout-ms",
        "300",
        "--defects",
        &defects,
    ];
    let out = harness(&args);
    let all = text(&out);
    assert!(!out.status.success(), "{all}");
    assert!(
        all.contains("defect selftest-panic: panic fuzz-harness/src/targets/selftest.rs"),
        "{all}"
    );
    assert!(all.contains("defect selftest-alloc: alloc x3"), "{all}");
    assert!(all.contains("1099511627776 single"), "{all}");
    assert!(all.contains("defect selftest-hang: hang x3"), "{all}");
    assert!(
        dir.path().join("selftest-alloc/alloc-0.bin").is_file(),
        "{all}"
    );
}
