//! A field whose density is fitted to the grid's ball, so that the timed
//! inference renders rays that meet a surface and end there, as on a
//! trained scene (a freshly initialised field is a thin fog that no ray
//! ends in, where early termination has nothing to skip).

use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::{Device, Tensor, TensorData};
use model::OpenNerf;

/// Radius of the ball (the grid's, see `object_grid`).
pub const RADIUS: f32 = 1.2;
/// Density inside the ball, per unit of normalised length.
const INSIDE: f32 = 40.0;

/// A 64-bit linear congruential generator (the bench's rays use the same).
struct Lcg(u64);

impl Lcg {
    /// Uniform in `[lo, hi)`.
    fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 40) as f32 / (1u64 << 24) as f32)
    }
}

/// Half points uniform in the cube `[-2.5, 2.5]^3` the bench rays cross,
/// half uniform in the ball, with their target densities.
fn batch(n: usize, rng: &mut Lcg) -> (Vec<f32>, Vec<f32>) {
    let mut points = Vec::with_capacity(3 * n);
    let mut target = Vec::with_capacity(n);
    for i in 0..n {
        let p = loop {
            let p: [f32; 3] = std::array::from_fn(|_| rng.uniform(-2.5, 2.5));
            let r2: f32 = p.iter().map(|v| v * v).sum();
            if i % 2 == 0 || r2 < RADIUS * RADIUS {
                break p;
            }
        };
        let r2: f32 = p.iter().map(|v| v * v).sum();
        target.push(if r2 < RADIUS * RADIUS { INSIDE } else { 0.0 });
        points.extend(p);
    }
    (points, target)
}

/// `model` (on the autodiff device) after `steps` Adam steps (learning rate 1e-3) fitting its
/// density to the ball (squared error relative to the inside density, on
/// points of radius 0.01), and the final loss.
pub fn fit(model: OpenNerf, steps: usize, points: usize, device: &Device) -> (OpenNerf, f32) {
    let mut rng = Lcg(9);
    let mut optim = AdamConfig::new().init();
    let mut model = model;
    let mut last = f32::NAN;
    for _ in 0..steps {
        let (p, t) = batch(points, &mut rng);
        let p = Tensor::<2>::from_data(TensorData::new(p, [points, 3]), device);
        let t = Tensor::<2>::from_data(TensorData::new(t, [points, 1]), device);
        let loss = model
            .query_density(p, 0.01)
            .sub(t)
            .div_scalar(INSIDE)
            .square()
            .mean();
        last = loss.clone().into_scalar::<f32>();
        let grads = GradientsParams::from_grads(loss.backward(), &model);
        model = optim.step(1e-3, model, grads);
    }
    (model, last)
}
