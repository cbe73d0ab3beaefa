//! Adam in one pass ([`model::FusedAdam`]) against Burn's Adam (the same
//! parameters and moments bit for bit, step after step, on every CPU
//! backend), against Adam written out in float64, across each other's
//! saved records, and leaving a parameter shared with another copy of the
//! module untouched.

mod common;

use burn::module::{Module, Param};
use burn::nn::LinearConfig;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor};
use common::{devices, tensor, uniform, vec};
use model::{FusedAdamConfig, HashGrid, HashGridConfig};

/// A grid of two levels (one dense, one hashed) with enough rows that the
/// update runs in parallel chunks.
fn grid(device: &Device) -> HashGrid {
    device.seed(5);
    HashGridConfig::new()
        .with_levels(2)
        .with_log2_table(14)
        .with_base_resolution(8)
        .with_max_resolution(64)
        .init(device)
}

/// A loss of the grid at `n` points of seed `seed` whose gradient moves
/// only the rows those points touch, of both signs.
fn grads(grid: &HashGrid, seed: u64, device: &Device) -> GradientsParams {
    let n = 300;
    let pts: Vec<f32> = uniform(3 * n, seed, -0.9, 0.9)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let enc = grid.forward(tensor(pts, [n, 3], device));
    let [_, w] = enc.dims();
    let target = Tensor::<2>::ones([n, w], device).mul_scalar(0.3);
    let loss = (enc - target).powi_scalar(2).mean();
    GradientsParams::from_grads(loss.backward(), grid)
}

fn table(grid: &HashGrid) -> Vec<f32> {
    vec(grid.table.val())
}

/// Trains two copies of one grid, one with each optimiser, for `steps`
/// steps at changing learning rates, and asserts equal tables after each.
fn assert_same_steps(
    mut a: HashGrid,
    mut b: HashGrid,
    optim_a: &mut ModuleOptimizer,
    optim_b: &mut ModuleOptimizer,
    seeds: std::ops::Range<u64>,
    name: &str,
    device: &Device,
) -> (HashGrid, HashGrid) {
    for seed in seeds {
        let lr = 1e-2 / (1.0 + seed as f64);
        let ga = grads(&a, seed, device);
        let gb = grads(&b, seed, device);
        a = optim_a.step(lr, a, ga);
        b = optim_b.step(lr, b, gb);
        let (ta, tb) = (table(&a), table(&b));
        let differing = ta.iter().zip(&tb).filter(|(x, y)| x != y).count();
        assert_eq!(differing, 0, "{name}: step of seed {seed}");
        assert_ne!(ta, table(&grid(device)), "{name}: the table moved");
    }
    (a, b)
}

#[test]
fn one_pass_gives_burns_adam_bit_for_bit() {
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let mut burn = AdamConfig::new().init();
        let mut fused = FusedAdamConfig::new().init();
        assert_same_steps(
            grid(&device),
            grid(&device),
            &mut burn,
            &mut fused,
            0..6,
            name,
            &device,
        );
    }
}

#[test]
fn records_load_across_the_two_optimisers_and_steps_stay_equal() {
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let mut burn = AdamConfig::new().init();
        let mut fused = FusedAdamConfig::new().init();
        let (a, b) = assert_same_steps(
            grid(&device),
            grid(&device),
            &mut burn,
            &mut fused,
            0..3,
            name,
            &device,
        );
        // Each continues from the other's saved state.
        let burn_bytes = burn.into_bytes().expect("Burn's record");
        let fused_bytes = fused.into_bytes().expect("the fused record");
        let mut fused_from_burn = FusedAdamConfig::new()
            .init()
            .from_bytes(burn_bytes)
            .expect("Burn's record loads into the fused optimiser");
        let mut burn_from_fused = AdamConfig::new()
            .init()
            .from_bytes(fused_bytes)
            .expect("the fused record loads into Burn's optimiser");
        assert_same_steps(
            a,
            b,
            &mut fused_from_burn,
            &mut burn_from_fused,
            3..6,
            name,
            &device,
        );
    }
}

/// Adam in float64 on a parameter of four numbers under fixed gradients.
#[test]
fn one_pass_follows_adam_written_in_float64() {
    let device = Device::flex().autodiff();
    let start = [0.5f32, -1.25, 2.0, 0.0];
    let gs = [
        [0.3f32, -0.2, 1e-3, -4.0],
        [-0.1, -0.2, 2e-3, 3.0],
        [0.25, 0.05, -1e-3, -0.5],
    ];
    let lrs = [0.1f64, 0.05, 0.02];
    let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-5f64);
    let mut optim = FusedAdamConfig::new().init();
    let mut linear = LinearConfig::new(4, 1).with_bias(false).init(&device);
    linear.weight = Param::from_tensor(tensor(start.to_vec(), [4, 1], &device));
    let (mut p, mut m, mut v) = (start.map(f64::from), [0f64; 4], [0f64; 4]);
    for (t, (g, lr)) in gs.iter().zip(lrs).enumerate() {
        // The loss `sum g * table` has gradient `g`.
        let weights = tensor(g.to_vec(), [4, 1], &device);
        let loss = (linear.weight.val() * weights).sum();
        let grads = GradientsParams::from_grads(loss.backward(), &linear);
        linear = optim.step(lr, linear, grads);
        let t = (t + 1) as i32;
        for k in 0..4 {
            let gk = f64::from(g[k]);
            m[k] = b1 * m[k] + (1.0 - b1) * gk;
            v[k] = b2 * v[k] + (1.0 - b2) * gk * gk;
            let m_hat = m[k] / (1.0 - b1.powi(t));
            let v_hat = v[k] / (1.0 - b2.powi(t));
            p[k] -= lr * m_hat / (v_hat.sqrt() + eps);
        }
        let got = vec(linear.weight.val());
        for k in 0..4 {
            assert!(
                (f64::from(got[k]) - p[k]).abs() <= 1e-6 * (1.0 + p[k].abs()),
                "step {t}, number {k}: {} against {}",
                got[k],
                p[k]
            );
        }
    }
}

#[test]
fn a_step_leaves_another_copy_of_the_module_as_it_was() {
    for (name, device) in devices(false) {
        let device = device.autodiff();
        let mut optim = FusedAdamConfig::new().init();
        let mut a = grid(&device);
        for seed in 0..3 {
            let before = a.clone();
            let kept = table(&before);
            let g = grads(&a, seed, &device);
            a = optim.step(1e-2, a, g);
            assert_eq!(table(&before), kept, "{name}: the copy changed");
            assert_ne!(table(&a), kept, "{name}: the step changed nothing");
        }
    }
}

#[test]
fn the_module_keeps_its_shapes() {
    let device = Device::flex().autodiff();
    let mut optim = FusedAdamConfig::new().init();
    let a = grid(&device);
    let dims = a.table.val().dims();
    let g = grads(&a, 0, &device);
    let a = optim.step(1e-2, a, g);
    assert_eq!(a.table.val().dims(), dims);
    assert_eq!(a.num_params(), grid(&device).num_params());
}
