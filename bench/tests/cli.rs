//! The measurement programs on bad options: `--backend` and `--device` are
//! the flags of `train` and `eval` (the timing programs take a list of
//! backends), refused at a bad value before anything is measured or
//! written, and the other fixed-set flags list their values.

use std::process::{Command, Output};

fn run(program: &str, args: &[&str]) -> Output {
    Command::new(program)
        .args(args)
        .output()
        .expect("the program runs")
}

/// Asserts a clean refusal (non-zero exit, no panic) mentioning every `words`.
fn assert_refused(program: &str, args: &[&str], words: &[&str]) {
    let out = run(program, args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{program} {args:?} succeeded: {err}");
    assert!(
        !err.contains("panicked"),
        "{program} {args:?} panicked: {err}"
    );
    for w in words {
        assert!(err.contains(w), "{program} {args:?}: {w:?} not in {err:?}");
    }
    eprintln!("refused {args:?}:\n{}", err.trim_end());
}

const BENCH: &str = env!("CARGO_BIN_EXE_bench");
const BENCH_VLM: &str = env!("CARGO_BIN_EXE_bench-vlm");
const SWEEP: &str = env!("CARGO_BIN_EXE_sweep");
const TIME_TO_ACCURACY: &str = env!("CARGO_BIN_EXE_time_to_accuracy");
const HASH_ENCODING: &str = env!("CARGO_BIN_EXE_hash_encoding");

#[test]
fn every_program_refuses_a_bad_backend_or_device() {
    for program in [BENCH, BENCH_VLM, SWEEP, TIME_TO_ACCURACY, HASH_ENCODING] {
        assert_refused(
            program,
            &["--backend", "cuda"],
            &["'cuda'", "--backend", "flex", "ndarray", "wgpu"],
        );
        assert_refused(
            program,
            &["--device", "gpu0"],
            &["--device", "adapter index"],
        );
        assert_refused(
            program,
            &["--backend", "ndarray", "--device", "0"],
            &["--device", "wgpu"],
        );
    }
}

/// The timing programs measure several backends in one run: `--backend`
/// takes a list (`--backends` is the same flag), and `--device` needs wgpu
/// in it.
#[test]
fn the_timing_programs_take_a_list_of_backends() {
    for program in [BENCH, BENCH_VLM, HASH_ENCODING] {
        assert_refused(
            program,
            &["--backends", "flex,cuda"],
            &["'cuda'", "flex", "ndarray", "wgpu"],
        );
        assert_refused(
            program,
            &["--backend", "flex,ndarray", "--device", "1"],
            &["--device", "no wgpu"],
        );
        let help = String::from_utf8_lossy(&run(program, &["--help"]).stdout).into_owned();
        assert!(help.contains("--backend <BACKEND>"), "{help}");
        assert!(help.contains("--device <INDEX>"), "{help}");
    }
}

/// The hash-encoding timing refuses sizes it cannot measure, naming the
/// flag, before it measures anything.
#[test]
fn the_hash_encoding_timing_refuses_empty_and_unbounded_sizes() {
    for flag in ["--points", "--steps", "--levels"] {
        assert_refused(HASH_ENCODING, &[flag, "0"], &[flag, "at least 1"]);
    }
    for rows in ["3", "25"] {
        assert_refused(
            HASH_ENCODING,
            &["--log2-table", rows],
            &["--log2-table", rows, "2^4 to 2^24"],
        );
    }
    assert_refused(HASH_ENCODING, &["--points", "many"], &["--points", "many"]);
}

/// The training-step timing refuses empty sizes, naming the flag.
#[test]
fn the_step_timing_refuses_empty_sizes() {
    for flag in ["--rays", "--samples", "--steps"] {
        assert_refused(BENCH, &[flag, "0"], &[flag, "at least 1"]);
    }
}

#[test]
fn a_dense_variant_outside_the_set_is_listed_against_it() {
    assert_refused(
        BENCH_VLM,
        &["--dense", "clip"],
        &["'clip'", "--dense", "naclip", "clearclip", "maskclip"],
    );
}

#[test]
fn the_scale_report_names_a_missing_directory() {
    assert_refused(
        env!("CARGO_BIN_EXE_scale_report"),
        &["--dir", "/nonexistent/scale", "--sizes", "ci"],
        &["/nonexistent/scale"],
    );
}
