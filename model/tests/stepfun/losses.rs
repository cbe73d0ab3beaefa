//! The interlevel and distortion losses against brute-force f64 evaluations
//! of their definitions (exact interval overlaps, the double integral over
//! every pair of intervals), their gradients, and the proposal-weight
//! dilation and annealing.

use super::{
    anneal_exponent, anneal_weights, assert_close, devices, distortion_loss, interlevel_loss,
    max_dilate_weights, max_dilate_weights_host, tensor, vec,
};
use burn::tensor::{Device, Tensor};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Step functions of `rays` rays with `n` intervals each, flattened
/// row-major, in f32 (the references read the same f32 values).
struct Steps {
    rays: usize,
    n: usize,
    t: Vec<f32>,
    w: Vec<f32>,
}

impl Steps {
    /// Random sorted ends spanning a random `[lo, hi]` of `range` per ray
    /// (the ends included) and random weights summing to 0.5 to 1.
    fn random(rng: &mut ChaCha8Rng, rays: usize, n: usize, range: (f64, f64)) -> Self {
        let (mut t, mut w) = (Vec::new(), Vec::new());
        for _ in 0..rays {
            let lo = rng.random_range(range.0..range.0 + 0.25 * (range.1 - range.0));
            let hi = rng.random_range(range.1 - 0.25 * (range.1 - range.0)..range.1);
            let gaps: Vec<f64> = (0..n).map(|_| rng.random_range(0.2..1.0)).collect();
            let total: f64 = gaps.iter().sum();
            let mut acc = 0.0;
            t.push(lo as f32);
            for g in &gaps[..n - 1] {
                acc += g;
                t.push((lo + (hi - lo) * acc / total) as f32);
            }
            t.push(hi as f32);
            let raw: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..1.0)).collect();
            let scale = rng.random_range(0.5..1.0) / raw.iter().sum::<f64>();
            w.extend(raw.iter().map(|v| (v * scale) as f32));
        }
        Steps { rays, n, t, w }
    }

    fn t_row(&self, r: usize) -> Vec<f64> {
        self.t[r * (self.n + 1)..(r + 1) * (self.n + 1)]
            .iter()
            .map(|&v| v as f64)
            .collect()
    }

    fn w_row(&self, r: usize) -> Vec<f64> {
        self.w[r * self.n..(r + 1) * self.n]
            .iter()
            .map(|&v| v as f64)
            .collect()
    }

    fn tensors(&self, device: &Device) -> (Tensor<2>, Tensor<2>) {
        (
            tensor(self.t.clone(), [self.rays, self.n + 1], device),
            tensor(self.w.clone(), [self.rays, self.n], device),
        )
    }
}

/// Whether `[a0, a1]` and `[b0, b1]` overlap in an interval of positive
/// length.
fn overlaps(a0: f64, a1: f64, b0: f64, b1: f64) -> bool {
    a0 < b1 && a1 > b0
}

/// The interlevel loss by its definition: per NeRF interval, the proposal
/// weight of every proposal interval overlapping it, with `env_w` the
/// proposal weights (flattened, `[rays, m]`).
fn interlevel64(nerf: &Steps, env: &Steps, env_w: &[f64]) -> f64 {
    let eps = f32::EPSILON as f64;
    let mut total = 0.0;
    for r in 0..nerf.rays {
        let (t, w, te) = (nerf.t_row(r), nerf.w_row(r), env.t_row(r));
        for k in 0..nerf.n {
            let outer: f64 = (0..env.n)
                .filter(|&j| overlaps(te[j], te[j + 1], t[k], t[k + 1]))
                .map(|j| env_w[r * env.n + j])
                .sum();
            total += (w[k] - outer).max(0.0).powi(2) / (w[k] + eps);
        }
    }
    total / nerf.rays as f64
}

/// `int int |x - y|` over `[a, b] x [c, d]`, from the antiderivative
/// `G(x, y) = |x - y|^3 / 6` (`d^2 G / dx dy = -|x - y|`); holds for
/// overlapping and identical intervals alike.
fn abs_diff_integral(a: f64, b: f64, c: f64, d: f64) -> f64 {
    let g = |x: f64, y: f64| (x - y).abs().powi(3) / 6.0;
    g(b, c) + g(a, d) - g(b, d) - g(a, c)
}

