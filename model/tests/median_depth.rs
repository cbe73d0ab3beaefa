//! The median depth against a brute-force f64 reference (each interval cut
//! into many steps of its constant density), split over segments as the
//! march renders it, and against the expected depth where a little weight
//! lies far behind the surface.
// Index loops mirror the formulas in the reference computation.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{devices, tensor, vec};
use model::composite::{SegmentOptics, compute_weights, depth_crossing, median_depth};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Where the accumulated weight of one ray first reaches `level`, walking
/// each interval in `steps` equal steps of its constant density (f64); `None`
/// where it never does.
fn brute_force_crossing(density: &[f64], t: &[f64], dnorm: f64, level: f64) -> Option<f64> {
    let steps = 20_000;
    let mut acc = 0.0f64;
    for i in 0..density.len() {
        let h = (t[i + 1] - t[i]) / steps as f64;
        for k in 0..steps {
            let next = 1.0 - (1.0 - acc) * (-density[i] * h * dnorm).exp();
            if next >= level {
                // The last step's share of the way, linear inside one small step.
                let f = if next > acc {
                    (level - acc) / (next - acc)
                } else {
                    0.0
                };
                return Some(t[i] + (k as f64 + f) * h);
            }
            acc = next;
        }
    }
    None
}

struct Rays {
    density: Vec<f32>,
    t: Vec<f32>,
    dnorm: Vec<f32>,
    n: usize,
    s: usize,
}

/// Rays of `s` samples from 0.5 to 4 with the last post far out (as an
/// unbounded ray's), log-uniform densities and some exact zeros; every
/// fourth ray a thousand times thinner, so that some never reach a half.
fn random_rays(n: usize, s: usize, seed: u64) -> Rays {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = Vec::new();
    for _ in 0..n {
        let mut v: Vec<f32> = (0..s).map(|_| rng.random_range(0.5..4.0)).collect();
        v.sort_by(f32::total_cmp);
        v.push(rng.random_range(50.0..1000.0));
        t.extend(v);
    }
    let density = (0..n * s)
        .map(|i| {
            let thin = if (i / s).is_multiple_of(4) { 1e-3 } else { 1.0 };
            if i % 5 == 0 {
                0.0
            } else {
                thin * 10f32.powf(rng.random_range(-2.0..1.5))
            }
        })
        .collect();
    let dnorm = (0..n).map(|_| rng.random_range(0.5..2.0)).collect();
    Rays {
        density,
        t,
        dnorm,
        n,
        s,
    }
}

/// Where a ray's weight reaches a half the median matches the brute-force
/// crossing to a thousandth of the interval it falls in (plus float noise);
/// where it never does, the median is the expected depth given.
#[test]
fn median_depth_matches_brute_force() {
    for (name, device) in devices(false) {
        let r = random_rays(64, 12, 7);
        let expected: Vec<f32> = (0..r.n).map(|i| -(i as f32) - 1.0).collect();
        let median = vec(median_depth(
            tensor(r.density.clone(), [r.n, r.s], &device),
            tensor(r.t.clone(), [r.n, r.s + 1], &device),
            tensor(r.dnorm.clone(), [r.n, 1], &device),
            tensor(expected.clone(), [r.n, 1], &device),
        ));
        let (mut crossed, mut not) = (0, 0);
        for i in 0..r.n {
            let d: Vec<f64> = r.density[i * r.s..(i + 1) * r.s]
                .iter()
                .map(|&x| x as f64)
                .collect();
            let t: Vec<f64> = r.t[i * (r.s + 1)..(i + 1) * (r.s + 1)]
                .iter()
                .map(|&x| x as f64)
                .collect();
            match brute_force_crossing(&d, &t, r.dnorm[i] as f64, 0.5) {
                Some(want) => {
                    crossed += 1;
                    let k = t.windows(2).position(|w| want <= w[1]).unwrap();
                    let tol = 1e-3 * (t[k + 1] - t[k]) + 1e-4 * want;
                    let got = median[i] as f64;
                    assert!(
                        (got - want).abs() <= tol,
                        "{name}: ray {i}: median {got}, brute force {want} (interval {k}, tol {tol})"
                    );
                }
                None => {
                    not += 1;
                    assert_eq!(
                        median[i], expected[i],
                        "{name}: ray {i} never reaches a half"
                    );
                }
            }
        }
        assert!(
            crossed > 20 && not > 0,
            "{name}: both cases drawn ({crossed}, {not})"
        );
    }
}

