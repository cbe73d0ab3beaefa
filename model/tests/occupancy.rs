//! The occupancy grid against brute force: the cells a known density marks,
//! the occupied span of random rays against dense marching, rendering with
//! a grid that covers all the density against rendering without, the
//! update from the field's density, and the byte and hex formats. These tests use the grid without its conservative rules
//! (see `occupancy_conservative.rs` for those).

mod common;

use std::f64::consts::PI;

use burn::tensor::{Device, Tensor, TensorData};
use common::vec;
use model::composite::composite;
use model::geometry::NormalizedRay;
use model::{FeatureMode, RenderRequest};
use model::{GridDecodeError, OccupancyConfig, OccupancyGrid};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const SPHERE: f64 = 1.2;

fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol, "{what}: {a} vs {b}");
}

/// Density 50 inside a sphere of radius [`SPHERE`] about the origin, 0 outside.
fn sphere_density(p: [f32; 3]) -> f32 {
    let r2: f64 = p.iter().map(|&v| (v as f64) * (v as f64)).sum();
    if r2 <= SPHERE * SPHERE { 50.0 } else { 0.0 }
}

/// A grid under the rules before the conservative ones (the first update
/// decides alone, no dilation): the exact cells of these tests.
fn grid(resolution: usize) -> OccupancyGrid {
    let config = OccupancyConfig::new()
        .with_resolution(resolution)
        .with_early_samples(1)
        .with_early_updates(0)
        .with_dilation(0);
    OccupancyGrid::new(&config)
}

fn sphere_grid(resolution: usize, updates: u64) -> OccupancyGrid {
    let mut g = grid(resolution);
    for u in 0..updates {
        let d: Vec<f32> = g.sample_points(u).into_iter().map(sphere_density).collect();
        g.update(&d);
    }
    g
}

/// Nearest and farthest distance from the origin to points of cell `(i, j, k)`.
fn cell_distances(g: &OccupancyGrid, c: [usize; 3]) -> (f64, f64) {
    let h = g.cell_size();
    let (mut near2, mut far2) = (0.0, 0.0);
    for &ca in &c {
        let lo = -PI + ca as f64 * h;
        let hi = lo + h;
        let n = if lo > 0.0 {
            lo
        } else if hi < 0.0 {
            -hi
        } else {
            0.0
        };
        near2 += n * n;
        far2 += lo.abs().max(hi.abs()).powi(2);
    }
    (near2.sqrt(), far2.sqrt())
}

#[test]
fn a_sphere_of_density_marks_the_cells_inside_and_frees_those_outside() {
    let g = sphere_grid(16, 12);
    let r = g.resolution();
    let (mut inside, mut outside) = (0, 0);
    for k in 0..r {
        for j in 0..r {
            for i in 0..r {
                let (near, far) = cell_distances(&g, [i, j, k]);
                if far <= SPHERE {
                    inside += 1;
                    assert!(g.is_occupied(i, j, k), "cell {i},{j},{k} inside");
                } else if near > SPHERE {
                    outside += 1;
                    assert!(!g.is_occupied(i, j, k), "cell {i},{j},{k} outside");
                }
            }
        }
    }
    assert!(inside > 0 && outside > 0);
    // The sphere fills (4/3 pi 1.2^3) / (2 pi)^3 = 2.9 % of the cube; the
    // boundary cells add some.
    let f = g.occupied_fraction();
    assert!(f > 0.02 && f < 0.08, "occupied fraction {f}");
}

#[test]
fn decay_forgets_density_that_went_away() {
    let mut g = sphere_grid(8, 1);
    let before = g.occupied_fraction();
    assert!(before < 1.0);
    // The sphere vanishes except one cell: the others decay below the
    // threshold after enough updates, never at once.
    let cells = g.resolution().pow(3);
    let mut d = vec![0.0f32; cells];
    d[0] = 50.0;
    g.update(&d);
    assert!(
        g.occupied_fraction() >= before,
        "max with decay keeps old cells"
    );
    for _ in 0..400 {
        g.update(&d);
    }
    assert!(g.is_occupied(0, 0, 0));
    assert_eq!(g.occupied_fraction(), 1.0 / cells as f64);
}

#[test]
fn an_empty_field_falls_back_to_every_cell_and_nan_counts_as_occupied() {
    let mut g = grid(4);
    g.update(&[0.0; 64]);
    assert_eq!(
        g.occupied_fraction(),
        1.0,
        "no occupied cell: complete grid"
    );
    let mut d = [0.0f32; 64];
    d[5] = f32::NAN;
    d[9] = 1e3;
    let mut g = grid(4);
    g.update(&d);
    assert!(g.is_occupied(1, 1, 0) && g.is_occupied(1, 2, 0));
    assert_eq!(g.occupied_fraction(), 2.0 / 64.0);
}

