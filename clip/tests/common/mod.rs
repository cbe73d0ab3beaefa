//! Helpers shared by the parity tests: the CPU backends, reading reference
//! JSON, comparing outputs, and the Python that regenerates references.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::Path;
use std::process::Command;

use burn::tensor::Device;
use serde_json::Value;

/// The CPU backends every parity check runs on.
pub fn devices() -> Vec<(&'static str, Device)> {
    #[allow(deprecated)] // ndarray is the reference backend
    let ndarray = Device::ndarray();
    vec![("flex", Device::flex()), ("ndarray", ndarray)]
}

/// A JSON file, or a panic naming it.
pub fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A JSON array of numbers as `f32`.
pub fn floats(v: &Value) -> Vec<f32> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number") as f32)
        .collect()
}

/// The largest absolute difference (infinite where `a` is not finite).
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "lengths");
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            if x.is_finite() {
                (x - y).abs()
            } else {
                f32::INFINITY
            }
        })
        .fold(0.0, f32::max)
}

/// The Python the tests run: `$OPENNERF_PYTHON` (e.g. a virtual
/// environment's), else `python3`.
pub fn python() -> String {
    std::env::var("OPENNERF_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// Fails (with how to install them) unless `python()` can import `modules`.
pub fn require_python(modules: &str, install: &str) {
    let ok = Command::new(python())
        .args(["-c", &format!("import {modules}")])
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "{} cannot import {modules}: {install} (or set OPENNERF_PYTHON)",
        python()
    );
}