/// The distortion loss as the double integral of `w(s) w(s') |s - s'|`
/// over every pair of intervals (the density of interval `i` is
/// `w_i / (s_{i+1} - s_i)`), including each interval with itself.
fn distortion64(s: &[f64], w: &[f64], rays: usize, n: usize) -> f64 {
    let mut total = 0.0;
    for r in 0..rays {
        let s = &s[r * (n + 1)..(r + 1) * (n + 1)];
        let w = &w[r * n..(r + 1) * n];
        for i in 0..n {
            for j in 0..n {
                let (pi, pj) = (w[i] / (s[i + 1] - s[i]), w[j] / (s[j + 1] - s[j]));
                total += pi * pj * abs_diff_integral(s[i], s[i + 1], s[j], s[j + 1]);
            }
        }
    }
    total / rays as f64
}

fn to64(v: &[f32]) -> Vec<f64> {
    v.iter().map(|&x| x as f64).collect()
}

/// A proposal on its own grid whose every interval carries the largest
/// NeRF weight it overlaps bounds the NeRF histogram: loss exactly 0, as
/// for the NeRF histogram itself. Zeroing the proposal over the heaviest
/// NeRF interval of each ray makes the loss positive, as the brute force.
#[test]
fn interlevel_loss_vanishes_for_bounding_proposals() {
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let nerf = Steps::random(&mut rng, 4, 16, (0.0, 1.0));
    let mut env = Steps::random(&mut rng, 4, 11, (0.0, 1.0));
    // Same span as the NeRF rays, so every NeRF interval is covered.
    for r in 0..4 {
        env.t[r * 12] = nerf.t[r * 17];
        env.t[r * 12 + 11] = nerf.t[r * 17 + 16];
    }
    let mut missing = Vec::new();
    for r in 0..4 {
        let (t, w, te) = (nerf.t_row(r), nerf.w_row(r), env.t_row(r));
        let heaviest = (0..16).max_by(|&a, &b| w[a].total_cmp(&w[b])).unwrap();
        for j in 0..11 {
            let cover = (0..16)
                .filter(|&k| overlaps(te[j], te[j + 1], t[k], t[k + 1]))
                .map(|k| w[k])
                .fold(0.0, f64::max);
            env.w[r * 11 + j] = cover as f32;
            let hit = overlaps(te[j], te[j + 1], t[heaviest], t[heaviest + 1]);
            missing.push(if hit { 0.0 } else { cover });
        }
    }
    let want_missing = interlevel64(&nerf, &env, &missing);
    assert!(
        want_missing > 0.01,
        "the test case misses mass: {want_missing}"
    );
    for (name, device) in devices(false) {
        let (t, w) = nerf.tensors(&device);
        let (te, we) = env.tensors(&device);
        let same = vec(interlevel_loss(t.clone(), w.clone(), t.clone(), w.clone()));
        assert_eq!(same, vec![0.0], "{name}: identical histograms");
        let bound = vec(interlevel_loss(t.clone(), w.clone(), te.clone(), we));
        assert_eq!(bound, vec![0.0], "{name}: bounding proposal");
        let missing = missing.iter().map(|&v| v as f32).collect();
        let got = vec(interlevel_loss(t, w, te, tensor(missing, [4, 11], &device)));
        assert_close(&got, &[want_missing as f32], 1e-7, 1e-4, name);
    }
}

/// Random NeRF and proposal histograms over different, partly overlapping
/// spans (so some NeRF intervals lie outside the proposal): the loss equals
/// the brute-force evaluation with exact interval overlaps.
#[test]
fn interlevel_loss_matches_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let nerf = Steps::random(&mut rng, 6, 24, (0.0, 1.0));
    let env = Steps::random(&mut rng, 6, 15, (-0.1, 0.9));
    let want = interlevel64(&nerf, &env, &to64(&env.w));
    assert!(want > 0.01, "random histograms miss mass: {want}");
    for (name, device) in devices(false) {
        let (t, w) = nerf.tensors(&device);
        let (te, we) = env.tensors(&device);
        let got = vec(interlevel_loss(t, w, te, we));
        assert_close(&got, &[want as f32], 1e-7, 1e-4, name);
    }
}

