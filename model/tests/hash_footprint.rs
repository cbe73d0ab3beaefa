//! The hash levels' footprint weights against a Monte Carlo oracle (the
//! weight of a level is the mass of the sample's Gaussian within half a
//! cell of its mean), their limits, and the fast field's encoding with and
//! without them.

mod common;

use burn::tensor::{Device, Tensor};
use common::{assert_close, devices, tensor, uniform, vec};
use model::hash_footprint::{isotropic_variance, level_weights, weigh_levels};
use model::{FastFieldConfig, HashGridConfig};

/// `P(|X| < 1 / (2 r))` for `X ~ N(0, sigma^2)`, from `draws` normal draws
/// (Box-Muller over deterministic uniforms), in float64.
fn mass_within_half_cell(sigma: f64, cells: f64, draws: usize, seed: u64) -> f64 {
    let u = uniform(2 * draws, seed, 1e-12, 1.0);
    let half = 0.5 / cells;
    let inside = (0..draws)
        .filter(|&i| {
            let r = (-2.0 * u[2 * i].ln()).sqrt();
            let x = sigma * r * (2.0 * std::f64::consts::PI * u[2 * i + 1]).cos();
            x.abs() < half
        })
        .count();
    inside as f64 / draws as f64
}

#[test]
fn each_levels_weight_is_the_gaussians_mass_within_half_a_cell() {
    let half_extent = 2.0f32;
    let resolutions = [4u32, 16, 64, 256];
    // Standard deviations in the encoded coordinates, from far below a
    // fine cell to above a coarse one.
    let sigmas = [1e-3f64, 0.01, 0.05, 0.2, 1.0];
    let variance: Vec<f32> = sigmas.iter().map(|s| (s * s) as f32).collect();
    for (name, device) in devices(false) {
        let got = vec(level_weights(
            tensor(variance.clone(), [sigmas.len(), 1], &device),
            &resolutions,
            half_extent,
        ));
        let draws = 400_000;
        for (i, &sigma) in sigmas.iter().enumerate() {
            // The unit cube is the encoded cube scaled by 1 / (2 h).
            let sigma_unit = sigma / (2.0 * half_extent as f64);
            for (l, &r) in resolutions.iter().enumerate() {
                let want = mass_within_half_cell(sigma_unit, r as f64, draws, 7 + i as u64);
                let tolerance = 4.0 * (want * (1.0 - want) / draws as f64).sqrt() + 1e-5;
                let g = got[i * resolutions.len() + l] as f64;
                assert!(
                    (g - want).abs() <= tolerance,
                    "{name}: sigma {sigma}, {r} cells: weight {g}, Monte Carlo {want}"
                );
            }
        }
    }
}

#[test]
fn a_point_keeps_every_level_and_a_wider_gaussian_keeps_less() {
    let device = Device::flex();
    let resolutions = [16u32, 64, 512];
    let variance = tensor(vec![0.0, 1e-6, 1e-4, 1e-2], [4, 1], &device);
    let w = vec(level_weights(variance, &resolutions, std::f32::consts::PI));
    assert_close(&w[0..3], &[1.0, 1.0, 1.0], 0.0, 0.0, "a point's weights");
    for i in 0..4 {
        let row = &w[i * 3..i * 3 + 3];
        assert!(
            row.windows(2).all(|p| p[1] <= p[0]),
            "finer levels weigh less: {row:?}"
        );
        assert!(row.iter().all(|&x| x > 0.0 && x <= 1.0), "{row:?}");
        if i > 0 {
            let above = &w[(i - 1) * 3..i * 3];
            assert!(
                row.iter().zip(above).all(|(b, a)| b <= a),
                "wider weighs less: {above:?} then {row:?}"
            );
        }
    }
}

#[test]
fn the_isotropic_variance_is_the_mean_of_the_diagonal() {
    let device = Device::flex();
    let cov = tensor(vec![1.0, 2.0, 6.0, 0.0, 0.3, 0.0], [2, 3], &device);
    assert_close(
        &vec(isotropic_variance(cov)),
        &[3.0, 0.1],
        0.0,
        1e-6,
        "variance",
    );
}

#[test]
fn weighing_scales_each_levels_features_by_its_weight() {
    let device = Device::flex();
    let (n, levels, features) = (3, 4, 2);
    let encoded: Vec<f32> = uniform(n * levels * features, 1, -1.0, 1.0)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let weights: Vec<f32> = uniform(n * levels, 2, 0.0, 1.0)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let got = vec(weigh_levels(
        tensor(encoded.clone(), [n, levels * features], &device),
        tensor(weights.clone(), [n, levels], &device),
    ));
    let want: Vec<f32> = (0..n * levels * features)
        .map(|k| encoded[k] * weights[k / features])
        .collect();
    assert_close(&got, &want, 0.0, 1e-6, "weighed features");
}

/// Off, the fast field's input is the hash encoding of the means whatever
/// their size; on, a point's encoding is that too, and a wide Gaussian's
/// fine levels fade.
#[test]
fn the_fast_field_weighs_its_levels_only_when_asked() {
    let device = Device::flex();
    let grid = HashGridConfig::new()
        .with_levels(4)
        .with_log2_table(10)
        .with_base_resolution(4)
        .with_max_resolution(256);
    let n = 16;
    let mean: Vec<f32> = uniform(3 * n, 5, -3.0, 3.0)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let mean = tensor(mean, [n, 3], &device);
    let point = Tensor::<2>::zeros([n, 3], &device);
    let wide = point.clone().add_scalar(0.05);
    for on in [false, true] {
        let config = FastFieldConfig::new()
            .with_grid(grid.clone())
            .with_footprint_weights(Some(on));
        let mut field = config.init(0, &device);
        field.grid.table = burn::module::Param::from_tensor(Tensor::random(
            field.grid.table.val().dims(),
            burn::tensor::Distribution::Uniform(-1.0, 1.0),
            &device,
        ));
        let plain = vec(field.grid.forward(mean.clone()));
        let at_point = vec(field.encode(mean.clone(), point.clone()));
        assert_close(&at_point, &plain, 0.0, 1e-6, "a point's encoding");
        let at_wide = vec(field.encode(mean.clone(), wide.clone()));
        let width = field.grid.output_dim();
        let finest = |v: &[f32]| -> f32 {
            (0..n)
                .flat_map(|i| v[i * width + width - 2..(i + 1) * width].to_vec())
                .map(f32::abs)
                .sum()
        };
        if on {
            assert!(
                finest(&at_wide) < 0.2 * finest(&plain),
                "the finest level fades: {} of {}",
                finest(&at_wide),
                finest(&plain)
            );
        } else {
            assert_close(&at_wide, &plain, 0.0, 0.0, "unweighed");
        }
    }
}
