//! The sine and the exponential of the workspace's patched burn-flex
//! (`vendor/burn-flex`, `VENDORED.md`): vectorised polynomials after
//! reduction by multiples of pi (arguments up to 2^17 in magnitude) and of
//! ln 2 (arguments in [-87, 88], and 0 below -104), libm elsewhere. Checked
//! against float64 over the encoding's whole range and at the edges of the
//! fast paths, on tensors small and large enough to be split over threads.

use burn::tensor::{Device, Tensor, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The largest argument of the vectorised path (`FAST_LIMIT` there).
const FAST_LIMIT: f32 = 131_072.0;

fn flex_tensor(values: &[f32]) -> Tensor<1> {
    Tensor::from_data(
        TensorData::new(values.to_vec(), [values.len()]),
        &Device::flex(),
    )
}

fn flex_sin(values: &[f32]) -> Vec<f32> {
    let out = flex_tensor(values).sin().into_data();
    out.as_slice::<f32>().unwrap().to_vec()
}

fn flex_exp(values: &[f32]) -> Vec<f32> {
    let out = flex_tensor(values).exp().into_data();
    out.as_slice::<f32>().unwrap().to_vec()
}

/// Largest `|sin(x) - reference|` over `xs`, the reference in float64.
fn max_error(xs: &[f32], got: &[f32]) -> (f64, f32) {
    xs.iter()
        .zip(got)
        .map(|(&x, &y)| ((y as f64 - (x as f64).sin()).abs(), x))
        .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
}

#[test]
fn matches_the_float64_sine_over_the_encodings_range() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    // The encoding's arguments: coordinates in [-pi, pi] (a few times that
    // for samples outside a scene box) scaled by 2^l.
    for scale in [
        1.0f32,
        0.01,
        16.0,
        2048.0,
        8192.0,
        FAST_LIMIT / std::f32::consts::PI,
    ] {
        // Sizes below and above the threaded path, and not a multiple of
        // any vector width or block.
        for n in [1usize, 7, 63, 65, 1000, 300_001] {
            let xs: Vec<f32> = (0..n)
                .map(|_| rng.random_range(-std::f32::consts::PI..std::f32::consts::PI) * scale)
                .map(|x| x.clamp(-FAST_LIMIT, FAST_LIMIT))
                .collect();
            let (err, at) = max_error(&xs, &flex_sin(&xs));
            println!(
                "sin, |x| <= {:.2}, n {n}: largest error {err:.2e}",
                scale * std::f32::consts::PI
            );
            assert!(
                err <= 2.5e-7,
                "scale {scale}, n {n}: error {err:e} at x = {at}"
            );
        }
    }
}

#[test]
fn multiples_of_half_pi_and_the_edges_of_the_fast_path() {
    let mut xs = Vec::new();
    for k in -83_443i32..=83_443 {
        let x = k as f32 * std::f32::consts::FRAC_PI_2;
        xs.extend([
            x,
            f32::from_bits(x.to_bits() + 1),
            f32::from_bits(x.to_bits().max(1) - 1),
        ]);
    }
    xs.extend([
        FAST_LIMIT,
        -FAST_LIMIT,
        f32::from_bits(FAST_LIMIT.to_bits() - 1),
    ]);
    xs.retain(|x| x.abs() <= FAST_LIMIT);
    let (err, at) = max_error(&xs, &flex_sin(&xs));
    assert!(err <= 2.5e-7, "error {err:e} at x = {at}");
}

#[test]
fn zeros_tiny_values_and_signs_are_exact() {
    let xs = [
        0.0f32,
        -0.0,
        1e-30,
        -1e-30,
        f32::MIN_POSITIVE,
        1e-45,
        1e-4,
        -1e-4,
    ];
    let got = flex_sin(&xs);
    for (x, y) in xs.iter().zip(&got) {
        // sin(x) = x to within float32 rounding for |x| < 2^-12.
        assert_eq!(y.to_bits(), x.to_bits(), "sin({x:e}) = {y:e}");
    }
}

#[test]
fn arguments_beyond_the_fast_path_infinities_and_nan_take_libm() {
    // Mixed into blocks of fast arguments: only their block falls back.
    let mut xs: Vec<f32> = (0..200).map(|i| i as f32 * 0.37 - 30.0).collect();
    let odd = [
        131_073.0f32,
        -1e6,
        1e30,
        f32::MAX,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
    ];
    for (i, &x) in odd.iter().enumerate() {
        xs[i * 23 + 5] = x;
    }
    let got = flex_sin(&xs);
    for (x, y) in xs.iter().zip(&got) {
        if x.is_finite() {
            let err = (*y as f64 - (*x as f64).sin()).abs();
            assert!(err <= 2.5e-7, "sin({x:e}) = {y:e}, error {err:e}");
        } else {
            assert!(y.is_nan(), "sin({x}) = {y}, expected NaN");
        }
    }
    for &x in &odd[..4] {
        let i = xs.iter().position(|v| v.to_bits() == x.to_bits()).unwrap();
        assert_eq!(got[i].to_bits(), x.sin().to_bits(), "sin({x:e}) is libm's");
    }
}

