//! Mip-NeRF 360 math against f64 host references: the contraction (values,
//! C1 continuity at the unit sphere, finite-difference Jacobians, a
//! Monte-Carlo covariance of contracted samples, finiteness of values and
//! gradients at extreme norms) and the s-space round trips. The step
//! functions' tests are `stepfun.rs`'s.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

mod common;

use burn::tensor::{Device, Tensor};
use common::{assert_close, devices, tensor, vec};
use model::mip::cast_rays;
use model::unbounded::{
    cast_rays_contracted, contract, contract_gaussian, contract_jacobian, cov_diagonal,
    frustum_covariance, s_to_t, t_to_s,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

type V3 = [f64; 3];

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(1e-300..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn norm(x: V3) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

fn scaled(x: V3, s: f64) -> V3 {
    x.map(|v| v * s)
}

fn unit(rng: &mut ChaCha8Rng) -> V3 {
    let v = [normal(rng), normal(rng), normal(rng)];
    scaled(v, 1.0 / norm(v))
}

/// The points as they are after rounding to f32.
fn rounded(x: V3) -> V3 {
    x.map(|v| v as f32 as f64)
}

/// Host reference of the contraction.
fn contract64(x: V3) -> V3 {
    let r = norm(x);
    if r <= 1.0 {
        x
    } else {
        scaled(x, (2.0 - 1.0 / r) / r)
    }
}

/// Central finite differences of [`contract64`], `J[i][j] = d c_i / d x_j`.
fn fd_jacobian(x: V3) -> [V3; 3] {
    let h = 1e-6 * norm(x).max(1.0);
    let mut j = [[0.0; 3]; 3];
    for col in 0..3 {
        let (mut xp, mut xm) = (x, x);
        xp[col] += h;
        xm[col] -= h;
        let (cp, cm) = (contract64(xp), contract64(xm));
        for row in 0..3 {
            j[row][col] = (cp[row] - cm[row]) / (2.0 * h);
        }
    }
    j
}

/// `[1, n, 3]` tensor of points.
fn points(p: &[V3], device: &Device) -> Tensor<3> {
    let flat = p.iter().flatten().map(|&v| v as f32).collect();
    tensor(flat, [1, p.len(), 3], device)
}

fn to64(v: &[f32]) -> Vec<f64> {
    v.iter().map(|&x| x as f64).collect()
}

/// Inside the closed unit ball the contraction returns its input bit for
/// bit; outside it matches the f64 formula and stays within radius 2 (up to
/// f32 rounding of the components, `1e-6`; strictly below 2 up to
/// `|x| = 1e5`, where f32 can still tell).
#[test]
fn contraction_is_identity_inside_and_stays_within_radius_two() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut pts: Vec<V3> = (0..200)
        .map(|_| {
            let r = rng.random_range(0.0..1.0);
            scaled(unit(&mut rng), r)
        })
        .collect();
    pts.extend([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]);
    let inside = pts.len();
    for _ in 0..300 {
        let r = 10f64.powf(rng.random_range(0.001..12.0));
        pts.push(scaled(unit(&mut rng), r));
    }
    for (name, device) in devices(false) {
        let x = points(&pts, &device);
        let input = vec(x.clone());
        let got = vec(contract(x));
        assert_eq!(got[..3 * inside], input[..3 * inside], "{name}: identity");
        for p in inside..pts.len() {
            let c = &got[3 * p..3 * p + 3];
            let want = contract64(rounded(pts[p])).map(|v| v as f32);
            assert_close(c, &want, 1e-6, 1e-5, &format!("{name}: point {p}"));
            let n = norm([c[0] as f64, c[1] as f64, c[2] as f64]);
            assert!(
                n <= 2.0 + 1e-6,
                "{name}: |contract| = {n} for |x| = {}",
                norm(pts[p])
            );
            if norm(pts[p]) < 1e5 {
                assert!(
                    n < 2.0,
                    "{name}: |contract| = {n} for |x| = {}",
                    norm(pts[p])
                );
            }
        }
    }
}

/// Just inside and just outside the unit sphere (`|x| = 1 -+ 1e-4`) the
/// values differ by `2e-4` along the radius (slope 1 on both sides) and the
/// Jacobians agree to `5e-4` (both are the identity at the sphere; the
/// radial entry moves by `-2 (|x| - 1)` outside).
#[test]
fn contraction_is_c1_at_the_unit_sphere() {
    let delta = 1e-4;
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let dirs: Vec<V3> = (0..50).map(|_| unit(&mut rng)).collect();
    let inner: Vec<V3> = dirs.iter().map(|&u| scaled(u, 1.0 - delta)).collect();
    let outer: Vec<V3> = dirs.iter().map(|&u| scaled(u, 1.0 + delta)).collect();
    for (name, device) in devices(false) {
        let c_in = vec(contract(points(&inner, &device)));
        let c_out = vec(contract(points(&outer, &device)));
        let j_in = vec(contract_jacobian(points(&inner, &device)));
        let j_out = vec(contract_jacobian(points(&outer, &device)));
        for p in 0..dirs.len() {
            let step: f64 = (0..3)
                .map(|k| (c_out[3 * p + k] as f64 - c_in[3 * p + k] as f64).powi(2))
                .sum::<f64>()
                .sqrt();
            let slope = step / (2.0 * delta);
            assert!((slope - 1.0).abs() < 0.02, "{name}: slope {slope} at {p}");
            for e in 0..9 {
                let eye = if e % 4 == 0 { 1.0 } else { 0.0 };
                let (a, b) = (j_in[9 * p + e], j_out[9 * p + e]);
                assert!((a - b).abs() < 5e-4, "{name}: J jumps {a} -> {b} at {p}");
                assert!((b - eye).abs() < 5e-4, "{name}: J = {b} at the sphere");
            }
        }
    }
}

/// The Jacobian against central differences of the f64 contraction, at
/// 300 points inside (radius 0.02 to 0.99) and outside (1.01 to 1e3).
#[test]
fn jacobian_matches_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let pts: Vec<V3> = (0..300)
        .map(|i| {
            let r = if i % 2 == 0 {
                rng.random_range(0.02..0.99)
            } else {
                10f64.powf(rng.random_range(0.005..3.0))
            };
            rounded(scaled(unit(&mut rng), r))
        })
        .collect();
    let want: Vec<f32> = pts
        .iter()
        .flat_map(|&x| fd_jacobian(x).into_iter().flatten().map(|v| v as f32))
        .collect();
    for (name, device) in devices(false) {
        let got = vec(contract_jacobian(points(&pts, &device)));
        assert_close(&got, &want, 2e-6, 1e-4, name);
    }
}

