//! The multiresolution hash encoding against independent references: a
//! table that is linear in its vertices' coordinates interpolates to the
//! point's own coordinates (trilinear interpolation reproduces linear
//! functions), the interpolation weights form a partition of unity, the
//! gradient reaches the table as finite differences say, points outside
//! the domain take the nearest face's value, and a field with the encoding
//! renders finite values and learns its table.

mod common;

use burn::module::{Module, Param};
use burn::tensor::{Device, Tensor};
use common::{assert_close, camera_rays, devices, tensor, tiny_config, uniform, vec};
use model::{HashGrid, HashGridConfig, RenderRequest};

/// A one-level grid of `res` cells whose table holds, at the row of each
/// vertex, that vertex's position in the unit cube (x, y, z), so that the
/// encoding of a point is the point's own normalised position.
fn linear_grid(res: usize, half_extent: f32, device: &Device) -> HashGrid {
    let config = HashGridConfig::new()
        .with_levels(1)
        .with_features(3)
        .with_log2_table(12)
        .with_base_resolution(res)
        .with_max_resolution(res)
        .with_half_extent(half_extent);
    let mut grid = config.init(device);
    let side = res + 1;
    assert!(side * side * side <= grid.rows, "dense level");
    let mut table = vec![0f32; grid.rows * 3];
    for z in 0..side {
        for y in 0..side {
            for x in 0..side {
                // The dense layout: x fastest, then y, then z.
                let row = x + side * (y + side * z);
                table[3 * row] = x as f32 / res as f32;
                table[3 * row + 1] = y as f32 / res as f32;
                table[3 * row + 2] = z as f32 / res as f32;
            }
        }
    }
    grid.table = Param::from_tensor(tensor(table, [grid.rows, 3], device));
    grid
}

#[test]
fn a_table_linear_in_the_vertices_interpolates_to_the_point_itself() {
    for (name, device) in devices(false) {
        let half = 1.5f32;
        let grid = linear_grid(8, half, &device);
        let n = 200;
        let pts: Vec<f32> = uniform(3 * n, 7, -half as f64, half as f64)
            .into_iter()
            .map(|v| v as f32)
            .collect();
        let enc = vec(grid.forward(tensor(pts.clone(), [n, 3], &device)));
        let expected: Vec<f32> = pts
            .iter()
            .map(|&p| ((p as f64 / half as f64) * 0.5 + 0.5) as f32)
            .collect();
        assert_close(&enc, &expected, 1e-5, 0.0, name);
    }
}

#[test]
fn points_outside_the_domain_take_the_nearest_face() {
    let device = Device::flex();
    let grid = linear_grid(4, 1.0, &device);
    let pts = vec![5.0f32, -0.5, 1e9, -1e9, 0.0, 1.0];
    let enc = vec(grid.forward(tensor(pts, [2, 3], &device)));
    assert_close(&enc, &[1.0, 0.25, 1.0, 0.0, 0.5, 1.0], 1e-6, 0.0, "clamped");
}

#[test]
fn weights_are_a_partition_of_unity_and_rows_stay_in_their_level() {
    let device = Device::flex();
    let grid = HashGridConfig::new()
        .with_levels(6)
        .with_log2_table(10)
        .with_base_resolution(4)
        .with_max_resolution(512)
        .init(&device);
    assert_eq!(grid.resolutions.first(), Some(&4));
    assert_eq!(grid.resolutions.last(), Some(&512));
    assert!(grid.resolutions.windows(2).all(|w| w[0] < w[1]));
    let n = 300;
    let pts: Vec<f32> = uniform(3 * n, 3, -3.5, 3.5)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let (rows, weights) = grid.corners(&pts);
    assert_eq!(rows.len(), n * 6 * 8);
    for (i, (r, w)) in rows.chunks(8).zip(weights.chunks(8)).enumerate() {
        let level = (i % 6) as i64;
        let total: f64 = w.iter().map(|&v| v as f64).sum();
        assert!((total - 1.0).abs() < 1e-5, "weights sum to {total}");
        assert!(w.iter().all(|&v| (0.0..=1.0).contains(&v)));
        let range = level * grid.rows as i64..(level + 1) * grid.rows as i64;
        assert!(r.iter().all(|x| range.contains(x)), "level {level}: {r:?}");
    }
}

