//! The learned pose correction: the rotation against the float64 matrix
//! exponential of its skew matrix (summed as a series, not by Rodrigues'
//! formula), its gradient against central finite differences of that
//! oracle (the zero and small angles included), corrected rays, and a
//! perturbed camera recovered by gradient descent on its correction.

mod common;

use burn::module::Param;
use burn::tensor::{Device, Tensor};
use common::{assert_close, devices, tensor, uniform, vec};
use model::pose::rotate;
use model::{PoseCorrectionConfig, Rays};

type M3 = [[f64; 3]; 3];

/// `exp([w]x)` as the series `sum_k [w]x^k / k!`, in float64.
fn exp_skew(w: [f64; 3]) -> M3 {
    let k: M3 = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let mul = |a: &M3, b: &M3| -> M3 {
        std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|i| a[r][i] * b[i][c]).sum()))
    };
    let mut sum: M3 = std::array::from_fn(|r| std::array::from_fn(|c| f64::from(r == c)));
    let mut term = sum;
    for n in 1..40 {
        term = mul(&term, &k);
        term = term.map(|row| row.map(|x| x / n as f64));
        for r in 0..3 {
            for c in 0..3 {
                sum[r][c] += term[r][c];
            }
        }
    }
    sum
}

fn apply(m: &M3, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|c| m[r][c] * v[c]).sum())
}

fn values(n: usize, seed: u64, lo: f64, hi: f64) -> Vec<f64> {
    uniform(n, seed, lo, hi)
}

/// `n` deterministic 3-vectors with components in `[lo, hi)`.
fn vec3s(n: usize, seed: u64, lo: f64, hi: f64) -> Vec<[f64; 3]> {
    values(3 * n, seed, lo, hi)
        .chunks(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}

/// Rotation vectors at every regime: zero, far below, near and past the
/// switch to the series (|w| = 0.01), moderate and large angles.
fn rotation_vectors() -> Vec<[f64; 3]> {
    let axis = |s: f64, a: [f64; 3]| {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|x| x * s / n)
    };
    let mut w = vec![[0.0; 3]];
    for (i, angle) in [1e-9, 1e-6, 1e-3, 0.00999, 0.01001, 0.05, 0.3, 1.0, 2.0, 3.1]
        .into_iter()
        .enumerate()
    {
        let a = values(3, 10 + i as u64, -1.0, 1.0);
        w.push(axis(angle, [a[0], a[1], a[2]]));
    }
    w
}

fn flat(v: &[[f64; 3]]) -> Vec<f32> {
    v.iter().flatten().map(|&x| x as f32).collect()
}

#[test]
fn the_rotation_is_the_exponential_of_the_skew_matrix() {
    let w = rotation_vectors();
    let n = w.len();
    let v = vec3s(n, 3, -2.0, 2.0);
    let expected: Vec<[f64; 3]> = (0..n).map(|i| apply(&exp_skew(w[i]), v[i])).collect();
    for (name, device) in devices(true) {
        let got = rotate(
            tensor(flat(&v), [n, 3], &device),
            tensor(flat(&w), [n, 3], &device),
        );
        assert_close(&vec(got.clone()), &flat(&expected), 2e-6, 2e-6, name);
        // Turning back by -w gives the vector again.
        let minus: Vec<[f64; 3]> = w.iter().map(|a| a.map(|x| -x)).collect();
        let back = rotate(got, tensor(flat(&minus), [n, 3], &device));
        assert_close(&vec(back), &flat(&v), 4e-6, 4e-6, name);
    }
    // No rotation leaves the vector exactly as it was.
    let device = Device::flex();
    let v = values(12, 4, -5.0, 5.0)
        .iter()
        .map(|&x| x as f32)
        .collect::<Vec<_>>();
    let same = rotate(
        tensor(v.clone(), [4, 3], &device),
        Tensor::zeros([4, 3], &device),
    );
    assert_eq!(vec(same), v);
}

#[test]
fn the_gradient_matches_finite_differences_of_the_exponential() {
    let w = rotation_vectors();
    let n = w.len();
    let v = vec3s(n, 5, -1.0, 1.0);
    let c = vec3s(n, 6, -1.0, 1.0);
    // d/dw_j of c . exp([w]x) v, central differences in float64.
    let h = 1e-6;
    let expected: Vec<f64> = (0..n)
        .flat_map(|i| {
            let (w, v, c) = (w[i], v[i], c[i]);
            (0..3).map(move |j| {
                let f = |s: f64| {
                    let mut a = w;
                    a[j] += s;
                    let r = apply(&exp_skew(a), v);
                    (0..3).map(|k| c[k] * r[k]).sum::<f64>()
                };
                (f(h) - f(-h)) / (2.0 * h)
            })
        })
        .collect();
    let expected: Vec<f32> = expected.iter().map(|&x| x as f32).collect();
    #[allow(deprecated)]
    for (name, device) in [
        ("flex", Device::flex().autodiff()),
        ("ndarray", Device::ndarray().autodiff()),
    ] {
        let wt = tensor(flat(&w), [n, 3], &device).require_grad();
        let out = rotate(tensor(flat(&v), [n, 3], &device), wt.clone());
        let loss = (out * tensor(flat(&c), [n, 3], &device)).sum();
        let grads = loss.backward();
        let g = vec(wt.grad(&grads).expect("a gradient"));
        assert_close(&g, &expected, 1e-5, 1e-4, name);
    }
}

