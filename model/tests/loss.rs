//! Losses against direct f64 evaluation, their masking rules and finiteness
//! (including gradients) at zero-norm vectors and f16-range magnitudes.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

mod common;

use burn::tensor::Device;
use common::{assert_close, devices, tensor, uniform, vec};
use model::{
    FeatureSpace, capped_depth, depth_huber, depth_smoothness, depth_window, open_set_cosine,
    rgb_mse,
};

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

/// The weight away from each ray's depth target against a float64 loop
/// over random posts, weights and targets (some invalid); zero with the
/// weight inside the window, the whole weight beyond it; gradients only
/// through the weights, equal to the capped distances.
/// `n` rays' `k + 1` increasing posts, from 0.5 on, in gaps of 0.05 to
/// 0.6 drawn with `seed`, ray-major.
fn increasing_posts(n: usize, k: usize, seed: u64) -> Vec<f64> {
    let gaps = uniform(n * (k + 1), seed, 0.05, 0.6);
    let mut t = vec![0.0f64; n * (k + 1)];
    for r in 0..n {
        let mut acc = 0.5;
        for j in 0..=k {
            acc += gaps[r * (k + 1) + j];
            t[r * (k + 1) + j] = acc;
        }
    }
    t
}

#[test]
fn depth_window_matches_float64_and_bounds() {
    let (n, k, width) = (7usize, 9usize, 0.1f32);
    let t = increasing_posts(n, k, 3);
    let w = uniform(n * k, 4, 0.0, 0.2);
    let mut target: Vec<f64> = uniform(n, 5, 1.0, 4.0);
    target[2] = 0.0;
    target[5] = -1.0;
    let mut sum = 0.0f64;
    let mut valid = 0.0f64;
    let mut grad = vec![0.0f64; n * k];
    for r in 0..n {
        if target[r] <= 0.0 {
            continue;
        }
        valid += 1.0;
        for j in 0..k {
            let mid = 0.5 * (t[r * (k + 1) + j] + t[r * (k + 1) + j + 1]);
            let away = ((mid - target[r]).abs() / (width as f64 * target[r])).min(1.0);
            sum += w[r * k + j] * away;
            grad[r * k + j] = away;
        }
    }
    let want = (sum / valid) as f32;
    let f = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    for (name, device) in devices(false) {
        let device: Device = device.autodiff();
        let weights = tensor(f(&w), [n, k], &device).require_grad();
        let posts = tensor(f(&t), [n, k + 1], &device).require_grad();
        let loss = depth_window(
            posts.clone(),
            weights.clone(),
            tensor(f(&target), [n, 1], &device),
            width,
        );
        assert_close(&vec(loss.clone()), &[want], 1e-6, 1e-5, name);
        let g = loss.backward();
        let gw = weights.grad(&g).expect("weights' gradient");
        let gw: Vec<f32> = gw.into_data().try_to_vec().expect("f32");
        let want_g: Vec<f32> = grad.iter().map(|&x| (x / valid) as f32).collect();
        assert_close(&gw, &want_g, 1e-6, 1e-5, name);
        assert!(posts.grad(&g).is_none_or(|p| {
            p.into_data()
                .try_to_vec::<f32>()
                .expect("f32")
                .iter()
                .all(|&x| x == 0.0)
        }));
    }
    for (name, device) in devices(true) {
        // One ray: posts 1..=5, target 2.5 (the middle sample, at 2.5).
        let posts = tensor(vec![1.0, 2.0, 3.0, 4.0, 5.0], [1, 5], &device);
        let target = || tensor(vec![2.5], [1, 1], &device);
        let inside = depth_window(
            posts.clone(),
            tensor(vec![0.0, 0.9, 0.0, 0.0], [1, 4], &device),
            target(),
            0.1,
        );
        assert_eq!(vec(inside), vec![0.0], "{name}");
        let beyond = depth_window(
            posts.clone(),
            tensor(vec![0.3, 0.0, 0.4, 0.2], [1, 4], &device),
            target(),
            0.1,
        );
        assert_close(&vec(beyond), &[0.9], 1e-6, 1e-5, name);
    }
}

