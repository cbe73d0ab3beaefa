//! Mip-NeRF encodings against independent references: Monte Carlo over the
//! conical frustum, the closed-form (naive) frustum moments in f64, and direct
//! evaluation of the encodings.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{assert_close, devices, tensor, vec};
use model::mip::{cast_rays, conical_frustum_to_gaussian, integrated_pos_enc, pos_enc, reference};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Stable and closed-form moments agree in f64 where the closed form is
/// well conditioned.
#[test]
fn frustum_stable_matches_closed_form_f64() {
    let cases = [
        (1.0, 2.0, 0.1),
        (0.5, 0.6, 0.003),
        (3.0, 3.5, 1.0),
        (0.0, 1.0, 0.2),
        (10.0, 10.5, 0.01),
    ];
    for (t0, t1, r) in cases {
        let s = reference::frustum_stable(t0, t1, r);
        let n = reference::frustum_naive(t0, t1, r);
        for (a, b, what) in [
            (s.0, n.0, "t_mean"),
            (s.1, n.1, "t_var"),
            (s.2, n.2, "r_var"),
        ] {
            assert!(
                (a - b).abs() <= 1e-9 * b.abs().max(1e-12),
                "{what} at ({t0}, {t1}, {r}): stable {a} vs naive {b}"
            );
        }
    }
}