/// One Gaussian case: mean, ray direction, along-axis and cross-axis std.
struct Case {
    mean: V3,
    dir: V3,
    sigma_t: f64,
    sigma_r: f64,
}

fn gaussian_cases(rng: &mut ChaCha8Rng) -> Vec<Case> {
    [0.5, 1.6, 3.0, 20.0, 1e3]
        .into_iter()
        .map(|r| Case {
            mean: rounded(scaled(unit(rng), r)),
            dir: rounded(scaled(unit(rng), 1.3)),
            sigma_t: 0.02 * r,
            sigma_r: 0.008 * r,
        })
        .collect()
}

/// Two unit vectors orthogonal to `d` and to each other.
fn orthonormal_complement(d: V3) -> (V3, V3) {
    let n = scaled(d, 1.0 / norm(d));
    let a = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let dot = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
    let e1 = [a[0] - dot * n[0], a[1] - dot * n[1], a[2] - dot * n[2]];
    let e1 = scaled(e1, 1.0 / norm(e1));
    let e2 = [
        n[1] * e1[2] - n[2] * e1[1],
        n[2] * e1[0] - n[0] * e1[2],
        n[0] * e1[1] - n[1] * e1[0],
    ];
    (e1, e2)
}

/// Sample covariance of the contracted samples of the case's Gaussian.
fn monte_carlo_cov(case: &Case, samples: usize, rng: &mut ChaCha8Rng) -> [f64; 9] {
    let dn = scaled(case.dir, 1.0 / norm(case.dir));
    let (e1, e2) = orthonormal_complement(case.dir);
    let xs: Vec<V3> = (0..samples)
        .map(|_| {
            let (z1, z2, z3) = (normal(rng), normal(rng), normal(rng));
            let x: V3 = std::array::from_fn(|k| {
                case.mean[k] + case.sigma_t * z1 * dn[k] + case.sigma_r * (z2 * e1[k] + z3 * e2[k])
            });
            contract64(x)
        })
        .collect();
    let mut mean = [0.0; 3];
    xs.iter()
        .for_each(|x| (0..3).for_each(|k| mean[k] += x[k] / samples as f64));
    let mut cov = [0.0; 9];
    for x in &xs {
        for i in 0..3 {
            for j in 0..3 {
                cov[3 * i + j] += (x[i] - mean[i]) * (x[j] - mean[j]) / (samples - 1) as f64;
            }
        }
    }
    cov
}