fn random_ray(rng: &mut ChaCha8Rng) -> NormalizedRay {
    let mut r = || rng.random_range(-1.0f32..1.0);
    let mut origin = [3.5 * r(), 3.5 * r(), 3.5 * r()];
    // Aimed near the sphere, so that about half of the rays meet it.
    let target = [1.8 * r(), 1.8 * r(), 1.8 * r()];
    let mut direction = [0, 1, 2].map(|a| target[a] - origin[a]);
    // Some rays parallel to a plane or an axis, which the march must handle.
    let (u, v) = (r(), r());
    if u > 0.5 {
        origin[1] = target[1];
        direction[1] = 0.0;
    }
    if v > 0.7 {
        origin = [target[0], target[1], -3.5];
        direction = [0.0, 0.0, 3.5 + target[2]];
    }
    let scale = 0.5 + 0.5 * (r() + 1.0);
    let direction = direction.map(|d| d * scale);
    let near = 0.05 + 0.05 * (r() + 1.0);
    NormalizedRay {
        origin,
        direction,
        radius: 0.01,
        near,
        // Past the target, to 1.5 to 2 times its distance.
        far: (1.75 + 0.25 * r()) / scale,
    }
}

/// First and last `t` of a dense march whose point lies in an occupied cell.
fn marched_span(g: &OccupancyGrid, ray: &NormalizedRay, steps: usize) -> Option<(f64, f64)> {
    let h = g.cell_size();
    let r = g.resolution() as i64;
    let cell = |x: f64| (((x + PI) / h).floor() as i64).clamp(0, r - 1) as usize;
    let (near, far) = (ray.near as f64, ray.far as f64);
    let mut span: Option<(f64, f64)> = None;
    for s in 0..=steps {
        let t = near + (far - near) * s as f64 / steps as f64;
        let p: Vec<usize> = (0..3)
            .map(|a| cell(ray.origin[a] as f64 + t * ray.direction[a] as f64))
            .collect();
        if g.is_occupied(p[0], p[1], p[2]) {
            span = Some(span.map_or((t, t), |(a, _)| (a, t)));
        }
    }
    span
}

#[test]
fn the_occupied_span_matches_a_dense_march() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let g = sphere_grid(12, 3);
    let steps = 20_000;
    let (mut hits, mut misses) = (0, 0);
    for _ in 0..300 {
        let ray = random_ray(&mut rng);
        let tol = 2.0 * (ray.far - ray.near) as f64 / steps as f64;
        match (g.ray_span(&ray), marched_span(&g, &ray, steps)) {
            (Some((a, b)), Some((c, d))) => {
                hits += 1;
                assert!(a >= ray.near && b <= ray.far && a <= b);
                assert!((a as f64 - c).abs() <= tol + 1e-5, "near {a} vs {c}");
                assert!((b as f64 - d).abs() <= tol + 1e-5, "far {b} vs {d}");
            }
            (None, None) => misses += 1,
            (s, m) => panic!("span {s:?} but march {m:?} for {ray:?}"),
        }
    }
    assert!(hits > 30 && misses > 30, "hits {hits}, misses {misses}");
}

#[test]
fn a_complete_grid_leaves_every_ray_and_render_unchanged() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let rays: Vec<NormalizedRay> = (0..40).map(|_| random_ray(&mut rng)).collect();
    let g = grid(16);
    let clipped = g.clip(&rays);
    assert_eq!(clipped.rays, rays);
    assert_eq!(clipped.kept, (0..40).collect::<Vec<_>>());
    assert_close(clipped.span_fraction_sum, 40.0, 1e-9, "span fraction");
    let device = Device::flex();
    device.seed(1);
    let model = common::tiny_config().with_num_samples(8).init(&device);
    let render = |m: &model::OpenNerf, rays: &[NormalizedRay]| {
        let request = RenderRequest::train(rays)
            .with_randomized(false)
            .with_features(FeatureMode::Composited);
        m.render(&request)
    };
    let a = render(&model, &rays);
    let b = render(&model, &clipped.rays);
    // The same grid on the model: every ray kept, in place.
    let with = model.clone().with_occupancy(Some(g));
    let c = render(&with, &rays);
    assert_eq!(c.kept, None);
    let stats = c.clip.expect("the model's grid");
    assert_eq!((stats.drawn, stats.kept, stats.empty), (40, 40, 0));
    assert_eq!(vec(c.fine.rgb), vec(a.fine.rgb.clone()));
    assert_eq!(vec(a.fine.rgb), vec(b.fine.rgb));
    assert_eq!(vec(a.fine.feature.unwrap()), vec(b.fine.feature.unwrap()));
}

/// The update from the field queries its density at the grid's jittered
/// points (a quarter cell wide) and folds it in as an update with those
/// densities does.
#[test]
fn the_update_from_the_field_folds_in_its_density_at_the_jittered_points() {
    let device = Device::flex();
    device.seed(2);
    let model = common::tiny_config().init(&device);
    let mut by_field = grid(4);
    let mut by_hand = grid(4);
    for seed in [5, 6] {
        by_field.update_from_field(&model, seed);
        let points = by_hand.sample_points(seed);
        let flat: Vec<f32> = points.iter().flatten().copied().collect();
        let p = Tensor::<2>::from_data(TensorData::new(flat, [points.len(), 3]), &device);
        let radius = 0.25 * by_hand.cell_size() as f32;
        by_hand.update(&vec(model.query_density(p, radius)));
        assert_eq!(by_field, by_hand, "update with seed {seed}");
    }
    assert_eq!(by_field.updates(), 2);
}