fn rays(origins: Vec<f32>, directions: Vec<f32>, device: &Device) -> Rays {
    let n = origins.len() / 3;
    Rays {
        origins: tensor(origins, [n, 3], device),
        directions: tensor(directions, [n, 3], device),
        radii: tensor(
            values(n, 7, 0.001, 0.01)
                .iter()
                .map(|&x| x as f32)
                .collect(),
            [n, 1],
            device,
        ),
        near: tensor(vec![0.5; n], [n, 1], device),
        appearance: None,
        far: tensor(vec![4.0; n], [n, 1], device),
    }
}

#[test]
fn corrected_rays_move_their_origin_and_turn_their_direction() {
    let device = Device::flex();
    let n = 5;
    let o: Vec<f32> = values(3 * n, 8, -1.0, 1.0)
        .iter()
        .map(|&x| x as f32)
        .collect();
    let d: Vec<f32> = values(3 * n, 9, -1.0, 1.0)
        .iter()
        .map(|&x| x as f32)
        .collect();
    let before = rays(o.clone(), d.clone(), &device);
    // No correction: the rays as they were, bit for bit.
    let same = before.clone().corrected(Tensor::zeros([n, 6], &device));
    assert_eq!(vec(same.origins), o);
    assert_eq!(vec(same.directions), d);
    let corr: Vec<f64> = values(6 * n, 11, -0.2, 0.2);
    let out = before.clone().corrected(tensor(
        corr.iter().map(|&x| x as f32).collect(),
        [n, 6],
        &device,
    ));
    let mut eo = Vec::new();
    let mut ed = Vec::new();
    for i in 0..n {
        let c = &corr[6 * i..6 * i + 6];
        let r = exp_skew([c[0], c[1], c[2]]);
        let di = [d[3 * i] as f64, d[3 * i + 1] as f64, d[3 * i + 2] as f64];
        ed.extend(apply(&r, di));
        eo.extend((0..3).map(|k| o[3 * i + k] as f64 + c[3 + k]));
    }
    let f = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect::<Vec<_>>();
    assert_close(&vec(out.origins), &f(eo), 1e-6, 1e-6, "origins");
    assert_close(&vec(out.directions), &f(ed), 1e-6, 1e-6, "directions");
    assert_eq!(vec(out.radii), vec(before.radii));
    assert_eq!(vec(out.near), vec(before.near));
    assert_eq!(vec(out.far), vec(before.far));
}

#[test]
fn a_perturbed_camera_is_recovered_by_descent_on_its_correction() {
    let device = Device::flex().autodiff();
    // Photograph 1's true rays; it was given a pose turned by `w_err`
    // about its centre and shifted by `t_err`.
    let n = 64;
    let centre = [0.3, -0.4, -2.5];
    let d_true: Vec<[f64; 3]> = values(3 * n, 12, -0.4, 0.4)
        .chunks(3)
        .map(|c| [c[0], c[1], 1.0 + c[2] * 0.1])
        .collect();
    let (w_err, t_err) = ([0.02, -0.035, 0.01], [0.05, 0.02, -0.04]);
    let r_err = exp_skew(w_err);
    let d_given: Vec<[f64; 3]> = d_true.iter().map(|&d| apply(&r_err, d)).collect();
    let o_given: Vec<f32> = (0..n)
        .flat_map(|_| (0..3).map(|k| (centre[k] + t_err[k]) as f32))
        .collect();
    let target_o = tensor(
        (0..n).flat_map(|_| centre.map(|x| x as f32)).collect(),
        [n, 3],
        &device,
    );
    let target_d = tensor(flat(&d_true), [n, 3], &device);
    let frames = vec![1; n];
    let mut table = PoseCorrectionConfig::new(3).init(&device);
    let lr = 0.5;
    for _ in 0..400 {
        let given = rays(o_given.clone(), flat(&d_given), &device);
        let out = given.corrected(table.per_ray(&frames));
        let loss = (out.origins - target_o.clone()).square().sum_dim(1).mean()
            + (out.directions - target_d.clone())
                .square()
                .sum_dim(1)
                .mean();
        let grads = loss.backward();
        let g = vec(table.params.grad(&grads).expect("a gradient"));
        let p: Vec<f32> = vec(table.params.val())
            .iter()
            .zip(&g)
            .map(|(p, g)| p - lr * g)
            .collect();
        table.params = Param::from_tensor(tensor(p, [3, 6], &device));
    }
    let got = vec(table.params.val());
    // Photograph 1 turned back by -w_err and shifted back by -t_err; the
    // others untouched.
    let want: Vec<f32> = [w_err, t_err]
        .iter()
        .flatten()
        .map(|&x| -x as f32)
        .collect();
    assert_close(&got[6..12], &want, 1e-4, 1e-3, "photograph 1");
    assert!(
        got[..6].iter().chain(&got[12..]).all(|&x| x == 0.0),
        "{got:?}"
    );
}