fn frobenius(a: &[f64]) -> f64 {
    a.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn rel_error(a: &[f64], b: &[f64]) -> f64 {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    frobenius(&d) / frobenius(b)
}

/// The linearised covariance against the covariance of 200k contracted
/// samples of small frustum Gaussians (std 2% / 0.8% of the distance to the
/// origin, at radii 0.5 to 1e3): within 1.5% in Frobenius norm (the sampling
/// error is about 0.5%), while the uncontracted covariance is off by more
/// than 30% outside the unit ball. The frustum covariance matches its
/// formula, and the closed form matches `J cov J^T` with the tensor Jacobian.
#[test]
fn linearised_covariance_matches_monte_carlo() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let cases = gaussian_cases(&mut rng);
    let mc: Vec<[f64; 9]> = cases
        .iter()
        .map(|c| monte_carlo_cov(c, 200_000, &mut rng))
        .collect();
    for (name, device) in devices(false) {
        let k = cases.len();
        let dirs = cases.iter().flat_map(|c| c.dir).map(|v| v as f32).collect();
        let t_var = cases
            .iter()
            .map(|c| (c.sigma_t / norm(c.dir)).powi(2) as f32)
            .collect();
        let r_var = cases.iter().map(|c| c.sigma_r.powi(2) as f32).collect();
        let means: Vec<V3> = cases.iter().map(|c| c.mean).collect();
        let mean = points(&means, &device).reshape([k, 1, 3]);
        let cov = frustum_covariance(
            tensor(dirs, [k, 3], &device),
            tensor(t_var, [k, 1], &device),
            tensor(r_var, [k, 1], &device),
        );
        let (c_mean, c_cov) = contract_gaussian(mean.clone(), cov.clone());
        let (cov_in, c_mean, c_cov) = (to64(&vec(cov)), vec(c_mean), to64(&vec(c_cov)));
        let jac = to64(&vec(contract_jacobian(mean)));
        for (i, case) in cases.iter().enumerate() {
            let what = format!("{name}: radius {}", norm(case.mean));
            let sigma_in = &cov_in[9 * i..9 * i + 9];
            let (e1, e2) = orthonormal_complement(case.dir);
            let dn = scaled(case.dir, 1.0 / norm(case.dir));
            let formula: Vec<f64> = (0..9)
                .map(|e| {
                    let (a, b) = (e / 3, e % 3);
                    case.sigma_t.powi(2) * dn[a] * dn[b]
                        + case.sigma_r.powi(2) * (e1[a] * e1[b] + e2[a] * e2[b])
                })
                .collect();
            assert!(rel_error(sigma_in, &formula) < 1e-5, "{what}: frustum cov");
            let got = &c_cov[9 * i..9 * i + 9];
            let j = &jac[9 * i..9 * i + 9];
            let jsj: Vec<f64> = (0..9)
                .map(|e| {
                    let (a, b) = (e / 3, e % 3);
                    let mut s = 0.0;
                    for p in 0..3 {
                        for q in 0..3 {
                            s += j[3 * a + p] * sigma_in[3 * p + q] * j[3 * b + q];
                        }
                    }
                    s
                })
                .collect();
            assert!(
                rel_error(got, &jsj) < 1e-4,
                "{what}: closed form vs J cov J^T"
            );
            let err = rel_error(got, &mc[i]);
            assert!(err < 0.015, "{what}: relative error {err} vs Monte Carlo");
            if norm(case.mean) > 1.0 {
                let plain = rel_error(sigma_in, &mc[i]);
                assert!(plain > 0.3, "{what}: uncontracted is {plain} off");
            }
            let want = contract64(case.mean).map(|v| v as f32);
            assert_close(&c_mean[3 * i..3 * i + 3], &want, 1e-6, 1e-5, &what);
        }
    }
}

