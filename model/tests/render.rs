//! Compositing and sampling against f64 references and their invariants,
//! including the numerical extremes.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{assert_close, devices, tensor, vec};
use model::composite::composite;
use model::sampling::stratified_t_vals;
use model::stepfun::{blur_weights, sample_pdf};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// f64 reference compositing of one ray: (weights, transmittances, rgb, depth, acc).
fn reference(
    density: &[f64],
    rgb: &[[f64; 3]],
    t: &[f64],
    dnorm: f64,
) -> (Vec<f64>, Vec<f64>, [f64; 3], f64, f64) {
    let mut trans = 1.0f64;
    let mut w = Vec::new();
    let mut ts = Vec::new();
    let mut c = [0.0; 3];
    let mut depth = 0.0;
    for i in 0..density.len() {
        let tau = density[i] * (t[i + 1] - t[i]) * dnorm;
        let wi = (1.0 - (-tau).exp()) * trans;
        ts.push(trans);
        w.push(wi);
        for k in 0..3 {
            c[k] += wi * rgb[i][k];
        }
        depth += wi * 0.5 * (t[i] + t[i + 1]);
        trans *= (-tau).exp();
    }
    let acc: f64 = w.iter().sum();
    (w, ts, c, depth / acc.max(1e-10), acc)
}

struct Batch {
    density: Vec<f32>,
    rgb: Vec<f32>,
    t: Vec<f32>,
    dnorm: Vec<f32>,
    rays: usize,
    s: usize,
}

fn random_batch(rays: usize, s: usize, seed: u64) -> Batch {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = Vec::new();
    for _ in 0..rays {
        let mut v: Vec<f32> = (0..=s).map(|_| rng.random_range(0.5..4.0)).collect();
        v.sort_by(f32::total_cmp);
        t.extend(v);
    }
    Batch {
        // Log-uniform densities from 1e-3 to 1e3 plus exact zeros.
        density: (0..rays * s)
            .map(|i| {
                if i % 7 == 0 {
                    0.0
                } else {
                    10f32.powf(rng.random_range(-3.0..3.0))
                }
            })
            .collect(),
        rgb: (0..rays * s * 3).map(|_| rng.random()).collect(),
        t,
        dnorm: (0..rays).map(|_| rng.random_range(0.5..3.0)).collect(),
        rays,
        s,
    }
}

/// Weights, colour, depth and opacity equal the f64 reference; weights are in
/// [0, 1], sum to at most 1, and the transmittance implied by them is
/// non-increasing.
#[test]
fn compositing_matches_reference_and_invariants() {
    let b = random_batch(6, 16, 1);
    for (name, device) in devices(true) {
        let out = composite(
            tensor(b.density.clone(), [b.rays, b.s], &device),
            tensor(b.rgb.clone(), [b.rays, b.s, 3], &device),
            tensor(b.t.clone(), [b.rays, b.s + 1], &device),
            tensor(b.dnorm.clone(), [b.rays, 1], &device),
            None,
        );
        let (w, rgb, depth, acc) = (vec(out.weights), vec(out.rgb), vec(out.depth), vec(out.acc));
        for r in 0..b.rays {
            let dens: Vec<f64> = b.density[r * b.s..(r + 1) * b.s]
                .iter()
                .map(|&v| v as f64)
                .collect();
            let cols: Vec<[f64; 3]> = (0..b.s)
                .map(|i| std::array::from_fn(|k| b.rgb[(r * b.s + i) * 3 + k] as f64))
                .collect();
            let t: Vec<f64> = b.t[r * (b.s + 1)..(r + 1) * (b.s + 1)]
                .iter()
                .map(|&v| v as f64)
                .collect();
            let (ew, ets, ec, ed, ea) = reference(&dens, &cols, &t, b.dnorm[r] as f64);
            let got = &w[r * b.s..(r + 1) * b.s];
            let want: Vec<f32> = ew.iter().map(|&v| v as f32).collect();
            assert_close(got, &want, 1e-5, 1e-4, &format!("{name} weights ray {r}"));
            assert_close(
                &rgb[3 * r..3 * r + 3],
                &ec.map(|v| v as f32),
                1e-5,
                1e-4,
                &format!("{name} rgb"),
            );
            assert_close(
                &[depth[r]],
                &[ed as f32],
                1e-4,
                1e-4,
                &format!("{name} depth"),
            );
            assert_close(&[acc[r]], &[ea as f32], 1e-5, 1e-5, &format!("{name} acc"));
            assert!(
                got.iter().all(|&v| (0.0..=1.0).contains(&v)),
                "{name}: weight range"
            );
            assert!(acc[r] <= 1.0 + 1e-6, "{name}: acc {}", acc[r]);
            // T_i = 1 - sum_{j<i} w_j must be non-increasing and match the reference.
            let mut prev = f32::INFINITY;
            let mut cum = 0.0f32;
            for (i, &wi) in got.iter().enumerate() {
                let ti = 1.0 - cum;
                assert!(ti <= prev + 1e-6, "{name}: transmittance increases at {i}");
                assert!(
                    (ti as f64 - ets[i]).abs() < 1e-4,
                    "{name}: transmittance {i}"
                );
                prev = ti;
                cum += wi;
            }
        }
    }
}

