//! The proposal sampler's host resampling against the tensor forms it
//! replaces (`sample_pdf`, `anneal_weights`) and against inverse-CDF
//! sampling evaluated in f64, on step functions with empty intervals,
//! weightless rays and single intervals.

use super::{anneal_weights, assert_close, devices, tensor, vec};
use model::stepfun::{
    anneal_weights_host, blur_weights, blur_weights_host, pdf_quantiles, resample_t_vals_on_device,
    resample_t_vals_on_host, sample_pdf, sample_pdf_host,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// `rays` step functions of `n` intervals on [0, 1], row-major: sorted ends
/// (about a fifth of the intervals empty) and weights (some zero, and every
/// fourth ray weightless).
fn steps(rng: &mut ChaCha8Rng, rays: usize, n: usize) -> (Vec<f32>, Vec<f32>) {
    let (mut t, mut w) = (Vec::new(), Vec::new());
    for r in 0..rays {
        let mut ends: Vec<f32> = (0..n + 1).map(|_| rng.random_range(0.0..1.0)).collect();
        for j in 1..=n {
            if rng.random_range(0.0..1.0) < 0.2 {
                ends[j] = ends[j - 1];
            }
        }
        ends.sort_by(f32::total_cmp);
        t.extend(ends);
        for _ in 0..n {
            let x: f32 = rng.random_range(0.0..1.0);
            w.push(if r % 4 == 3 || x < 0.15 { 0.0 } else { x });
        }
    }
    (t, w)
}

/// Inverse-CDF sampling in f64 by a scan over the intervals: the pdf of
/// `sample_pdf` (weights padded towards uniform when they sum below 1e-5),
/// and each quantile placed linearly inside the last interval whose CDF
/// starts at or below it (an interval of no mass yields its start).
fn sample_pdf64(bins: &[f32], weights: &[f32], u: &[f32], rays: usize) -> Vec<f64> {
    let n = weights.len() / rays;
    let k = u.len() / rays;
    let mut out = Vec::new();
    for r in 0..rays {
        let b: Vec<f64> = bins[r * (n + 1)..(r + 1) * (n + 1)]
            .iter()
            .map(|&x| x as f64)
            .collect();
        let w: Vec<f64> = weights[r * n..(r + 1) * n]
            .iter()
            .map(|&x| x as f64)
            .collect();
        let sum: f64 = w.iter().sum();
        let pad = (1e-5 - sum).max(0.0);
        let mut cdf = vec![0.0];
        for j in 0..n - 1 {
            cdf.push((cdf[j] + (w[j] + pad / n as f64) / (sum + pad)).min(1.0));
        }
        cdf.push(1.0);
        for &q in &u[r * k..(r + 1) * k] {
            let q = q as f64;
            let count = cdf.iter().filter(|&&c| c <= q).count();
            let lo = count.saturating_sub(1);
            let hi = count.min(n);
            let d = cdf[hi] - cdf[lo];
            let f = if d <= 0.0 {
                0.0
            } else {
                ((q - cdf[lo]) / d).clamp(0.0, 1.0)
            };
            out.push(b[lo] + f * (b[hi] - b[lo]));
        }
    }
    out
}

#[test]
fn host_sampling_equals_the_tensor_form() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    for (name, device) in devices(false) {
        for (n, k) in [(1, 2), (3, 9), (16, 65), (191, 33)] {
            let rays = 24;
            let (t, w) = steps(&mut rng, rays, n);
            let u = vec(pdf_quantiles(rays, k, false, &device));
            let dense = vec(sample_pdf(
                tensor(t.clone(), [rays, n + 1], &device),
                tensor(w.clone(), [rays, n], &device),
                k,
                false,
            ));
            let host = sample_pdf_host(&t, &w, &u, rays);
            assert_close(&host, &dense, 2e-6, 1e-5, &format!("{name}: n {n}, k {k}"));
        }
    }
}

#[test]
fn host_sampling_inverts_the_cdf_in_float64() {
    let mut rng = ChaCha8Rng::seed_from_u64(32);
    for (name, device) in devices(false) {
        for (n, k) in [(1, 3), (8, 33), (64, 65), (191, 33)] {
            let rays = 32;
            let (t, w) = steps(&mut rng, rays, n);
            // Jittered quantiles, from the backend's generator.
            let u = vec(pdf_quantiles(rays, k, true, &device));
            let host = sample_pdf_host(&t, &w, &u, rays);
            let want: Vec<f32> = sample_pdf64(&t, &w, &u, rays)
                .iter()
                .map(|&x| x as f32)
                .collect();
            assert_close(&host, &want, 2e-5, 1e-4, &format!("{name}: n {n}, k {k}"));
            for row in host.chunks(k) {
                assert!(
                    row.windows(2).all(|p| p[0] <= p[1]),
                    "{name}: unsorted {row:?}"
                );
            }
        }
    }
}