/// Values and gradients (of the points and the covariances) of the
/// contraction, its Jacobian and the pushed Gaussian are finite at
/// `|x| = 0, 1e-12, 1, 1e6, 1e12`, along an oblique and an axis direction.
#[test]
fn contraction_is_finite_at_extreme_norms() {
    let norms = [0.0, 1e-12, 1.0, 1e6, 1e12];
    let dirs = [[1.0 / 3.0, 2.0 / 3.0, -2.0 / 3.0], [0.0, 0.0, -1.0]];
    let pts: Vec<V3> = dirs
        .iter()
        .flat_map(|&d| norms.map(|r| scaled(d, r)))
        .collect();
    let n = pts.len();
    let sigma = [2e-4f32, 5e-5, 0.0, 5e-5, 3e-4, -1e-5, 0.0, -1e-5, 1e-4];
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let finite = |v: Vec<f32>, what: &str| {
            assert!(v.iter().all(|x| x.is_finite()), "{name}: {what} {v:?}");
        };
        let x = points(&pts, &device).require_grad();
        let cov = tensor(sigma.repeat(n), [1, n, 3, 3], &device).require_grad();
        let c = contract(x.clone());
        finite(vec(c.clone()), "contract");
        finite(vec(x.grad(&c.sum().backward()).unwrap()), "d contract");
        let j = contract_jacobian(x.clone());
        finite(vec(j.clone()), "jacobian");
        finite(vec(x.grad(&j.sum().backward()).unwrap()), "d jacobian");
        let (m, s) = contract_gaussian(x.clone(), cov.clone());
        finite(vec(m.clone()), "gaussian mean");
        finite(vec(s.clone()), "gaussian cov");
        let grads = m.sum().add(s.sum().mul_scalar(1e3)).backward();
        finite(vec(x.grad(&grads).unwrap()), "d gaussian / d mean");
        finite(vec(cov.grad(&grads).unwrap()), "d gaussian / d cov");
        let far = vec(contract(points(&[scaled(dirs[0], 1e12)], &device)));
        let r = norm([far[0] as f64, far[1] as f64, far[2] as f64]);
        assert!((r - 2.0).abs() < 1e-6, "{name}: |contract(1e12)| = {r}");
    }
}

/// Rays entirely inside the unit ball: the contracted casting is Mip-NeRF's
/// own (`mip::cast_rays`, diagonal covariance); rays reaching `t = 1e6`
/// stay finite and inside radius 2.
#[test]
fn contracted_casting_reduces_to_mip_inside_the_ball() {
    for (name, device) in devices(false) {
        let t_inside: Vec<f32> = (0..=8).map(|i| 0.1 + 0.05 * i as f32).collect();
        let origins = tensor(vec![0.1, -0.2, -0.3, 0.0, 0.2, 0.1], [2, 3], &device);
        let dirs = tensor(vec![0.3, 0.5, 0.8, -0.6, 0.2, 0.4], [2, 3], &device);
        let radii = tensor(vec![0.01, 0.02], [2, 1], &device);
        let t = tensor(t_inside.repeat(2), [2, 9], &device);
        let plain = cast_rays(t.clone(), origins.clone(), dirs.clone(), radii.clone());
        let contracted = cast_rays_contracted(t, origins.clone(), dirs.clone(), radii.clone());
        let mean = vec(plain.mean);
        assert!(
            mean.chunks(3)
                .all(|p| p.iter().map(|v| v * v).sum::<f32>() < 1.0)
        );
        assert_close(&vec(contracted.mean), &mean, 1e-7, 1e-6, name);
        assert_close(
            &vec(contracted.cov_diag),
            &vec(plain.cov_diag),
            1e-12,
            1e-5,
            name,
        );
        let t_far: Vec<f32> = (0..=8).map(|i| 10f32.powi(i - 2)).collect();
        let far = cast_rays_contracted(
            tensor(t_far.repeat(2), [2, 9], &device),
            origins,
            dirs,
            radii,
        );
        let (mean, var) = (vec(far.mean), vec(far.cov_diag));
        assert!(mean.iter().chain(&var).all(|v| v.is_finite()), "{name}");
        assert!(
            mean.chunks(3)
                .all(|p| p.iter().map(|v| v * v).sum::<f32>() <= 4.0)
        );
        assert!(var.iter().all(|&v| v >= -1e-9), "{name}: {var:?}");
    }
}