/// An opaque first sample takes all the weight; an empty ray gives zero
/// colour, opacity and depth; the background fills the missing opacity.
#[test]
fn opaque_and_empty_rays() {
    for (name, device) in devices(true) {
        let s = 4;
        let density = vec![1e10, 5.0, 5.0, 5.0, 0.0, 0.0, 0.0, 0.0];
        let rgb: Vec<f32> = (0..2 * s * 3).map(|i| (i % 5) as f32 / 5.0).collect();
        let t = vec![1.0, 1.5, 2.0, 2.5, 3.0, 1.0, 1.5, 2.0, 2.5, 3.0];
        let out = composite(
            tensor(density.clone(), [2, s], &device),
            tensor(rgb.clone(), [2, s, 3], &device),
            tensor(t.clone(), [2, s + 1], &device),
            tensor(vec![1.0, 1.0], [2, 1], &device),
            None,
        );
        let w = vec(out.weights);
        assert_eq!(
            &w[..4],
            &[1.0, 0.0, 0.0, 0.0],
            "{name}: opaque first sample"
        );
        assert_eq!(&w[4..], &[0.0; 4], "{name}: empty ray");
        assert_close(
            &vec(out.rgb),
            &[rgb[0], rgb[1], rgb[2], 0.0, 0.0, 0.0],
            1e-6,
            0.0,
            name,
        );
        assert_eq!(vec(out.acc), vec![1.0, 0.0], "{name}");
        assert_close(&vec(out.depth), &[1.25, 0.0], 1e-6, 0.0, name);
        let bg = [0.2, 0.4, 0.6];
        let out = composite(
            tensor(density, [2, s], &device),
            tensor(rgb.clone(), [2, s, 3], &device),
            tensor(t, [2, s + 1], &device),
            tensor(vec![1.0, 1.0], [2, 1], &device),
            Some(bg),
        );
        assert_close(
            &vec(out.rgb),
            &[rgb[0], rgb[1], rgb[2], 0.2, 0.4, 0.6],
            1e-6,
            0.0,
            name,
        );
    }
}

/// Extremes: densities 0 and 1e10 mixed, zero-length intervals, a single
/// sample, near == far, and a huge density after small ones (where an
/// inclusive-scan-minus-tau shortcut would overshoot) stay finite and exact.
#[test]
fn compositing_extremes() {
    for (name, device) in devices(true) {
        // Huge density after a small one: w = [1 - e^-0.1, e^-0.1, 0].
        let out = composite(
            tensor(vec![0.1, 1e10, 1e10], [1, 3], &device),
            tensor(vec![0.5; 9], [1, 3, 3], &device),
            tensor(vec![0.0, 1.0, 2.0, 3.0], [1, 4], &device),
            tensor(vec![1.0], [1, 1], &device),
            None,
        );
        let w = vec(out.weights);
        let e = (-0.1f64).exp();
        assert_close(
            &w,
            &[(1.0 - e) as f32, e as f32, 0.0],
            1e-6,
            0.0,
            &format!("{name} huge after small"),
        );
        assert!(vec(out.acc)[0] <= 1.0 + 1e-6);
        // Zero-length intervals (near == far) with huge density: no NaN, no weight.
        let out = composite(
            tensor(vec![1e10, 1e10, 0.0], [1, 3], &device),
            tensor(vec![0.5; 9], [1, 3, 3], &device),
            tensor(vec![2.0; 4], [1, 4], &device),
            tensor(vec![1.0], [1, 1], &device),
            None,
        );
        assert_eq!(vec(out.weights), vec![0.0; 3], "{name}: zero-length");
        assert_eq!(vec(out.depth), vec![0.0], "{name}: zero-length depth");
        // Single sample per ray, opaque and transparent.
        let out = composite(
            tensor(vec![1e10, 0.0], [2, 1], &device),
            tensor(vec![0.3; 6], [2, 1, 3], &device),
            tensor(vec![1.0, 2.0, 1.0, 2.0], [2, 2], &device),
            tensor(vec![1.0, 1.0], [2, 1], &device),
            None,
        );
        assert_eq!(vec(out.acc), vec![1.0, 0.0], "{name}: single sample");
        assert_close(&vec(out.depth), &[1.5, 0.0], 1e-6, 0.0, name);
    }
}

