//! Losses against direct f64 evaluation, their masking rules and finiteness
//! (including gradients) at zero-norm vectors and f16-range magnitudes.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

mod common;

use burn::tensor::Device;
use common::{assert_close, devices, tensor, vec};
use model::{depth_huber, open_set_cosine, rgb_mse};

#[test]
fn rgb_mse_matches_direct() {
    for (name, device) in devices(true) {
        let p = vec![0.1, 0.2, 0.3, 0.9, 0.5, 0.0];
        let t = vec![0.0, 0.2, 0.5, 1.0, 0.5, 0.5];
        let want: f32 = p
            .iter()
            .zip(&t)
            .map(|(a, b): (&f32, &f32)| (a - b).powi(2))
            .sum::<f32>()
            / 6.0;
        let got = vec(rgb_mse(
            tensor(p, [2, 3], &device),
            tensor(t, [2, 3], &device),
        ));
        assert_close(&got, &[want], 1e-7, 1e-5, name);
    }
}

/// Huber on valid rays only (target > 0, NaN excluded), weighted, divided by
/// the number of valid rays; zero when none is valid.
#[test]
fn depth_huber_masks_and_weights() {
    for (name, device) in devices(true) {
        let pred = vec![1.0, 2.0, 5.0, 3.0, 7.0];
        let target = vec![1.5, 0.0, 2.0, f32::NAN, -1.0];
        let weight = vec![1.0, 1.0, 0.5, 1.0, 1.0];
        let delta = 1.0f32;
        let huber = |r: f32| {
            if r.abs() <= delta {
                0.5 * r * r
            } else {
                delta * (r.abs() - 0.5 * delta)
            }
        };
        let want = (1.0 * huber(-0.5) + 0.5 * huber(3.0)) / 2.0;
        let got = vec(depth_huber(
            tensor(pred, [5, 1], &device),
            tensor(target, [5, 1], &device),
            tensor(weight, [5, 1], &device),
            delta,
        ));
        assert_close(&got, &[want], 1e-6, 1e-5, name);
        let none = vec(depth_huber(
            tensor(vec![1.0, 2.0], [2, 1], &device),
            tensor(vec![0.0, -3.0], [2, 1], &device),
            tensor(vec![1.0, 1.0], [2, 1], &device),
            delta,
        ));
        assert_eq!(none, vec![0.0], "{name}: no valid depth");
    }
}

/// Mean of 1 - cos over rays with a non-zero target; zero-norm targets are
/// skipped, zero-norm predictions and f16-range magnitudes stay finite, and
/// so does the gradient.
#[test]
fn cosine_loss_handles_zero_norms() {
    for (name, device) in devices(false) {
        let device: Device = device.autodiff();
        let pred = vec![
            1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0, 4.0, 0.0, 60000.0, 60000.0, -60000.0,
        ];
        let target = vec![
            0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 65504.0, -65504.0, 65504.0,
        ];
        // Rays: orthogonal (1 - 0), zero pred (1 - 0), zero target (skipped),
        // f16-range (cos = -1/3).
        let want = (1.0 + 1.0 + (1.0 + 1.0 / 3.0)) / 3.0;
        let p = tensor(pred, [4, 3], &device).require_grad();
        let loss = open_set_cosine(p.clone(), tensor(target.clone(), [4, 3], &device));
        assert_close(&vec(loss.clone()), &[want], 1e-6, 1e-5, name);
        let grads = loss.backward();
        let g = vec(p.grad(&grads).expect("gradient"));
        assert!(g.iter().all(|v| v.is_finite()), "{name}: gradient {g:?}");
        // The skipped ray gets no gradient.
        assert_eq!(&g[6..9], &[0.0, 0.0, 0.0], "{name}");
        let all_zero = vec(open_set_cosine(
            tensor(vec![1.0, 2.0], [1, 2], &device),
            tensor(vec![0.0, 0.0], [1, 2], &device),
        ));
        assert_eq!(all_zero, vec![0.0], "{name}: no valid target");
    }
}
