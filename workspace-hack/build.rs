// A build script, so that cargo-hakari's `[build-dependencies]` section
// takes part in feature resolution.
fn main() {}
