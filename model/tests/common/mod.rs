//! Shared test helpers: the devices to run on and tensor readers.
#![allow(dead_code)]

use burn::tensor::{Device, Tensor};

/// Whether a Vulkan driver is installed (or wgpu tests are forced on).
pub fn wgpu_available() -> bool {
    if std::env::var("OPENNERF_TEST_WGPU").is_ok_and(|v| v == "1") {
        return true;
    }
    std::fs::read_dir("/usr/share/vulkan/icd.d")
        .map(|d| {
            d.filter_map(Result::ok)
                .any(|e| e.path().extension().is_some_and(|x| x == "json"))
        })
        .unwrap_or(false)
}

/// The CPU devices every test runs on, plus wgpu when a Vulkan driver exists.
/// `with_wgpu` lets heavy tests stay on the CPU backends.
pub fn devices(with_wgpu: bool) -> Vec<(&'static str, Device)> {
    #[allow(deprecated)]
    let mut v = vec![("flex", Device::flex()), ("ndarray", Device::ndarray())];
    if with_wgpu {
        if !cfg!(feature = "wgpu") {
            eprintln!("skipping wgpu: built without the wgpu feature");
        } else if wgpu_available() {
            // Run with CUBECL_AUTOTUNE_LEVEL=minimal: shader autotuning on a
            // CPU Vulkan driver otherwise takes minutes.
            push_wgpu(&mut v);
        } else {
            eprintln!("skipping wgpu: no Vulkan driver (set OPENNERF_TEST_WGPU=1 to force)");
        }
    }
    v
}

/// `n` deterministic values in `[lo, hi)` (xorshift from `seed`).
pub fn uniform(n: usize, seed: u64, lo: f64, hi: f64) -> Vec<f64> {
    let mut z = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..n)
        .map(|_| {
            z ^= z << 13;
            z ^= z >> 7;
            z ^= z << 17;
            lo + (hi - lo) * ((z >> 11) as f64 / (1u64 << 53) as f64)
        })
        .collect()
}

/// Reads a float tensor as `Vec<f32>`.
pub fn vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.try_into_vec_as::<f32>().expect("readable f32 tensor")
}

/// Builds a tensor from values.
pub fn tensor<const D: usize>(v: Vec<f32>, shape: [usize; D], device: &Device) -> Tensor<D> {
    Tensor::from_data(burn::tensor::TensorData::new(v, shape), device)
}

/// Asserts element-wise closeness with a mixed tolerance.
pub fn assert_close(a: &[f32], b: &[f32], atol: f32, rtol: f32, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: length");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        let tol = atol + rtol * y.abs();
        assert!(
            (x - y).abs() <= tol && x.is_finite(),
            "{what}[{i}]: {x} vs {y} (tol {tol})"
        );
    }
}

#[cfg(feature = "wgpu")]
fn push_wgpu(v: &mut Vec<(&'static str, Device)>) {
    v.push(("wgpu", Device::wgpu(burn::tensor::DeviceKind::Cpu)));
}

#[cfg(not(feature = "wgpu"))]
fn push_wgpu(_: &mut Vec<(&'static str, Device)>) {}

/// Rays from a camera looking at the origin of a box of half-size 1 m.
pub fn camera_rays(n: usize, seed: u64) -> Vec<model::geometry::NormalizedRay> {
    use model::geometry::{Camera, Intrinsics, SceneBox, look_at};
    use rand::{Rng, SeedableRng};
    let scene = SceneBox {
        min: [-1.0; 3],
        max: [1.0; 3],
    };
    let cam = Camera {
        intrinsics: Intrinsics::from_fov_x(32, 32, 0.8),
        pose: look_at([0.3, -0.4, -2.5], [0.0; 3], [0.0, -1.0, 0.0]).expect("valid look-at"),
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let ray = cam.ray(rng.random_range(0.0..31.0), rng.random_range(0.0..31.0));
            scene.normalize_ray(&ray, 0.05)
        })
        .collect()
}

/// The tests' tiny field: a 4-channel head of width 8 on a 2 x 16 trunk
/// with its skip after the first layer (samples per level and top-k left
/// at their defaults for the caller to set).
#[allow(dead_code)]
pub fn tiny_config() -> model::OpenNerfConfig {
    model::OpenNerfConfig::new(model::FeatureHeadConfig::new(4).with_width(8)).with_mlp(
        model::MipMlpConfig::new()
            .with_width(16)
            .with_depth(2)
            .with_skip_layer(1),
    )
}