/// Deterministic stratified posts are the even grid; randomized ones stay
/// sorted and inside [near, far], each in its own stratum.
#[test]
fn stratified_sampling() {
    for (name, device) in devices(true) {
        let near = tensor(vec![1.0, 2.0, 3.0], [3, 1], &device);
        let far = tensor(vec![2.0, 6.0, 3.0], [3, 1], &device);
        let s = 4;
        let t = vec(stratified_t_vals(near.clone(), far.clone(), s, false));
        let want = [
            1.0, 1.25, 1.5, 1.75, 2.0, 2.0, 3.0, 4.0, 5.0, 6.0, 3.0, 3.0, 3.0, 3.0, 3.0,
        ];
        assert_close(&t, &want, 1e-6, 0.0, name);
        let t = vec(stratified_t_vals(near, far, s, true));
        for r in 0..3 {
            let row = &t[r * (s + 1)..(r + 1) * (s + 1)];
            for i in 0..=s {
                let g = want[r * (s + 1) + i];
                let step = (want[r * (s + 1) + s] - want[r * (s + 1)]) / s as f32;
                assert!(
                    (row[i] - g).abs() <= 0.5 * step + 1e-5,
                    "{name}: stratum {i}"
                );
                assert!(
                    row[i] >= want[r * (s + 1)] - 1e-6 && row[i] <= want[r * (s + 1) + s] + 1e-6
                );
                if i > 0 {
                    assert!(row[i] >= row[i - 1], "{name}: sorted");
                }
            }
        }
    }
}

/// Blur-resample weights against a direct f64 evaluation.
#[test]
fn blur_matches_reference() {
    let w = [0.0f32, 0.5, 0.1, 0.0, 0.9];
    let mut p = vec![w[0]];
    p.extend_from_slice(&w);
    p.push(w[4]);
    let maxes: Vec<f32> = (0..6).map(|i| p[i].max(p[i + 1])).collect();
    let want: Vec<f32> = (0..5)
        .map(|i| 0.5 * (maxes[i] + maxes[i + 1]) + 0.01)
        .collect();
    for (name, device) in devices(true) {
        let got = vec(blur_weights(tensor(w.to_vec(), [1, 5], &device), 0.01));
        assert_close(&got, &want, 1e-6, 0.0, name);
    }
}

/// Brute-force inverse CDF in f64 for one ray.
fn inverse_cdf(bins: &[f64], weights: &[f64], u: &[f64]) -> Vec<f64> {
    let total: f64 = weights.iter().sum();
    let mut cdf = vec![0.0];
    for w in weights {
        let last = *cdf.last().unwrap_or(&0.0);
        cdf.push(last + w / total);
    }
    u.iter()
        .map(|&q| {
            let j = (0..weights.len()).rev().find(|&j| q >= cdf[j]).unwrap_or(0);
            let f = ((q - cdf[j]) / (cdf[j + 1] - cdf[j])).clamp(0.0, 1.0);
            bins[j] + f * (bins[j + 1] - bins[j])
        })
        .collect()
}

/// Deterministic inverse-CDF sampling equals a brute-force f64 inversion;
/// randomized samples stay sorted and inside the bins; a zero-weight ray
/// samples uniformly.
#[test]
fn pdf_sampling_matches_brute_force() {
    let bins = [1.0f32, 1.5, 2.0, 3.0, 3.5, 5.0];
    let weights = [0.1f32, 0.0, 0.6, 0.2, 0.1];
    let n = 9;
    let u: Vec<f64> = (0..n)
        .map(|i| (1.0 - 1e-5) * i as f64 / (n - 1) as f64)
        .collect();
    let b64: Vec<f64> = bins.iter().map(|&v| v as f64).collect();
    let w64: Vec<f64> = weights.iter().map(|&v| v as f64).collect();
    let want: Vec<f32> = inverse_cdf(&b64, &w64, &u)
        .iter()
        .map(|&v| v as f32)
        .collect();
    for (name, device) in devices(true) {
        let mut b = bins.to_vec();
        b.extend_from_slice(&bins);
        let mut w = weights.to_vec();
        w.extend_from_slice(&[0.0; 5]);
        let got = vec(sample_pdf(
            tensor(b.clone(), [2, 6], &device),
            tensor(w.clone(), [2, 5], &device),
            n,
            false,
        ));
        assert_close(&got[..n], &want, 1e-4, 1e-5, &format!("{name} inverse cdf"));
        // Zero weights: uniform in [1, 5] by quantile.
        let uniform: Vec<f32> = inverse_cdf(&b64, &[1.0; 5], &u)
            .iter()
            .map(|&v| v as f32)
            .collect();
        assert_close(
            &got[n..],
            &uniform,
            1e-4,
            1e-5,
            &format!("{name} zero weights"),
        );
        let got = vec(sample_pdf(
            tensor(b, [2, 6], &device),
            tensor(w, [2, 5], &device),
            n,
            true,
        ));
        for r in 0..2 {
            let row = &got[r * n..(r + 1) * n];
            assert!(
                row.windows(2).all(|p| p[0] <= p[1]),
                "{name}: sorted {row:?}"
            );
            assert!(
                row.iter().all(|&v| (1.0..=5.0).contains(&v)),
                "{name}: in range"
            );
        }
        // No sample falls in the zero-weight bin (1.5, 2.0) of the first ray.
        assert!(
            got[..n]
                .iter()
                .all(|&v| !(v > 1.5 + 1e-4 && v < 2.0 - 1e-4)),
            "{name}: {got:?}"
        );
    }
}