/// The capped expected depth against float64: each midpoint counted at no
/// more than `cap` times the ray's target, divided by the ray's total
/// weight; its gradient on a weight is that capped midpoint less the depth,
/// over the total weight, so a weight in a last interval thousands of units
/// long pulls no harder than one at the cap. Rays without a target keep
/// the uncapped depth.
#[test]
fn capped_depth_matches_float64_and_bounds_the_far_interval() {
    let (n, k, cap) = (6usize, 8usize, 2.0f32);
    let mut t = increasing_posts(n, k, 7);
    let w = uniform(n * k, 8, 0.0, 0.2);
    for r in 0..n {
        // An unbounded ray's last post, far past the scene.
        t[r * (k + 1) + k] = 25_000.0;
    }
    let mut target: Vec<f64> = uniform(n, 9, 0.8, 2.0);
    target[4] = 0.0;
    target[5] = f64::NAN;
    let mut want = vec![0.0f64; n];
    let mut grad = vec![0.0f64; n * k];
    for r in 0..n {
        let limit = if target[r] > 0.0 {
            cap as f64 * target[r]
        } else {
            f64::INFINITY
        };
        let mids: Vec<f64> = (0..k)
            .map(|j| (0.5 * (t[r * (k + 1) + j] + t[r * (k + 1) + j + 1])).min(limit))
            .collect();
        let acc: f64 = (0..k).map(|j| w[r * k + j]).sum();
        let sum: f64 = (0..k).map(|j| w[r * k + j] * mids[j]).sum();
        want[r] = sum / acc;
        for j in 0..k {
            // d(sum / acc) / dw_j, summed into the loss `sum of depths`.
            grad[r * k + j] = (mids[j] - want[r]) / acc;
        }
    }
    let f = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    for (name, device) in devices(false) {
        let device: Device = device.autodiff();
        let weights = tensor(f(&w), [n, k], &device).require_grad();
        let depth = capped_depth(
            weights.clone(),
            tensor(f(&t), [n, k + 1], &device),
            tensor(f(&target), [n, 1], &device),
            cap,
        );
        let got = vec(depth.clone());
        assert_close(&got, &f(&want), 1e-5, 1e-5, name);
        // Capped rays stay within the cap; the ray without a target does not.
        for r in 0..n {
            if target[r] > 0.0 {
                assert!(
                    got[r] <= (cap as f64 * target[r]) as f32 + 1e-4,
                    "{name}: ray {r}"
                );
            }
        }
        assert!(got[4] > 1000.0 && got[5] > 1000.0, "{name}: {got:?}");
        let g = depth.sum().backward();
        let gw: Vec<f32> = weights
            .grad(&g)
            .expect("weights' gradient")
            .into_data()
            .try_to_vec()
            .expect("f32");
        for r in 0..n {
            let row = r * k..(r + 1) * k;
            let scale = if target[r] > 0.0 { 1e-4 } else { 1e-2 };
            for i in row {
                let tol = scale * grad[i].abs().max(1.0) as f32;
                assert!(
                    (gw[i] - grad[i] as f32).abs() <= tol,
                    "{name}: {i}: {} vs {}",
                    gw[i],
                    grad[i]
                );
            }
            if target[r] > 0.0 {
                let last = r * k + k - 1;
                assert!(
                    gw[last].abs() < 20.0 * cap * target[r] as f32,
                    "{name}: {}",
                    gw[last]
                );
            }
        }
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
        let loss = open_set_cosine(
            p.clone(),
            tensor(target.clone(), [4, 3], &device),
            tensor(vec![1.0; 4], [4, 1], &device),
            &FeatureSpace::Identity,
        );
        assert_close(&vec(loss.clone()), &[want], 1e-6, 1e-5, name);
        let grads = loss.backward();
        let g = vec(p.grad(&grads).expect("gradient"));
        assert!(g.iter().all(|v| v.is_finite()), "{name}: gradient {g:?}");
        // The skipped ray gets no gradient.
        assert_eq!(&g[6..9], &[0.0, 0.0, 0.0], "{name}");
        let all_zero = vec(open_set_cosine(
            tensor(vec![1.0, 2.0], [1, 2], &device),
            tensor(vec![0.0, 0.0], [1, 2], &device),
            tensor(vec![1.0], [1, 1], &device),
            &FeatureSpace::Identity,
        ));
        assert_eq!(all_zero, vec![0.0], "{name}: no valid target");
    }
}