/// The gradient reaches the proposal weights, equal to central differences
/// of the brute force, and none of the NeRF side or the interval ends.
#[test]
fn interlevel_gradient_reaches_only_the_proposal_weights() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let nerf = Steps::random(&mut rng, 3, 12, (0.0, 1.0));
    let env = Steps::random(&mut rng, 3, 9, (0.0, 1.0));
    let base = to64(&env.w);
    let h = 1e-6;
    let fd: Vec<f32> = (0..base.len())
        .map(|i| {
            let (mut p, mut m) = (base.clone(), base.clone());
            p[i] += h;
            m[i] -= h;
            ((interlevel64(&nerf, &env, &p) - interlevel64(&nerf, &env, &m)) / (2.0 * h)) as f32
        })
        .collect();
    assert!(fd.iter().any(|g| g.abs() > 1e-3), "the case has a gradient");
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let (t, w) = nerf.tensors(&device);
        let (te, we) = env.tensors(&device);
        let (t, w) = (t.require_grad(), w.require_grad());
        let (te, we) = (te.require_grad(), we.require_grad());
        let grads = interlevel_loss(t.clone(), w.clone(), te.clone(), we.clone()).backward();
        assert_close(
            &vec(we.grad(&grads).expect("proposal gradient")),
            &fd,
            1e-5,
            1e-3,
            name,
        );
        for (what, x) in [("t", t), ("w", w), ("t_env", te)] {
            let g = x.grad(&grads).map(vec).unwrap_or_default();
            assert!(g.iter().all(|&v| v == 0.0), "{name}: gradient on {what}");
        }
    }
}

/// The `O(n)` distortion loss equals the double integral over all pairs of
/// intervals, on random histograms and on two cases by hand (a unit mass
/// spread over `[0, 1]`: `1/3`; two halves on `[0, 0.1]` and `[0.9, 1]`:
/// `2 (1/4) 0.9 + 2 (1/3) (1/4) 0.1`).
#[test]
fn distortion_loss_matches_the_double_integral() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let steps = Steps::random(&mut rng, 6, 32, (0.0, 1.0));
    let want = distortion64(&to64(&steps.t), &to64(&steps.w), 6, 32);
    let two_halves = 2.0 * 0.25 * 0.9 + 2.0 * 0.25 * 0.1 / 3.0;
    assert!((distortion64(&[0.0, 1.0], &[1.0], 1, 1) - 1.0 / 3.0).abs() < 1e-12);
    let s2 = [0.0, 0.1, 0.9, 1.0];
    assert!((distortion64(&s2, &[0.5, 0.0, 0.5], 1, 3) - two_halves).abs() < 1e-12);
    for (name, device) in devices(false) {
        let (s, w) = steps.tensors(&device);
        assert_close(
            &vec(distortion_loss(s, w)),
            &[want as f32],
            1e-7,
            1e-5,
            name,
        );
        let one = distortion_loss(
            tensor(vec![0.0, 1.0], [1, 2], &device),
            tensor(vec![1.0], [1, 1], &device),
        );
        assert_close(&vec(one), &[1.0 / 3.0], 1e-7, 1e-6, name);
        let halves = distortion_loss(
            tensor(s2.map(|v| v as f32).to_vec(), [1, 4], &device),
            tensor(vec![0.5, 0.0, 0.5], [1, 3], &device),
        );
        assert_close(&vec(halves), &[two_halves as f32], 1e-7, 1e-5, name);
    }
}

/// The gradient of the distortion loss in the weights and in every interval
/// end against central differences of the double integral.
#[test]
fn distortion_gradient_matches_finite_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let (rays, n) = (3, 10);
    let steps = Steps::random(&mut rng, rays, n, (0.0, 1.0));
    let (s0, w0) = (to64(&steps.t), to64(&steps.w));
    let h = 1e-6;
    let fd = |on_s: bool, i: usize| {
        let eval = |d: f64| {
            let (mut s, mut w) = (s0.clone(), w0.clone());
            if on_s {
                s[i] += d;
            } else {
                w[i] += d;
            }
            distortion64(&s, &w, rays, n)
        };
        ((eval(h) - eval(-h)) / (2.0 * h)) as f32
    };
    let fd_s: Vec<f32> = (0..s0.len()).map(|i| fd(true, i)).collect();
    let fd_w: Vec<f32> = (0..w0.len()).map(|i| fd(false, i)).collect();
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let (s, w) = steps.tensors(&device);
        let (s, w) = (s.require_grad(), w.require_grad());
        let grads = distortion_loss(s.clone(), w.clone()).backward();
        let gs = vec(s.grad(&grads).expect("gradient in s"));
        let gw = vec(w.grad(&grads).expect("gradient in w"));
        assert_close(&gs, &fd_s, 1e-5, 1e-3, &format!("{name}: d/ds"));
        assert_close(&gw, &fd_w, 1e-5, 1e-3, &format!("{name}: d/dw"));
    }
}

