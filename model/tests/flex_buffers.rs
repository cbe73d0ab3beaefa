//! New flex tensors (`FlexTensor::empty`: zeros, every matrix product's
//! output) come from the workspace's patched burn-flex
//! (`vendor/burn-flex/VENDORED.md`), which allocates their buffers as
//! elements of their dtype. These tests pin what that path must keep: the
//! values, the buffers readable as their element type, products equal to a
//! float64 reference, and the patch in use at all.

use burn::tensor::{DType, Device, Tensor, TensorData};

#[test]
fn zeros_of_every_float_dtype_are_zero_and_read_back_as_their_type() {
    let device = Device::flex();
    for n in [0usize, 1, 3, 17, 4096 + 5] {
        let t = Tensor::<1>::zeros([n], (&device, DType::F32)).into_data();
        assert_eq!(t.as_slice::<f32>().unwrap(), vec![0.0f32; n].as_slice());
        let t = Tensor::<1>::zeros([n], (&device, DType::F64)).into_data();
        assert_eq!(t.as_slice::<f64>().unwrap(), vec![0.0f64; n].as_slice());
        let t = Tensor::<1>::zeros([n], (&device, DType::F16)).into_data();
        assert!(
            t.as_slice::<burn::tensor::f16>()
                .unwrap()
                .iter()
                .all(|v| v.to_f32() == 0.0)
        );
    }
}

#[test]
fn products_match_a_float64_reference() {
    let device = Device::flex();
    let (m, k, n) = (67, 129, 35);
    let a: Vec<f32> = (0..m * k)
        .map(|i| ((i * 37 % 101) as f32 - 50.0) / 25.0)
        .collect();
    let b: Vec<f32> = (0..k * n)
        .map(|i| ((i * 53 % 97) as f32 - 48.0) / 24.0)
        .collect();
    let ta = Tensor::<2>::from_data(TensorData::new(a.clone(), [m, k]), &device);
    let tb = Tensor::<2>::from_data(TensorData::new(b.clone(), [k, n]), &device);
    // Twice: the second product's buffer may reuse the first's memory.
    for _ in 0..2 {
        let c = ta.clone().matmul(tb.clone()).into_data();
        let c = c.as_slice::<f32>().unwrap();
        for i in 0..m {
            for j in 0..n {
                let want: f64 = (0..k)
                    .map(|l| a[i * k + l] as f64 * b[l * n + j] as f64)
                    .sum();
                let got = c[i * n + j] as f64;
                assert!(
                    (got - want).abs() <= 1e-4 * want.abs().max(1.0),
                    "[{i},{j}] {got} vs {want}"
                );
            }
        }
    }
}

#[test]
fn the_workspace_builds_the_patched_burn_flex() {
    // A registry package has a `source` line in Cargo.lock; the patched
    // path dependency has none. A Burn upgrade that leaves the patch
    // unused (cargo only warns) fails here.
    let lock =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.lock")).unwrap();
    let entry = lock
        .split("[[package]]")
        .find(|p| p.contains("name = \"burn-flex\""))
        .expect("burn-flex in Cargo.lock");
    assert!(
        !entry.contains("source ="),
        "burn-flex comes from the registry:\n{entry}"
    );
    assert!(entry.contains("version = \"0.22.1\""), "{entry}");
}

#[test]
fn the_workspace_builds_gemms_avx512_kernels() {
    // gemm picks its AVX-512 kernels at run time only if they were compiled
    // (its `x86-v4` feature). workspace-hack lists the features every
    // member builds a dependency with (CI checks it is current), so a
    // member that stops asking for the feature fails here, not silently
    // in the step time on AVX-512 CPUs.
    let hack = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../workspace-hack/Cargo.toml"
    ))
    .unwrap();
    for package in ["gemm", "gemm-common", "gemm-f32"] {
        let line = hack
            .lines()
            .find(|l| l.starts_with(&format!("{package} = ")))
            .unwrap_or_else(|| panic!("{package} is not in workspace-hack/Cargo.toml"));
        assert!(line.contains("\"x86-v4\""), "{line}");
    }
}
