//! Targets that fail on purpose, one per check, so that a test can show
//! that each defect is caught (they are not part of `all`).

use std::path::Path;

use super::{Target, no_setup};

fn panics(_: &Path) {
    let v: Vec<u8> = Vec::new();
    // An index past the end, as a parser's unchecked offset would do.
    let i = std::hint::black_box(3);
    let _ = v[i];
}

fn allocates(_: &Path) {
    // What a header announcing a terabyte asks for.
    let v: Vec<u8> = Vec::with_capacity(std::hint::black_box(1usize << 40));
    std::hint::black_box(v);
}

fn hangs(_: &Path) {
    loop {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

macro_rules! selftest {
    ($name:literal, $run:expr) => {
        Target {
            name: $name,
            about: "fails on purpose (checks the harness)",
            file: "input.bin",
            tokens: &[],
            seeds: |_| vec![b"seed".to_vec()],
            setup: no_setup,
            run: $run,
        }
    };
}

/// The failing targets.
pub(super) fn targets() -> Vec<Target> {
    vec![
        selftest!("selftest-panic", panics),
        selftest!("selftest-alloc", allocates),
        selftest!("selftest-hang", hangs),
    ]
}