/// Composites the sphere density along `ray` with `n` evenly spaced
/// samples: (opacity, depth).
fn quadrature(ray: &NormalizedRay, n: usize) -> (f64, f64) {
    let device = Device::flex();
    let (near, far) = (ray.near as f64, ray.far as f64);
    let t: Vec<f32> = (0..=n)
        .map(|i| (near + (far - near) * i as f64 / n as f64) as f32)
        .collect();
    let density: Vec<f32> = t
        .windows(2)
        .map(|w| {
            let m = 0.5 * (w[0] + w[1]);
            sphere_density([0, 1, 2].map(|a| ray.origin[a] + m * ray.direction[a]))
        })
        .collect();
    let dnorm: f32 = ray.direction.iter().map(|d| d * d).sum::<f32>().sqrt();
    let out = composite(
        Tensor::from_data(TensorData::new(density, [1, n]), &device),
        Tensor::<3>::ones([1, n, 3], &device),
        Tensor::from_data(TensorData::new(t, [1, n + 1]), &device),
        Tensor::from_data(TensorData::new(vec![dnorm], [1, 1]), &device),
        None,
    );
    (vec(out.acc)[0] as f64, vec(out.depth)[0] as f64)
}

/// A grid whose occupied cells are exactly those that meet the sphere (a
/// grid that is complete for it).
fn covering_grid(resolution: usize) -> OccupancyGrid {
    let mut g = grid(resolution);
    let r = resolution;
    let mut d = Vec::with_capacity(r * r * r);
    for k in 0..r {
        for j in 0..r {
            for i in 0..r {
                let near = cell_distances(&g, [i, j, k]).0;
                d.push(if near <= SPHERE { 50.0 } else { 0.0 });
            }
        }
    }
    g.update(&d);
    g
}

#[test]
fn rendering_inside_the_occupied_span_equals_rendering_the_whole_ray() {
    let g = covering_grid(16);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut compared = 0;
    for _ in 0..200 {
        let ray = random_ray(&mut rng);
        let whole = quadrature(&ray, 8192);
        match g.ray_span(&ray) {
            Some((near, far)) => {
                // The span holds all of the density: same opacity and depth
                // with far fewer samples spent on empty space.
                let clipped = quadrature(&NormalizedRay { near, far, ..ray }, 8192);
                assert_close(clipped.0, whole.0, 2e-3, "opacity");
                if whole.0 > 0.5 {
                    assert_close(clipped.1, whole.1, 2e-3, "depth");
                }
                compared += 1;
            }
            None => assert!(whole.0 < 1e-6, "a skipped ray must see nothing: {whole:?}"),
        }
    }
    assert!(compared > 20);
}

#[test]
fn bytes_round_trip_and_damage_is_named() {
    let g = sphere_grid(8, 2);
    let bytes = g.to_bytes();
    assert_eq!(OccupancyGrid::from_bytes(&bytes).unwrap(), g);
    let fresh = grid(8);
    assert_eq!(OccupancyGrid::from_bytes(&fresh.to_bytes()).unwrap(), fresh);
    for cut in [0, 7, 20, bytes.len() - 1] {
        assert!(
            OccupancyGrid::from_bytes(&bytes[..cut]).is_err(),
            "cut at {cut}"
        );
    }
    let mut bad = bytes.clone();
    bad[0] = b'X';
    assert!(
        OccupancyGrid::from_bytes(&bad)
            .unwrap_err()
            .contains("header")
    );
    // As hex: the same bytes, and the damage named by kind.
    assert_eq!(OccupancyGrid::from_hex(&g.to_hex()), Ok(g.clone()));
    assert!(g.to_hex().bytes().all(|c| c.is_ascii_hexdigit()));
    assert_eq!(
        OccupancyGrid::from_hex("abc"),
        Err(GridDecodeError::OddLength)
    );
    let not_hex = OccupancyGrid::from_hex("00zz").unwrap_err();
    assert_eq!(
        not_hex,
        GridDecodeError::NotHex {
            index: 1,
            text: "zz".into()
        }
    );
    assert_eq!(not_hex.to_string(), "byte 1: \"zz\" is not two hex digits");
    let cut = OccupancyGrid::from_hex(&g.to_hex()[..40]).unwrap_err();
    assert!(matches!(cut, GridDecodeError::Format(_)), "{cut:?}");
    assert!(cut.to_string().contains("header"), "{cut}");
}

#[test]
fn updates_follow_the_warmup_and_the_period() {
    let c = OccupancyConfig::new()
        .with_enabled(true)
        .with_warmup(10)
        .with_update_every(4);
    let due: Vec<usize> = (0..24).filter(|&i| c.update_due(i)).collect();
    assert_eq!(due, vec![10, 14, 18, 22]);
    assert!(!OccupancyConfig::new().update_due(300), "off by default");
}