/// A `k x d` matrix with orthonormal rows (Gram-Schmidt of seeded rows) and
/// a mean vector, in f64.
fn pca_basis(k: usize, d: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut s = seed;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut rows: Vec<Vec<f64>> = Vec::new();
    while rows.len() < k {
        let mut r: Vec<f64> = (0..d).map(|_| next()).collect();
        for q in &rows {
            let p: f64 = r.iter().zip(q).map(|(a, b)| a * b).sum();
            r.iter_mut().zip(q).for_each(|(a, b)| *a -= p * b);
        }
        let n = r.iter().map(|a| a * a).sum::<f64>().sqrt();
        r.iter_mut().for_each(|a| *a /= n);
        rows.push(r);
    }
    let mean = (0..d).map(|_| 2.0 * next()).collect();
    (rows, mean)
}

fn lift(u: &[Vec<f64>], m: &[f64], c: &[f32]) -> Vec<f64> {
    let mut f = m.to_vec();
    for (row, &ci) in u.iter().zip(c) {
        f.iter_mut().zip(row).for_each(|(a, b)| *a += ci as f64 * b);
    }
    f
}

fn cos64(a: &[f64], b: &[f64]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let na = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    let nb = b.iter().map(|x| x * x).sum::<f64>().sqrt();
    dot / (na * nb)
}

/// With PCA targets the loss is the cosine of the lifted features `m + U^T c`
/// (an f64 explicit lift is the reference), not of the centred coefficients:
/// a prediction half as long as its target has centred cosine 1 but lifts to
/// another direction, and must be penalised. Masked rays do not count and get
/// no gradient.
#[test]
fn cosine_loss_compares_lifted_features() {
    let (k, d) = (3, 7);
    let (u, m) = pca_basis(k, d, 11);
    let um: Vec<f32> = u
        .iter()
        .map(|r| r.iter().zip(&m).map(|(a, b)| a * b).sum::<f64>() as f32)
        .collect();
    let msq = m.iter().map(|x| x * x).sum::<f64>() as f32;
    let target = vec![
        0.8, -0.4, 0.3, 0.1, 0.9, -0.7, -1.2, 0.2, 0.5, 2.0, 1.0, 0.0,
    ];
    // Ray 0: half the target (centred cosine 1); rays 1-2: other values;
    // ray 3 is masked out.
    let pred = vec![
        0.4, -0.2, 0.15, -0.3, 0.2, 0.4, 0.0, 0.0, 0.0, 9.0, 9.0, 9.0,
    ];
    let mask = vec![1.0, 1.0, 1.0, 0.0];
    let want: f64 = (0..3)
        .map(|r| {
            1.0 - cos64(
                &lift(&u, &m, &pred[r * k..(r + 1) * k]),
                &lift(&u, &m, &target[r * k..(r + 1) * k]),
            )
        })
        .sum::<f64>()
        / 3.0;
    let half = 1.0 - cos64(&lift(&u, &m, &pred[..k]), &lift(&u, &m, &target[..k]));
    assert!(
        half > 1e-3,
        "the half-length prediction lifts elsewhere: {half}"
    );
    for (name, device) in devices(false) {
        let device: Device = device.autodiff();
        let space = FeatureSpace::Lifted {
            mean_proj: Box::new(tensor(um.clone(), [1, k], &device)),
            mean_sq: msq,
        };
        let p = tensor(pred.clone(), [4, k], &device).require_grad();
        let loss = open_set_cosine(
            p.clone(),
            tensor(target.clone(), [4, k], &device),
            tensor(mask.clone(), [4, 1], &device),
            &space,
        );
        assert_close(&vec(loss.clone()), &[want as f32], 1e-6, 1e-5, name);
        let single = open_set_cosine(
            tensor(pred[..k].to_vec(), [1, k], &device),
            tensor(target[..k].to_vec(), [1, k], &device),
            tensor(vec![1.0], [1, 1], &device),
            &space,
        );
        assert_close(&vec(single), &[half as f32], 1e-6, 1e-4, name);
        let g = vec(p.grad(&loss.backward()).expect("gradient"));
        assert!(g.iter().all(|v| v.is_finite()), "{name}: {g:?}");
        assert!(g[..k].iter().any(|v| v.abs() > 1e-4), "{name}: {g:?}");
        assert_eq!(&g[3 * k..], &[0.0, 0.0, 0.0], "{name}: masked ray");
    }
}