/// Asserts that some of `flex(xs)` differ from libm's `reference` in the
/// last bit: the polynomials and libm round differently for some
/// arguments, so without the patch every result would be libm's.
fn assert_not_all_libm(xs: &[f32], flex: fn(&[f32]) -> Vec<f32>, reference: fn(f32) -> f32) {
    let differ = xs
        .iter()
        .zip(&flex(xs))
        .filter(|(x, y)| reference(**x).to_bits() != y.to_bits())
        .count();
    assert!(
        differ > 0,
        "every result is libm's: is vendor/burn-flex patched in?"
    );
}

#[test]
fn the_vectorised_path_is_in_use() {
    let xs: Vec<f32> = (0..10_000).map(|i| i as f32 * 0.618 - 3000.0).collect();
    assert_not_all_libm(&xs, flex_sin, f32::sin);
}

/// Largest relative error of `e^x` over `xs`, against float64.
fn max_exp_error(xs: &[f32], got: &[f32]) -> (f64, f32) {
    xs.iter()
        .zip(got)
        .map(|(&x, &y)| {
            let r = (x as f64).exp();
            ((y as f64 - r).abs() / r, x)
        })
        .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
}

#[test]
fn exp_matches_float64_over_its_fast_range() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for (lo, hi) in [
        (-87.0f32, 88.0f32),
        (-1.0, 1.0),
        (-1e-3, 1e-3),
        (-30.0, 0.0),
    ] {
        for n in [1usize, 7, 63, 65, 1000, 300_001] {
            let xs: Vec<f32> = (0..n).map(|_| rng.random_range(lo..=hi)).collect();
            let (err, at) = max_exp_error(&xs, &flex_exp(&xs));
            println!("exp, x in [{lo}, {hi}], n {n}: largest relative error {err:.2e}");
            assert!(
                err <= 2.5e-7,
                "[{lo}, {hi}], n {n}: error {err:e} at x = {at}"
            );
        }
    }
    // Every multiple of ln(2) / 2 in range, where the reduction switches.
    let xs: Vec<f32> = (-251i32..=253)
        .map(|k| k as f32 * std::f32::consts::LN_2 / 2.0)
        .flat_map(|x| [x, f32::from_bits(x.to_bits() + 1)])
        .filter(|x| (-87.0..=88.0).contains(x))
        .collect();
    let (err, at) = max_exp_error(&xs, &flex_exp(&xs));
    assert!(err <= 2.5e-7, "error {err:e} at x = {at}");
    assert_eq!(flex_exp(&[0.0, -0.0]), vec![1.0, 1.0]);
}

#[test]
fn exp_of_very_negative_arguments_is_zero_and_the_rest_is_libms() {
    // The encoding's integrated-away features: huge variances.
    let mut xs: Vec<f32> = (0..300).map(|i| -104.5 - i as f32 * 1e3).collect();
    xs.extend([f32::MIN, f32::NEG_INFINITY, -1e30]);
    assert!(flex_exp(&xs).iter().all(|&y| y.to_bits() == 0));
    // Subnormal and overflowing results, infinities and NaN, mixed into
    // blocks of fast arguments.
    let mut xs: Vec<f32> = (0..200).map(|i| i as f32 * 0.37 - 30.0).collect();
    let odd = [
        -87.5f32,
        -95.0,
        -103.9,
        88.5,
        89.0,
        1e30,
        f32::INFINITY,
        f32::NAN,
    ];
    for (i, &x) in odd.iter().enumerate() {
        xs[i * 23 + 5] = x;
    }
    let got = flex_exp(&xs);
    for (x, y) in xs.iter().zip(&got) {
        if (-87.0..=88.0).contains(x) {
            let r = (*x as f64).exp();
            assert!((*y as f64 - r).abs() / r <= 2.5e-7, "exp({x}) = {y:e}");
        } else {
            assert_eq!(y.to_bits(), x.exp().to_bits(), "exp({x}) is libm's");
        }
    }
}

#[test]
fn exp_is_vectorised_too() {
    let xs: Vec<f32> = (0..10_000).map(|i| i as f32 * 0.0171 - 85.0).collect();
    assert_not_all_libm(&xs, flex_exp, f32::exp);
}