/// The dilated ends (each old end and its two shifts, sorted and clamped to
/// the domain) and weights (at each new interval, the largest density among
/// the dilated intervals covering its left end, times its width) match
/// their definition; the dilated histogram bounds the original over every
/// original interval; zero dilation only refines the histogram; with
/// renormalisation the weights sum to 1.
#[test]
fn max_dilation_matches_its_definition_and_bounds_the_histogram() {
    let mut rng = ChaCha8Rng::seed_from_u64(15);
    let (rays, n, d) = (3, 8, 0.03f32);
    let steps = Steps::random(&mut rng, rays, n, (0.0, 1.0));
    // Mass of new intervals inside each original interval.
    let mass_per_interval = |t: &[f32], e: &[f32], wd: &[f32]| -> Vec<f64> {
        (0..n)
            .map(|i| {
                (0..3 * n)
                    .filter(|&k| e[k] >= t[i] && e[k + 1] <= t[i + 1])
                    .map(|k| wd[k] as f64)
                    .sum()
            })
            .collect()
    };
    for (name, device) in devices(false) {
        let (t_t, w_t) = steps.tensors(&device);
        let (ends, wd) = max_dilate_weights(t_t.clone(), w_t.clone(), d, (0.0, 1.0), false);
        assert_eq!((ends.dims(), wd.dims()), ([rays, 3 * n + 1], [rays, 3 * n]));
        let (ends, wd) = (vec(ends), vec(wd));
        let (zero_e, zero_w) = max_dilate_weights(
            t_t.clone(),
            w_t.clone(),
            0.0,
            (f32::NEG_INFINITY, f32::INFINITY),
            false,
        );
        let (zero_e, zero_w) = (vec(zero_e), vec(zero_w));
        let normed = vec(max_dilate_weights(t_t, w_t, d, (0.0, 1.0), true).1);
        for r in 0..rays {
            let t = &steps.t[r * (n + 1)..(r + 1) * (n + 1)];
            let w = &steps.w[r * n..(r + 1) * n];
            let e = &ends[r * (3 * n + 1)..(r + 1) * (3 * n + 1)];
            let wr = &wd[r * 3 * n..(r + 1) * 3 * n];
            let mut want_e: Vec<f32> = t.to_vec();
            want_e.extend((0..n).map(|i| t[i] - d));
            want_e.extend((0..n).map(|i| t[i + 1] + d));
            want_e.sort_by(f32::total_cmp);
            let want_e: Vec<f32> = want_e.iter().map(|v| v.clamp(0.0, 1.0)).collect();
            assert_eq!(e, &want_e[..], "{name}: dilated ends");
            let want_w: Vec<f32> = (0..3 * n)
                .map(|k| {
                    let density = (0..n)
                        .filter(|&i| t[i] - d <= e[k] && t[i + 1] + d > e[k])
                        .map(|i| w[i] as f64 / (t[i + 1] - t[i]) as f64)
                        .fold(0.0, f64::max);
                    (density * (e[k + 1] - e[k]) as f64) as f32
                })
                .collect();
            assert_close(wr, &want_w, 1e-9, 1e-5, &format!("{name}: dilated weights"));
            for (i, m) in mass_per_interval(t, e, wr).into_iter().enumerate() {
                assert!(m >= w[i] as f64 * (1.0 - 1e-5), "{name}: {m} < {}", w[i]);
            }
            let ze = &zero_e[r * (3 * n + 1)..(r + 1) * (3 * n + 1)];
            let zw = &zero_w[r * 3 * n..(r + 1) * 3 * n];
            let refined: Vec<f32> = mass_per_interval(t, ze, zw)
                .into_iter()
                .map(|m| m as f32)
                .collect();
            assert_close(&refined, w, 1e-9, 1e-5, &format!("{name}: zero dilation"));
            let total: f32 = normed[r * 3 * n..(r + 1) * 3 * n].iter().sum();
            assert!(
                (total - 1.0).abs() < 1e-5,
                "{name}: renormalised sum {total}"
            );
        }
    }
}

