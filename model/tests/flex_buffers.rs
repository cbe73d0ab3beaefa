//! New flex tensors (`FlexTensor::empty`: zeros; `FlexTensor::from_writer`:
//! every matrix product's output, written by gemm into a buffer that is not
//! zeroed first) come from the workspace's patched burn-flex
//! (`vendor/burn-flex/VENDORED.md`), which allocates their buffers as
//! elements of their dtype. These tests pin what that path must keep: the
//! values, the buffers readable as their element type, products equal to a
//! float64 reference on every path gemm takes (matrix-vector, dot product,
//! the small-output kernel, blocked and threaded products, 2-D and batched,
//! strided operands, an empty inner dimension) right after buffers full of
//! NaN were freed, and the patch in use at all.

use burn::tensor::{DType, Device, Tensor, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

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
    let want = reference(&a, &b, 1, m, k, n);
    // Twice: the second product's buffer may reuse the first's memory.
    for _ in 0..2 {
        let c = ta.clone().matmul(tb.clone()).into_data();
        let c = c.as_slice::<f32>().unwrap();
        for i in 0..m {
            for j in 0..n {
                let (got, want) = (c[i * n + j] as f64, want[i * n + j]);
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

fn random(rng: &mut ChaCha8Rng, n: usize) -> Vec<f32> {
    (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect()
}

/// Allocates and frees buffers of NaN of about `elements` numbers, so that
/// the allocator's next buffers of such sizes are likely to hold NaN.
fn dirty_the_allocator(elements: usize) {
    let device = Device::flex();
    for size in [elements / 4, elements, elements * 2] {
        let nan = Tensor::<1>::from_data(
            TensorData::new(vec![f32::NAN; size.max(1)], [size.max(1)]),
            &device,
        );
        drop(nan.clone().add_scalar(1.0));
    }
}

/// `a` (`[b, m, k]`) times `c` (`[b, k, n]`) in float64.
fn reference(a: &[f32], c: &[f32], b: usize, m: usize, k: usize, n: usize) -> Vec<f64> {
    let mut out = vec![0.0f64; b * m * n];
    for bi in 0..b {
        for i in 0..m {
            for j in 0..n {
                out[(bi * m + i) * n + j] = (0..k)
                    .map(|l| a[(bi * m + i) * k + l] as f64 * c[(bi * k + l) * n + j] as f64)
                    .sum();
            }
        }
    }
    out
}

fn assert_close(got: &[f32], want: &[f64], k: usize, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    let tolerance = 1e-5 * (k.max(1) as f64).sqrt() * 4.0;
    for (i, (&g, &w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g as f64 - w).abs() <= tolerance,
            "{what}: element {i} is {g}, float64 gives {w}"
        );
    }
}

/// Shapes that reach each of gemm's paths: n = 1 and m = 1 (matrix-vector),
/// m = n = 1 (a dot product), outputs of at most 16 x 16 (the horizontal
/// kernel), the field's layers (tens of thousands of rows, 3 to 64
/// columns), and one large enough to be threaded.
const SHAPES: [(usize, usize, usize); 10] = [
    (1, 1, 1),
    (1, 37, 1),
    (5, 33, 1),
    (1, 33, 7),
    (9, 13, 11),
    (16, 64, 16),
    (12_288, 32, 64),
    (12_288, 64, 3),
    (300, 257, 129),
    (400, 300, 500),
];

#[test]
fn two_dimensional_products_match_float64_in_recycled_buffers() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let device = Device::flex();
    for (m, k, n) in SHAPES {
        let a = random(&mut rng, m * k);
        let c = random(&mut rng, k * n);
        let want = reference(&a, &c, 1, m, k, n);
        dirty_the_allocator(m * n);
        let lhs = Tensor::<2>::from_data(TensorData::new(a.clone(), [m, k]), &device);
        let rhs = Tensor::<2>::from_data(TensorData::new(c.clone(), [k, n]), &device);
        let got = lhs.matmul(rhs).into_data();
        assert_close(
            got.as_slice::<f32>().unwrap(),
            &want,
            k,
            &format!("[{m}, {k}] x [{k}, {n}]"),
        );

        // The same product from transposed storage (strided operands, as
        // the backward pass multiplies).
        dirty_the_allocator(m * n);
        let lhs_t = Tensor::<2>::from_data(TensorData::new(transpose(&a, m, k), [k, m]), &device);
        let rhs_t = Tensor::<2>::from_data(TensorData::new(transpose(&c, k, n), [n, k]), &device);
        let got = lhs_t.transpose().matmul(rhs_t.transpose()).into_data();
        assert_close(
            got.as_slice::<f32>().unwrap(),
            &want,
            k,
            &format!("strided [{m}, {k}] x [{k}, {n}]"),
        );
    }
}

#[test]
fn batched_products_match_float64_in_recycled_buffers() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let device = Device::flex();
    // Batches one by one (one with an empty inner dimension), in parallel
    // over the batch, and of large matrices each threaded inside.
    for (b, m, k, n) in [
        (3, 5, 7, 2),
        (2, 3, 0, 4),
        (64, 48, 40, 24),
        (2, 300, 257, 129),
        (5, 1, 9, 1),
    ] {
        let a = random(&mut rng, b * m * k);
        let c = random(&mut rng, b * k * n);
        let want = reference(&a, &c, b, m, k, n);
        dirty_the_allocator(b * m * n);
        let lhs = Tensor::<3>::from_data(TensorData::new(a, [b, m, k]), &device);
        let rhs = Tensor::<3>::from_data(TensorData::new(c, [b, k, n]), &device);
        let got = lhs.matmul(rhs).into_data();
        assert_close(
            got.as_slice::<f32>().unwrap(),
            &want,
            k,
            &format!("[{b}, {m}, {k}] x [{b}, {k}, {n}]"),
        );
    }
}

#[test]
fn an_empty_inner_dimension_gives_zeros() {
    let device = Device::flex();
    dirty_the_allocator(12);
    let lhs = Tensor::<2>::from_data(TensorData::new(Vec::<f32>::new(), [3, 0]), &device);
    let rhs = Tensor::<2>::from_data(TensorData::new(Vec::<f32>::new(), [0, 4]), &device);
    let got = lhs.matmul(rhs).into_data();
    assert_eq!(got.as_slice::<f32>().unwrap(), &[0.0f32; 12]);
}

fn transpose(values: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    (0..cols)
        .flat_map(|j| (0..rows).map(move |i| values[i * cols + j]))
        .collect()
}
