//! Every workspace crate linked into this test was compiled from this
//! checkout. A target directory shared between checkouts (a working tree and
//! a clone of it, as CI's is) can otherwise hand out a crate compiled from
//! the other one: cargo judges freshness by file times, not by content.
//! `.ci/run` removes the workspace crates' artifacts before it builds; this
//! test fails if one slipped through.

use std::path::{Path, PathBuf};

/// The checkout's root as the test runs (cargo runs a test in its package's
/// directory, `tests/`), whatever this binary was compiled from.
fn checkout_root() -> PathBuf {
    let here = std::env::current_dir().expect("the test's working directory");
    let here = here.canonicalize().expect("an existing directory");
    here.parent()
        .expect("tests/ lies in the checkout")
        .to_path_buf()
}

#[test]
fn every_crate_was_compiled_from_this_checkout() {
    let root = checkout_root();
    let crates = [
        ("model", model::BUILT_FROM),
        ("datasets", datasets::BUILT_FROM),
        ("clip", clip::BUILT_FROM),
        ("field-ops", field_ops::BUILT_FROM),
        ("viewer", viewer::BUILT_FROM),
        ("train", train::BUILT_FROM),
        ("eval", eval::BUILT_FROM),
        ("tests", env!("CARGO_MANIFEST_DIR")),
    ];
    let mut foreign = Vec::new();
    for (name, dir) in crates {
        let dir = Path::new(dir);
        let dir = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
        if dir != root.join(name) {
            foreign.push(format!("{name} from {}", dir.display()));
        }
    }
    assert!(
        foreign.is_empty(),
        "crates compiled from another checkout than {}: {}; remove their artifacts \
         (`cargo clean --release -p NAME`) and build again",
        root.display(),
        foreign.join(", ")
    );
}