/// The depth smoothness of patches by float64 brute force: every ordered
/// pair of 4-neighbours within a patch, each unordered pair once.
fn smoothness64(depth: &[f64], side: usize) -> f64 {
    let (mut sum, mut pairs) = (0.0, 0usize);
    for patch in depth.chunks_exact(side * side) {
        for y in 0..side {
            for x in 0..side {
                for (dx, dy) in [(1usize, 0usize), (0, 1)] {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < side && ny < side {
                        sum += (patch[ny * side + nx] - patch[y * side + x]).powi(2);
                        pairs += 1;
                    }
                }
            }
        }
    }
    sum / pairs as f64
}

/// Value against float64 brute force on random patches; zero on patches
/// that are each constant, however far apart their constants (no pair
/// crosses a patch); zero for a patch of side 1.
#[test]
fn depth_smoothness_matches_brute_force_and_ignores_patch_borders() {
    let (patches, side) = (3, 5);
    let d64 = uniform(patches * side * side, 21, 0.5, 4.0);
    let want = smoothness64(&d64, side) as f32;
    let constant: Vec<f32> = (0..patches * side * side)
        .map(|i| [1.0, 9.0, 0.25][i / (side * side)])
        .collect();
    for (name, device) in devices(true) {
        let d: Vec<f32> = d64.iter().map(|&x| x as f32).collect();
        let n = d.len();
        let got = vec(depth_smoothness(tensor(d, [n, 1], &device), side));
        assert_close(&got, &[want], 1e-6, 1e-5, name);
        let flat = vec(depth_smoothness(
            tensor(constant.clone(), [n, 1], &device),
            side,
        ));
        assert_eq!(flat, vec![0.0], "{name}: constant patches");
        let single = vec(depth_smoothness(tensor(vec![1.0, 5.0], [2, 1], &device), 1));
        assert_eq!(single, vec![0.0], "{name}: side 1");
    }
}

/// Its gradient against central differences of the float64 form.
#[test]
fn depth_smoothness_gradient_matches_finite_differences() {
    let (patches, side) = (2, 4);
    let d64 = uniform(patches * side * side, 22, 0.0, 2.0);
    let h = 1e-6;
    let fd: Vec<f32> = (0..d64.len())
        .map(|i| {
            let mut up = d64.clone();
            let mut down = d64.clone();
            up[i] += h;
            down[i] -= h;
            ((smoothness64(&up, side) - smoothness64(&down, side)) / (2.0 * h)) as f32
        })
        .collect();
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let d: Vec<f32> = d64.iter().map(|&x| x as f32).collect();
        let n = d.len();
        let t = tensor(d, [n, 1], &device).require_grad();
        let grads = depth_smoothness(t.clone(), side).backward();
        let g = vec(t.grad(&grads).expect("gradient"));
        assert_close(&g, &fd, 1e-5, 1e-3, name);
    }
}