/// The corners as tensors on the device, against the host's: the same rows
/// bit for bit and the same weights, on dense and hashed levels, for points
/// inside, on the faces of and outside the domain.
#[test]
fn the_device_corners_are_the_host_corners() {
    let grid_on = |device: &Device| {
        HashGridConfig::new()
            .with_levels(8)
            .with_log2_table(10)
            .with_base_resolution(3)
            .with_max_resolution(2048)
            .with_half_extent(2.0)
            .init(device)
    };
    let n = 500;
    let mut pts: Vec<f32> = uniform(3 * n, 21, -2.5, 2.5)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    // Faces, corners and far outside.
    pts.extend([
        2.0, -2.0, 0.0, 2.0, 2.0, 2.0, -2.0, -2.0, -2.0, 1e6, -1e6, 0.5,
    ]);
    let n = pts.len() / 3;
    for (name, device) in devices(true) {
        let grid = grid_on(&device);
        let dense = grid
            .resolutions
            .iter()
            .filter(|&&r| ((r + 1) as usize).pow(3) <= grid.rows)
            .count();
        assert!(
            dense > 0 && dense < grid.resolutions.len(),
            "{name}: both kinds of level"
        );
        let (host_rows, host_weights) = grid.corners(&pts);
        let (rows, weights) = grid.corner_tensors(tensor(pts.clone(), [n, 3], &device));
        let rows: Vec<i64> = rows
            .into_data()
            .convert::<i64>()
            .try_to_vec::<i64>()
            .expect("rows as i64");
        assert_eq!(rows, host_rows, "{name}: rows");
        assert_close(&vec(weights), &host_weights, 1e-6, 0.0, name);
        // The encoding itself, in both forms (the one-pass form on the CPU
        // backends only): the host's corners gathered by hand against each.
        let points = tensor(pts.clone(), [n, 3], &device);
        let enc = vec(grid.forward_device(points.clone()));
        let cpu = model::host_work::is_cpu_backend(&device);
        if cpu {
            let fused = vec(grid.forward_fused(points.clone()));
            assert_eq!(enc, fused, "{name}: the two forms");
        }
        assert_eq!(vec(grid.forward(points)), enc, "{name}: forward");
        // The CPU backends take the one-pass form, wgpu the device's.
        assert_eq!(cpu, name != "wgpu", "{name}");
        let table = vec(grid.table.val());
        let f = grid.table.val().dims()[1];
        let mut expected = vec![0f32; n * grid.output_dim()];
        for (i, (r, w)) in host_rows.iter().zip(&host_weights).enumerate() {
            let (point, level) = (
                i / (8 * grid.resolutions.len()),
                (i / 8) % grid.resolutions.len(),
            );
            for c in 0..f {
                expected[point * grid.output_dim() + level * f + c] +=
                    w * table[*r as usize * f + c];
            }
        }
        assert_close(&enc, &expected, 1e-7, 1e-5, name);
    }
}

#[test]
fn the_gradient_reaches_the_table_as_finite_differences_say() {
    let base = Device::flex();
    let device: Device = base.clone().autodiff();
    device.seed(5);
    let grid = HashGridConfig::new()
        .with_levels(3)
        .with_log2_table(6)
        .with_base_resolution(2)
        .with_max_resolution(40)
        .init(&device);
    let n = 16;
    let pts: Vec<f32> = uniform(3 * n, 11, -3.0, 3.0)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let out_dim = grid.output_dim();
    let c: Vec<f32> = uniform(n * out_dim, 13, -1.0, 1.0)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let loss = |g: &HashGrid, d: &Device| -> Tensor<1> {
        let enc = g.forward(tensor(pts.clone(), [n, 3], d));
        enc.mul(tensor(c.clone(), [n, out_dim], d)).sum()
    };
    let grads = loss(&grid, &device).backward();
    let analytic = vec(grid.table.val().grad(&grads).expect("table gradient"));
    // The encoding is linear in the table: a central difference of step 1
    // on the plain device is exact up to rounding.
    let plain = grid.table.val().inner();
    let table = vec(plain.clone());
    let rows = table.len();
    let mut checked = 0;
    for k in (0..rows).step_by(7) {
        let bump = |delta: f32| {
            let mut t = table.clone();
            t[k] += delta;
            let mut g = grid.clone();
            g.table = Param::from_tensor(tensor(t, plain.dims(), &base));
            vec(loss(&g, &base))[0] as f64
        };
        let fd = (bump(1.0) - bump(-1.0)) / 2.0;
        assert!(
            (fd - analytic[k] as f64).abs() < 1e-4,
            "entry {k}: finite difference {fd}, gradient {}",
            analytic[k]
        );
        checked += 1;
    }
    assert!(checked > 10);
    assert!(analytic.iter().any(|&g| g != 0.0));
}