/// The f32 tensor version matches the f64 reference, including thin intervals
/// far away where the closed form would cancel catastrophically in f32.
#[test]
fn frustum_tensor_matches_f64_reference() {
    let cases = [
        (1.0f64, 2.0f64, 0.1f64),
        (2.0, 2.00006, 1.5e-5),
        (1000.0, 1000.001, 0.001),
        (0.0, 0.0, 0.1),
        (5.0, 5.0, 0.2),
    ];
    for (name, device) in devices(true) {
        let n = cases.len();
        let t0 = tensor(cases.iter().map(|c| c.0 as f32).collect(), [n, 1], &device);
        let t1 = tensor(cases.iter().map(|c| c.1 as f32).collect(), [n, 1], &device);
        let r = tensor(cases.iter().map(|c| c.2 as f32).collect(), [n, 1], &device);
        let (m, tv, rv) = conical_frustum_to_gaussian(t0, t1, r);
        let (m, tv, rv) = (vec(m), vec(tv), vec(rv));
        for (i, &(a, b, rad)) in cases.iter().enumerate() {
            // Reference on the f32-rounded inputs.
            let (a, b, rad) = (a as f32 as f64, b as f32 as f64, rad as f32 as f64);
            let (em, etv, erv) = if a == b && a == 0.0 {
                (0.0, 0.0, 0.0)
            } else {
                reference::frustum_stable(a, b, rad)
            };
            assert!(
                (m[i] as f64 - em).abs() <= 1e-6 * em.abs() + 1e-9,
                "{name} t_mean {i}"
            );
            assert!(
                (tv[i] as f64 - etv).abs() <= 1e-3 * etv.abs() + 1e-12,
                "{name} t_var {i}: {} vs {etv}",
                tv[i]
            );
            assert!(
                (rv[i] as f64 - erv).abs() <= 1e-4 * erv.abs() + 1e-15,
                "{name} r_var {i}"
            );
        }
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// Monte-Carlo IPE: the mean of `sin(2^l x_k)` and `cos(2^l x_k)` over points
/// drawn uniformly inside the conical frustum (cone radius `r t` around
/// `o + t d`, `t` in `[t0, t1]`), in the same layout as the model's IPE.
#[allow(clippy::too_many_arguments)]
fn monte_carlo_ipe(
    o: [f64; 3],
    d: [f64; 3],
    t0: f64,
    t1: f64,
    r: f64,
    min_deg: usize,
    max_deg: usize,
    n: usize,
) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let e1 = unit(cross(
        d,
        if d[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        },
    ));
    let e2 = unit(cross(d, e1));
    let levels = max_deg - min_deg;
    let mut acc = vec![0.0f64; 6 * levels];
    let (c0, c1) = (t0.powi(3), t1.powi(3));
    for _ in 0..n {
        // Volume density along t is proportional to t^2 (cross-section area).
        let u: f64 = rng.random();
        let t = (c0 + u * (c1 - c0)).cbrt();
        let rho = r * t * rng.random::<f64>().sqrt();
        let th = rng.random::<f64>() * std::f64::consts::TAU;
        let (c, s) = (th.cos(), th.sin());
        let x: [f64; 3] = std::array::from_fn(|k| o[k] + t * d[k] + rho * (c * e1[k] + s * e2[k]));
        for l in 0..levels {
            let sc = 2f64.powi((min_deg + l) as i32);
            for k in 0..3 {
                acc[3 * l + k] += (sc * x[k]).sin();
                acc[3 * levels + 3 * l + k] += (sc * x[k]).cos();
            }
        }
    }
    acc.iter().map(|v| v / n as f64).collect()
}

/// The IPE of the frustum Gaussian equals the Monte-Carlo expectation over
/// the frustum. Cases keep `2^l sigma <= ~0.7`, where the Gaussian
/// approximation of the frustum is within about 0.015 of the true expectation,
/// while the variance factor is still far from 1 (so a wrong variance fails).
#[test]
fn ipe_matches_monte_carlo_over_frustum() {
    let o = [0.1, 0.2, -0.3];
    let d = [0.3, -0.5, 1.0];
    // (t0, t1, radius, min_deg, max_deg, tolerance)
    let cases = [
        (1.0, 1.5, 0.05, 0usize, 3usize, 0.02f64),
        (3.0, 3.0034, 6e-4, 8, 10, 0.025),
        (2.0, 2.00006, 1.5e-5, 15, 16, 0.05),
        (0.5, 0.9, 0.3, 0, 3, 0.02),
    ];
    for (name, device) in devices(false) {
        for &(t0, t1, r, lo, hi, tol) in &cases {
            let mc = monte_carlo_ipe(o, d, t0, t1, r, lo, hi, 200_000);
            let t = tensor(vec![t0 as f32, t1 as f32], [1, 2], &device);
            let g = cast_rays(
                t,
                tensor(o.iter().map(|&v| v as f32).collect(), [1, 3], &device),
                tensor(d.iter().map(|&v| v as f32).collect(), [1, 3], &device),
                tensor(vec![r as f32], [1, 1], &device),
            );
            let ipe = vec(integrated_pos_enc(g.mean, g.cov_diag.clone(), lo, hi));
            assert_eq!(ipe.len(), 6 * (hi - lo));
            // The case must exercise the variance: some attenuation well below 1.
            let cov = vec(g.cov_diag);
            let top = 4f64.powi(hi as i32 - 1);
            let max_att = cov
                .iter()
                .map(|&c| (-0.5 * top * c as f64).exp())
                .fold(1.0, f64::min);
            assert!(
                max_att < 0.95,
                "case ({t0}, {t1}, {r}) does not test the variance"
            );
            for (i, (a, b)) in ipe.iter().zip(&mc).enumerate() {
                assert!(
                    (*a as f64 - b).abs() <= tol,
                    "{name}: ({t0}, {t1}, {r}, deg {lo}..{hi}) component {i}: ipe {a} vs monte carlo {b}"
                );
            }
        }
    }
}

/// IPE and PE against direct per-element evaluation, including the ordering
/// (sin block then cos block, degree-major) and the identity prefix.
#[test]
fn encodings_match_direct_evaluation() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 5;
    let mean: Vec<f32> = (0..3 * n).map(|_| rng.random_range(-3.0..3.0)).collect();
    let cov: Vec<f32> = (0..3 * n).map(|_| rng.random_range(0.0..0.01)).collect();
    for (name, device) in devices(true) {
        let (lo, hi) = (1, 5);
        let ipe = vec(integrated_pos_enc(
            tensor(mean.clone(), [n, 3], &device),
            tensor(cov.clone(), [n, 3], &device),
            lo,
            hi,
        ));
        let pe = vec(pos_enc(tensor(mean.clone(), [n, 3], &device), 0, 4, true));
        let levels = hi - lo;
        let mut want_ipe = Vec::new();
        let mut want_pe = Vec::new();
        for p in 0..n {
            let x = &mean[3 * p..3 * p + 3];
            let c = &cov[3 * p..3 * p + 3];
            let mut sin = Vec::new();
            let mut cos = Vec::new();
            for l in lo..hi {
                let s = 2f64.powi(l as i32);
                for k in 0..3 {
                    let att = (-0.5 * s * s * c[k] as f64).exp();
                    sin.push((att * (s * x[k] as f64).sin()) as f32);
                    cos.push((att * (s * x[k] as f64).cos()) as f32);
                }
            }
            want_ipe.extend(sin);
            want_ipe.extend(cos);
            want_pe.extend_from_slice(x);
            let mut sin = Vec::new();
            let mut cos = Vec::new();
            for l in 0..4 {
                let s = 2f64.powi(l);
                for &xk in x {
                    sin.push((s * xk as f64).sin() as f32);
                    cos.push((s * xk as f64).cos() as f32);
                }
            }
            want_pe.extend(sin);
            want_pe.extend(cos);
        }
        assert_eq!(ipe.len(), n * 6 * levels);
        assert_close(&ipe, &want_ipe, 2e-5, 0.0, &format!("{name} ipe"));
        assert_close(&pe, &want_pe, 2e-5, 0.0, &format!("{name} pe"));
    }
}

