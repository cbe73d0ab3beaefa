//! Flushing subnormals: after `flush_to_zero`, arithmetic whose result is
//! subnormal gives zero on the calling thread, on every thread of rayon's
//! global pool and in flex's tensor ops, and normal numbers are untouched.
//! (Alone in its test binary: the switch is per thread and stays set.)

use std::hint::black_box;

use burn::tensor::{Device, Tensor};
use field_ops::subnormals::{flush_to_zero, flushed_on_this_thread};

#[test]
fn flushing_zeroes_subnormal_results_on_every_thread_and_in_flex() {
    let tiny = f32::MIN_POSITIVE; // the smallest normal f32
    // The CPU's default: half of it is a subnormal, not zero.
    assert!(black_box(tiny) * black_box(0.5) > 0.0);
    assert!(!flushed_on_this_thread());
    let switched = flush_to_zero();
    assert_eq!(switched, cfg!(target_arch = "x86_64"));
    if !switched {
        return;
    }
    assert!(flushed_on_this_thread());
    assert_eq!(black_box(tiny) * black_box(0.5), 0.0);
    // A subnormal input reads as zero (denormals-are-zero).
    assert_eq!(
        black_box(f32::from_bits(1)) * black_box(2.0f32.powi(30)),
        0.0
    );
    let pool = rayon::broadcast(|_| (flushed_on_this_thread(), black_box(tiny) * black_box(0.5)));
    assert_eq!(pool.len(), rayon::current_num_threads());
    assert!(pool.iter().all(|&(on, x)| on && x == 0.0), "{pool:?}");
    // Normal numbers are computed as before.
    assert_eq!(black_box(tiny) * black_box(2.0), 2.0 * f32::MIN_POSITIVE);
    assert_eq!(black_box(1.5f32) * black_box(1.25), 1.875);
    // flex, element-wise and in a product large enough for the pool.
    let device = Device::flex();
    let x = Tensor::<1>::from_floats([tiny, 1.0], &device).mul_scalar(0.5);
    assert_eq!(x.into_data().try_to_vec::<f32>().unwrap(), vec![0.0, 0.5]);
    let a = Tensor::<2>::full([256, 256], 1e-20, &device);
    let b = Tensor::<2>::full([256, 256], 1e-20, &device);
    let p: Vec<f32> = a.matmul(b).into_data().try_to_vec().unwrap();
    assert!(p.iter().all(|&v| v == 0.0), "1e-40 per product: flushed");
}