#[test]
fn a_field_with_the_encoding_renders_finite_values_and_learns_its_table() {
    let base = Device::flex();
    let device: Device = base.clone().autodiff();
    device.seed(2);
    let m = tiny_config()
        .with_num_samples(8)
        .with_hash(Some(
            HashGridConfig::new()
                .with_levels(4)
                .with_log2_table(8)
                .with_max_resolution(64),
        ))
        .init(&device);
    assert_eq!(m.hash.as_ref().map(HashGrid::output_dim), Some(8));
    let rays = camera_rays(5, 4);
    let out = m.render(&RenderRequest::train(&rays).with_randomized(false));
    let rgb = out.fine.rgb.clone();
    assert!(vec(rgb.clone().inner()).iter().all(|v| v.is_finite()));
    let grads = rgb.sum().backward();
    let table = m.hash.as_ref().expect("hash").table.val();
    let g = vec(table.grad(&grads).expect("the table gets a gradient"));
    assert!(g.iter().all(|v| v.is_finite()) && g.iter().any(|&v| v != 0.0));
    // The same field without autodiff renders the same colours.
    let plain = m.valid();
    let again = plain.render(&RenderRequest::train(&rays).with_randomized(false));
    assert_close(
        &vec(again.fine.rgb),
        &vec(out.fine.rgb.inner()),
        1e-6,
        1e-6,
        "valid",
    );
}

/// The CPU backends' one-pass encoding and its backward against the
/// tensor-op form: the same encoding bit for bit, the same table gradient
/// (the scatter-adds sum in another order), on flex and ndarray.
#[test]
fn the_fused_encoding_and_its_gradient_are_the_tensor_forms() {
    // In a pool of three threads the encoding's parallel tasks take 2048
    // points each (their least), so 4500 points are three, the last one
    // short.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .expect("a pool");
    let n = 4500;
    let pts: Vec<f32> = uniform(3 * n, 4, -3.5, 3.5)
        .into_iter()
        .map(|v| v as f32)
        .collect();
    for (name, base) in devices(false) {
        let device: Device = base.autodiff();
        device.seed(8);
        let grid = HashGridConfig::new()
            .with_levels(6)
            .with_log2_table(9)
            .with_base_resolution(2)
            .with_max_resolution(300)
            .init(&device);
        let c = tensor(
            uniform(n * grid.output_dim(), 5, -1.0, 1.0)
                .into_iter()
                .map(|v| v as f32)
                .collect(),
            [n, grid.output_dim()],
            &device,
        );
        let points = tensor(pts.clone(), [n, 3], &device);
        let fused = pool.install(|| grid.forward_fused(points.clone()));
        let plain = grid.forward_device(points);
        assert_eq!(vec(fused.clone()), vec(plain.clone()), "{name}: encoding");
        let grad = |enc: Tensor<2>| {
            let grads = enc.mul(c.clone()).sum().backward();
            vec(grid.table.val().grad(&grads).expect("a table gradient"))
        };
        let (g_fused, g_plain) = (pool.install(|| grad(fused)), grad(plain));
        assert!(g_plain.iter().any(|&g| g != 0.0));
        assert_close(&g_fused, &g_plain, 1e-6, 1e-5, name);
    }
}