/// Rendered in segments (each given the weight ahead of it), exactly one
/// segment holds a ray's crossing and their sum is the crossing of the
/// whole ray.
#[test]
fn crossing_split_over_segments_sums_to_the_whole() {
    for (name, device) in devices(false) {
        let r = random_rays(48, 12, 11);
        let t = tensor(r.t.clone(), [r.n, r.s + 1], &device);
        let density = tensor(r.density.clone(), [r.n, r.s], &device);
        let dnorm = tensor(r.dnorm.clone(), [r.n, 1], &device);
        let zero = tensor(vec![0.0; r.n], [r.n, 1], &device);
        let optics = SegmentOptics::new(density.clone(), t.clone(), dnorm.clone(), zero.clone());
        let (whole, whole_found) = depth_crossing(&optics, t.clone(), 0.5);
        let (whole, whole_found) = (vec(whole), vec(whole_found));
        let (mut sum, mut found) = (vec![0.0f32; r.n], vec![0.0f32; r.n]);
        let mut tau_before = zero;
        for (a, b) in [(0, 5), (5, 9), (9, 12)] {
            let d = density.clone().slice_dim(1, a..b);
            let ts = t.clone().slice_dim(1, a..b + 1);
            let optics = SegmentOptics::new(d, ts.clone(), dnorm.clone(), tau_before);
            let (part, part_found) = depth_crossing(&optics, ts, 0.5);
            let (part, part_found) = (vec(part), vec(part_found));
            for i in 0..r.n {
                assert!(
                    part_found[i] == 0.0 || found[i] == 0.0,
                    "{name}: ray {i} crosses in two segments"
                );
                sum[i] += part[i];
                found[i] += part_found[i];
            }
            tau_before = optics.after;
        }
        assert_eq!(found, whole_found, "{name}: the same rays cross");
        for i in 0..r.n {
            let tol = 1e-5 * whole[i].abs().max(1.0);
            assert!(
                (sum[i] - whole[i]).abs() <= tol,
                "{name}: ray {i}: segments {} whole {}",
                sum[i],
                whole[i]
            );
        }
    }
}

/// A surface at 2 that lets a thousandth of the light through to a last
/// interval reaching 10,000 out: the expected depth moves by metres, the
/// median stays on the surface; an opaque interval crosses at its start.
#[test]
fn median_stays_on_the_surface_where_the_mean_is_pulled_out() {
    for (name, device) in devices(false) {
        // Posts 1, 2, 2.1, 10000: empty, a surface of optical depth ln(1000), the far end.
        let t = tensor(vec![1.0, 2.0, 2.1, 10_000.0], [1, 4], &device);
        let one = || tensor(vec![1.0], [1, 1], &device);
        let density = tensor(vec![0.0, (1000.0f32).ln() / 0.1, 1.0], [1, 3], &device);
        let w = vec(compute_weights(density.clone(), t.clone(), one()));
        let acc: f32 = w.iter().sum();
        let mids = [1.5f32, 2.05, 5001.05];
        let mean: f32 = w.iter().zip(mids).map(|(w, m)| w * m).sum::<f32>() / acc;
        assert!(mean > 6.0, "{name}: the mean is pulled out ({mean})");
        let median = vec(median_depth(
            density,
            t,
            one(),
            tensor(vec![mean], [1, 1], &device),
        ))[0];
        // Half the light is stopped after ln(2) / ln(1000) of the surface's 0.1.
        let want = 2.0 + 0.1 * (2.0f32).ln() / (1000.0f32).ln();
        assert!(
            (median - want).abs() < 1e-4,
            "{name}: median {median}, want {want}"
        );

        let t = tensor(vec![1.0, 3.0, 7.0], [1, 3], &device);
        let density = tensor(vec![0.0, 1e10], [1, 2], &device);
        let median = vec(median_depth(
            density,
            t,
            one(),
            tensor(vec![-1.0], [1, 1], &device),
        ))[0];
        assert!(
            (median - 3.0).abs() < 1e-5,
            "{name}: opaque interval crosses at its start ({median})"
        );
    }
}