/// At the maximum degree, tiny variances give the plain sinusoid (finite,
/// bounded) and huge variances give exactly zero.
#[test]
fn ipe_extreme_variances_at_max_degree() {
    for (name, device) in devices(true) {
        let mean = vec![3.0f32, -3.0, 1e-3, 0.0, 2.0, -1.0];
        let m = tensor(mean.clone(), [2, 3], &device);
        let tiny = vec(integrated_pos_enc(
            m.clone(),
            m.zeros_like().add_scalar(1e-30),
            0,
            16,
        ));
        let huge = vec(integrated_pos_enc(
            m.clone(),
            m.zeros_like().add_scalar(1e10),
            0,
            16,
        ));
        let inf = vec(integrated_pos_enc(
            m.clone(),
            m.zeros_like().add_scalar(f32::MAX),
            0,
            16,
        ));
        assert!(
            tiny.iter().all(|v| v.is_finite() && v.abs() <= 1.0 + 1e-6),
            "{name}"
        );
        assert!(
            huge.iter().all(|&v| v == 0.0),
            "{name}: huge variance must integrate to 0"
        );
        assert!(
            inf.iter().all(|&v| v == 0.0),
            "{name}: f32::MAX variance must integrate to 0"
        );
        // Degree 0: sin(x) itself with negligible variance.
        assert!((tiny[0] - 3.0f32.sin()).abs() < 1e-5, "{name}");
        // Degree 15 sin of 2^15 * x, checked in f64 on the f32 product.
        let y = (32768.0f32 * -3.0f32) as f64;
        assert!((tiny[3 * 15 + 1] as f64 - y.sin()).abs() < 2e-2, "{name}");
    }
}

/// The frustums' means alone (what a field that reads no covariance
/// takes) are the means of the Gaussians with their covariances, bit for
/// bit: in a box, and contracted in an unbounded scene, for rays inside
/// the ball and rays reaching far past it.
#[test]
fn frustum_means_are_the_gaussians_means_bit_for_bit() {
    use model::mip::frustum_means;
    use model::unbounded::UnboundedConfig;
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    for (name, device) in devices(false) {
        let rays = 5;
        let posts = 9usize;
        let origins: Vec<f32> = (0..rays * 3).map(|_| rng.random_range(-1.0..1.0)).collect();
        let dirs: Vec<f32> = (0..rays * 3).map(|_| rng.random_range(-1.0..1.0)).collect();
        let radii: Vec<f32> = (0..rays).map(|_| rng.random_range(1e-3..1e-2)).collect();
        let t: Vec<f32> = (0..rays)
            .flat_map(|_| (0..posts).map(|i| 0.05 * 1.8f32.powi(i as i32)))
            .collect();
        let (o, d) = (
            tensor(origins, [rays, 3], &device),
            tensor(dirs, [rays, 3], &device),
        );
        let (r, t) = (
            tensor(radii, [rays, 1], &device),
            tensor(t, [rays, posts], &device),
        );
        let boxed = cast_rays(t.clone(), o.clone(), d.clone(), r.clone());
        let means = frustum_means(t.clone(), o.clone(), d.clone());
        assert_eq!(vec(means), vec(boxed.mean), "{name}: box");
        let unbounded = UnboundedConfig::new(1.5);
        let contracted = unbounded.frustums(t.clone(), o.clone(), d.clone(), r);
        let means = vec(unbounded.frustum_means(t, o, d));
        assert!(
            means
                .chunks(3)
                .any(|p| p.iter().map(|v| v * v).sum::<f32>() > 2.5)
        );
        assert_eq!(means, vec(contracted.mean), "{name}: unbounded");
    }
}