#[test]
fn host_annealing_equals_the_tensor_form() {
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    for (name, device) in devices(false) {
        let (rays, n) = (16, 40);
        let (t, w) = steps(&mut rng, rays, n);
        for (exponent, padding) in [(0.0, 0.0), (0.37, 0.0), (1.0, 0.01), (1.0, 0.0)] {
            let dense = vec(anneal_weights(
                tensor(t.clone(), [rays, n + 1], &device),
                tensor(w.clone(), [rays, n], &device),
                exponent,
                padding,
            ));
            let mut host = w.clone();
            anneal_weights_host(&t, &mut host, rays, exponent, padding);
            let what = format!("{name}: exponent {exponent}, padding {padding}");
            assert_close(&host, &dense, 1e-7, 1e-5, &what);
        }
    }
}

/// One proposal round in its two forms (the host's loops, the device's
/// tensor ops): the same posts on every backend (wgpu where a Vulkan driver
/// is), for a first round and dilated ones, plain and jittered (the same
/// draw of the generator), one sample and many; every row from 0 to 1,
/// sorted.
#[test]
fn a_round_resamples_alike_on_the_host_and_on_the_device() {
    use model::proposal::rounds::{
        Round, resample, resample_on_device, resample_on_device_in_chunks, resample_on_host,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(34);
    for (name, device) in devices(true) {
        let cases = [
            (None, 1, 8, false),
            (None, 5, 12, true),
            (Some(0.02), 16, 32, false),
            (Some(0.005), 33, 16, true),
            (Some(0.1), 8, 1, true),
        ];
        for (dilation, n, count, randomized) in cases {
            let rays = 12;
            let (t, w) = steps(&mut rng, rays, n);
            let round = Round {
                dilation,
                exponent: 0.6,
                padding: 0.0,
                count,
                randomized,
            };
            let s = tensor(t, [rays, n + 1], &device);
            let w = tensor(w, [rays, n], &device);
            device.seed(9);
            let host = vec(resample_on_host(&round, s.clone(), w.clone()));
            device.seed(9);
            let dense = vec(resample_on_device(&round, s.clone(), w.clone()));
            let what = format!("{name}: {round:?}");
            assert_close(&dense, &host, 1e-6, 0.0, &what);
            // In chunks of one to a few rays, with the quantiles drawn once.
            for chunk_elements in [1, 5000] {
                device.seed(9);
                let chunked = vec(resample_on_device_in_chunks(
                    &round,
                    s.clone(),
                    w.clone(),
                    chunk_elements,
                ));
                let what = format!("{what}: chunks of {chunk_elements}");
                assert_close(&chunked, &dense, 1e-6, 1e-6, &what);
            }
            for row in host.chunks(count + 1) {
                assert_eq!((row[0], row[count]), (0.0, 1.0), "{what}");
                assert!(row.windows(2).all(|p| p[0] <= p[1]), "{what}: {row:?}");
            }
            // `resample` takes one of the two.
            device.seed(9);
            let chosen = vec(resample(&round, s, w));
            let cpu = model::host_work::is_cpu_backend(&device);
            assert_eq!(chosen, if cpu { host } else { dense }, "{what}");
        }
    }
}

#[test]
fn the_fine_resample_on_the_host_equals_the_tensor_form() {
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    for (name, device) in devices(false) {
        for n in [1, 2, 16, 48] {
            let rays = 20;
            let (t, w) = steps(&mut rng, rays, n);
            let t_vals = tensor(t.clone(), [rays, n + 1], &device);
            let weights = tensor(w.clone(), [rays, n], &device);
            for padding in [0.0, 0.01] {
                let host = vec(resample_t_vals_on_host(
                    t_vals.clone(),
                    weights.clone(),
                    padding,
                    false,
                ));
                let dense = vec(resample_t_vals_on_device(
                    t_vals.clone(),
                    weights.clone(),
                    padding,
                    false,
                ));
                let what = format!("{name}: n {n}, padding {padding}");
                assert_close(&host, &dense, 2e-6, 1e-5, &what);
                let blurred = vec(blur_weights(weights.clone(), padding));
                assert_close(
                    &blur_weights_host(&w, rays, padding),
                    &blurred,
                    0.0,
                    0.0,
                    &what,
                );
            }
        }
    }
}