/// `cov_diagonal` reads the diagonal of a full `[.., 3, 3]` covariance.
#[test]
fn covariance_diagonal_reads_the_diagonal() {
    for (name, device) in devices(false) {
        let m: Vec<f32> = (0..18).map(|v| v as f32).collect();
        let got = vec(cov_diagonal(tensor(m, [1, 2, 3, 3], &device)));
        assert_eq!(got, vec![0.0, 4.0, 8.0, 9.0, 13.0, 17.0], "{name}");
    }
}

/// Per ray: `near`, `far`, and sorted distances from `near` to `far`.
fn spacing_rays(rng: &mut ChaCha8Rng, samples: usize) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let (mut near, mut far, mut t) = (Vec::new(), Vec::new(), Vec::new());
    for &f in &[2.0f64, 6.0, 100.0, 1e4, 1e10] {
        let n: f64 = rng.random_range(0.05..1.0);
        let f = n * f;
        let mut ts: Vec<f64> = (0..samples - 2)
            .map(|_| n * (f / n).powf(rng.random_range(0.0..1.0)))
            .collect();
        ts.extend([n, f]);
        ts.sort_by(f64::total_cmp);
        near.push(n as f32);
        far.push(f as f32);
        t.extend(ts.iter().map(|&v| v as f32));
    }
    (near, far, t)
}

/// `s(near) = 0` and `s(far) = 1` exactly; `s` is non-decreasing in `t`,
/// matches the f64 formula and maps back to `t` (`t -> s -> t` within
/// `1e-4` relative where `t <= 100 near`: beyond that, f32 `s` cannot
/// resolve `t`; `s -> t -> s` within `1e-6` everywhere). Finite values and
/// gradients with `far` up to `1e10`.
#[test]
fn s_space_round_trips_and_hits_the_ends() {
    let samples = 64;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (near, far, t) = spacing_rays(&mut rng, samples);
    let rays = near.len();
    let s_grid: Vec<f32> = (0..samples)
        .map(|i| i as f32 / (samples - 1) as f32)
        .collect();
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let n_t = tensor(near.clone(), [rays, 1], &device);
        let f_t = tensor(far.clone(), [rays, 1], &device);
        let t_t = tensor(t.clone(), [rays, samples], &device).require_grad();
        let s = t_to_s(t_t.clone(), n_t.clone(), f_t.clone());
        let back = vec(s_to_t(s.clone(), n_t.clone(), f_t.clone()));
        let sv = vec(s.clone());
        let grad = vec(t_t.grad(&s.sum().backward()).unwrap());
        assert!(grad.iter().all(|g| g.is_finite()), "{name}: ds/dt");
        for r in 0..rays {
            let row = &sv[r * samples..(r + 1) * samples];
            assert_eq!((row[0], row[samples - 1]), (0.0, 1.0), "{name}: ends");
            assert!(row.windows(2).all(|w| w[0] <= w[1]), "{name}: monotone");
            let (n, f) = (near[r] as f64, far[r] as f64);
            for i in 0..samples {
                let tv = t[r * samples + i] as f64;
                let want = (1.0 / tv - 1.0 / n) / (1.0 / f - 1.0 / n);
                assert!((row[i] as f64 - want).abs() < 1e-6, "{name}: s {}", row[i]);
                if tv <= 100.0 * n {
                    let b = back[r * samples + i] as f64;
                    assert!((b - tv).abs() <= 1e-4 * tv, "{name}: t {tv} -> {b}");
                }
            }
        }
        let s_in = tensor(s_grid.repeat(rays), [rays, samples], &device).require_grad();
        let t_back = s_to_t(s_in.clone(), n_t.clone(), f_t.clone());
        let tv = vec(t_back.clone());
        let grad = vec(s_in.grad(&t_back.clone().sum().backward()).unwrap());
        assert!(
            grad.iter().chain(&tv).all(|g| g.is_finite()),
            "{name}: dt/ds"
        );
        for r in 0..rays {
            let row = &tv[r * samples..(r + 1) * samples];
            assert!((row[0] / near[r] - 1.0).abs() < 1e-6, "{name}: t(0)");
            assert!(
                (row[samples - 1] / far[r] - 1.0).abs() < 1e-6,
                "{name}: t(1)"
            );
        }
        let s_again = vec(t_to_s(t_back, n_t, f_t));
        assert_close(&s_again, &s_grid.repeat(rays), 1e-6, 0.0, name);
    }
}