/// The host dilation (linear-time, what the proposal sampler runs) gives
/// the tensor form's ends and weights, with and without renormalisation,
/// for small and large dilations and step functions with empty intervals.
#[test]
fn host_dilation_equals_the_tensor_form() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let device = Device::flex();
    for (n, d) in [(1, 0.2f32), (8, 0.0), (8, 0.03), (16, 0.6), (64, 0.0105)] {
        let mut steps = Steps::random(&mut rng, 5, n, (0.0, 1.0));
        if n > 2 {
            // An empty interval and a zero weight.
            steps.t[2] = steps.t[1];
            steps.w[3] = 0.0;
        }
        for renormalize in [false, true] {
            let (t, w) = steps.tensors(&device);
            let (e, wd) = max_dilate_weights(t, w, d, (0.0, 1.0), renormalize);
            let (he, hw) =
                max_dilate_weights_host(&steps.t, &steps.w, 5, d, (0.0, 1.0), renormalize);
            let what = format!("n {n}, dilation {d}, renormalised {renormalize}");
            assert_eq!(he, vec(e), "{what}: ends");
            assert_close(&hw, &vec(wd), 1e-9, 1e-5, &format!("{what}: weights"));
        }
    }
}

/// The annealing exponent follows Schlick's bias curve (0 at the start, 1
/// at the end, `10 x / (9 x + 1)` for slope 10, identity for slope 1, 1
/// when off), and annealed weights are `(w + padding)^exponent` on
/// non-empty intervals and 0 on empty ones, finite with gradient at `w = 0`.
#[test]
fn annealing_follows_the_schedule() {
    assert_eq!(anneal_exponent(0.0, 10.0), 0.0);
    assert_eq!(anneal_exponent(1.0, 10.0), 1.0);
    assert_eq!(anneal_exponent(2.0, 10.0), 1.0);
    assert_eq!(anneal_exponent(0.3, 0.0), 1.0);
    assert!((anneal_exponent(0.5, 10.0) - 5.0 / 5.5).abs() < 1e-6);
    assert!((anneal_exponent(0.37, 1.0) - 0.37).abs() < 1e-6);
    let curve: Vec<f32> = (0..=20)
        .map(|i| anneal_exponent(i as f32 / 20.0, 10.0))
        .collect();
    assert!(curve.windows(2).all(|p| p[0] < p[1]), "{curve:?}");
    let t = vec![0.0, 0.2, 0.2, 0.5, 1.0];
    let w = [0.3f32, 0.4, 0.0, 0.2];
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let tt = tensor(t.clone(), [1, 5], &device);
        let wt = tensor(w.to_vec(), [1, 4], &device).require_grad();
        let plain = vec(anneal_weights(tt.clone(), wt.clone(), 1.0, 0.0));
        assert_close(&plain, &[0.3, 0.0, 0.0, 0.2], 1e-12, 1e-6, name);
        let uniform = vec(anneal_weights(tt.clone(), wt.clone(), 0.0, 0.0));
        assert_eq!(uniform, vec![1.0, 0.0, 1.0, 1.0], "{name}: exponent 0");
        let want: Vec<f32> = [0.31f64, 0.0, 0.01, 0.21]
            .iter()
            .enumerate()
            .map(|(i, v)| if i == 1 { 0.0 } else { v.sqrt() as f32 })
            .collect();
        let half = anneal_weights(tt.clone(), wt.clone(), 0.5, 0.01);
        assert_close(&vec(half), &want, 1e-7, 1e-5, name);
        let root = anneal_weights(tt, wt.clone(), 0.5, 0.0);
        let grad = vec(wt.grad(&root.sum().backward()).expect("gradient"));
        assert!(grad.iter().all(|g| g.is_finite()), "{name}: {grad:?}");
    }
}
