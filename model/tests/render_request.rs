//! The one rendering entry point, `OpenNerf::render`: the model's own grid
//! applied by both passes (as clipping by hand does, and ignored with
//! `GridUse::Off`), the training pass's kept rays and clip statistics with
//! its whole-batch and warm-up rules, cancellation through the observer,
//! and the dense and the marched fine level without termination.

mod common;

use std::cell::RefCell;

use burn::tensor::Device;
use common::{camera_rays, devices, vec};
use model::geometry::NormalizedRay;
use model::{
    Cancelled, FeatureMode, GridUse, OccupancyConfig, OccupancyGrid, OpenNerf, RenderRequest,
    Termination,
};

fn small(top_k: Option<usize>, device: &Device) -> OpenNerf {
    common::tiny_config()
        .with_num_samples(8)
        .with_head_top_k(top_k)
        .init(device)
}

/// The grid's rules before the conservative ones: the first update decides
/// alone, no dilation, rays over free space skipped at once.
fn plain(resolution: usize) -> OccupancyConfig {
    OccupancyConfig::new()
        .with_resolution(resolution)
        .with_early_samples(1)
        .with_early_updates(0)
        .with_dilation(0)
        .with_keep_dropped_updates(0)
}

/// A grid of `r^3` cells whose cells `(i, j, k)` with `dense(i, j, k)` hold
/// density.
fn grid_where(
    config: &OccupancyConfig,
    dense: impl Fn(usize, usize, usize) -> bool,
) -> OccupancyGrid {
    let mut g = OccupancyGrid::new(config);
    let r = g.resolution();
    let d: Vec<f32> = (0..r * r * r)
        .map(|c| {
            if dense(c % r, c / r % r, c / (r * r)) {
                10.0
            } else {
                0.0
            }
        })
        .collect();
    g.update(&d);
    g
}

/// Rays of three kinds: along +x from x = -4 (clipped by a grid of the
/// half x < 0 to their first half), along +z at x > 0 (crossing free cells
/// only) and along +z at x < 0 (occupied from end to end).
fn mixed_rays(n: usize) -> Vec<NormalizedRay> {
    (0..n)
        .map(|i| {
            let y = -2.0 + 0.3 * i as f32;
            let (origin, direction) = match i % 3 {
                0 => ([-4.0, y, 0.3], [1.0, 0.05, 0.0]),
                1 => ([1.5 + 0.1 * i as f32, y, -4.0], [0.0, 0.0, 1.0]),
                _ => ([-1.5 - 0.05 * i as f32, y, -4.0], [0.0, 0.02, 1.0]),
            };
            NormalizedRay {
                origin,
                direction,
                radius: 0.01,
                near: 0.5,
                far: 7.5,
            }
        })
        .collect()
}

/// Rays along +x at heights from -3 to 3: the low ones pass through the
/// lower half of the cube only.
fn rising_rays(n: usize) -> Vec<NormalizedRay> {
    (0..n)
        .map(|i| NormalizedRay {
            origin: [-4.0, -3.0 + 6.0 * i as f32 / (n - 1) as f32, 0.1],
            direction: [1.0, 0.0, 0.0],
            radius: 0.01,
            near: 1.0,
            far: 7.0,
        })
        .collect()
}

/// A grid that frees half of the scene (x > 0): both passes render what
/// clipping by hand and rendering the clipped rays without a grid renders;
/// the dropped rays show the background with zero depth, opacity and
/// feature; `GridUse::Off` renders as the model without its grid.
#[test]
fn render_applies_the_model_grid_as_clipping_by_hand_does() {
    let device = Device::flex();
    device.seed(3);
    let grid = grid_where(&plain(8), |i, _, _| i < 4);
    let bare = small(None, &device);
    let model = bare.clone().with_occupancy(Some(grid.clone()));
    let rays = mixed_rays(12);
    let clipped = grid.clip(&rays);
    let n = rays.len();
    assert!(!clipped.kept.is_empty() && clipped.kept.len() < n);
    let narrowed = clipped
        .kept
        .iter()
        .zip(&clipped.rays)
        .filter(|(i, r)| rays[**i] != **r)
        .count();
    assert!(narrowed > 0, "some kept rays are clipped");

    let background = [0.2, 0.4, 0.6];
    let bg = Some(background);
    let infer = |m: &OpenNerf, rays: &[NormalizedRay], grid: GridUse| {
        let request = RenderRequest::inference(rays)
            .with_chunk(5)
            .with_background(bg)
            .with_grid(grid);
        m.render(&request).expect("no observer")
    };
    let with = infer(&model, &rays, GridUse::Model);
    let by_hand = infer(&bare, &clipped.rays, GridUse::Model);
    let d = with.feature_dim;
    assert_eq!(d, 4);
    assert_eq!(with.samples_evaluated, by_hand.samples_evaluated);
    let mut at = vec![None; n];
    for (j, &i) in clipped.kept.iter().enumerate() {
        at[i] = Some(j);
    }
    for (i, j) in at.iter().enumerate() {
        let rgb = &with.rgb[3 * i..3 * i + 3];
        let feature = &with.feature[i * d..(i + 1) * d];
        match *j {
            Some(j) => {
                assert_eq!(rgb, &by_hand.rgb[3 * j..3 * j + 3], "ray {i}");
                assert_eq!(with.depth[i], by_hand.depth[j], "ray {i}");
                assert_eq!(with.acc[i], by_hand.acc[j], "ray {i}");
                assert_eq!(feature, &by_hand.feature[j * d..(j + 1) * d], "ray {i}");
            }
            None => {
                assert_eq!(rgb, &background, "dropped ray {i}");
                assert_eq!((with.depth[i], with.acc[i]), (0.0, 0.0), "ray {i}");
                assert!(feature.iter().all(|&f| f == 0.0), "ray {i}");
            }
        }
    }
    let off = infer(&model, &rays, GridUse::Off);
    assert_eq!(off, infer(&bare, &rays, GridUse::Model));
    assert_ne!(off.rgb, with.rgb, "the grid changes the render");

    // The training pass renders the kept rays, clipped, and says which.
    let dense = |m: &OpenNerf, rays: &[NormalizedRay], grid: GridUse| {
        m.render(
            &RenderRequest::train(rays)
                .with_randomized(false)
                .with_grid(grid),
        )
    };
    let train = dense(&model, &rays, GridUse::Model);
    assert_eq!(train.kept.as_ref(), Some(&clipped.kept));
    let stats = train.clip.expect("the model's grid");
    assert_eq!(stats.drawn, n);
    assert_eq!(stats.kept, clipped.kept.len());
    assert_eq!(stats.empty, n - clipped.kept.len());
    assert_eq!(stats.span_sum, clipped.span_fraction_sum);
    let hand = dense(&bare, &clipped.rays, GridUse::Model);
    assert_eq!(vec(train.fine.rgb), vec(hand.fine.rgb));
    assert_eq!(
        vec(train.coarse.as_ref().expect("coarse level").t_vals.clone()),
        vec(hand.coarse.as_ref().expect("coarse level").t_vals.clone())
    );
    let off = dense(&model, &rays, GridUse::Off);
    assert!(off.kept.is_none() && off.clip.is_none());
    assert_eq!(
        vec(off.fine.rgb),
        vec(dense(&bare, &rays, GridUse::Model).fine.rgb)
    );
}

/// A training batch in which no ray crosses an occupied cell is rendered
/// whole (an empty step teaches nothing).
#[test]
fn a_batch_that_misses_every_cell_is_rendered_whole() {
    let device = Device::flex();
    device.seed(4);
    // The top corner only.
    let grid = grid_where(&plain(4), |i, j, k| (i, j, k) == (3, 3, 3));
    let bare = small(None, &device);
    let model = bare.clone().with_occupancy(Some(grid));
    let mut low = rising_rays(3);
    for r in &mut low {
        r.origin[1] = -2.5;
    }
    let dense = |m: &OpenNerf, grid: GridUse| {
        m.render(
            &RenderRequest::train(&low)
                .with_randomized(false)
                .with_grid(grid),
        )
    };
    let out = dense(&model, GridUse::Model);
    assert_eq!(out.kept, None);
    let stats = out.clip.expect("the model's grid");
    assert_eq!((stats.drawn, stats.kept, stats.empty), (3, 3, 3));
    assert_eq!(stats.span_sum, 3.0);
    let whole = dense(&bare, GridUse::Model);
    assert_eq!(vec(out.fine.rgb), vec(whole.fine.rgb));
    assert_eq!(
        vec(out.coarse.as_ref().expect("coarse level").t_vals.clone()),
        vec(whole.coarse.as_ref().expect("coarse level").t_vals.clone())
    );
}

/// Training's warm-up rule: during the grid's first `keep_dropped_updates`
/// updates the rays that cross no occupied cell are rendered over their
/// whole span and in their place; after, they are dropped.
#[test]
fn rays_over_free_space_are_rendered_whole_during_the_warm_up_only() {
    let device = Device::flex();
    device.seed(5);
    // Density in the upper half only (y > 0): the low rays cross no
    // occupied cell.
    let config = plain(4).with_keep_dropped_updates(3);
    let mut grid = OccupancyGrid::new(&config);
    let d: Vec<f32> = (0..64)
        .map(|c| if (c / 4) % 4 >= 2 { 10.0 } else { 0.0 })
        .collect();
    let rays = rising_rays(9);
    let low = rays.iter().filter(|r| r.origin[1] < 0.0).count();
    assert!(low > 0 && low < 9);
    let bare = small(None, &device);
    for update in 1..=5 {
        grid.update(&d);
        let model = bare.clone().with_occupancy(Some(grid.clone()));
        let use_grid = GridUse::for_training(&config, model.occupancy());
        let out = model.render(
            &RenderRequest::train(&rays)
                .with_randomized(false)
                .with_grid(use_grid),
        );
        let stats = out.clip.expect("the model's grid");
        assert_eq!((stats.drawn, stats.empty), (9, low), "update {update}");
        assert_eq!(out.fine.rgb.dims()[0], stats.kept);
        if update < 3 {
            assert!(config.keeps_empty_rays(&grid));
            assert_eq!(use_grid, GridUse::KeepEmpty);
            // Every ray rendered, in its place; the empty ones over their
            // whole span.
            assert_eq!(stats.kept, 9, "update {update}");
            assert_eq!(out.kept, None);
            let posts = vec(out.coarse.as_ref().expect("coarse level").t_vals.clone());
            for (i, r) in rays.iter().enumerate() {
                if r.origin[1] < 0.0 {
                    let row = &posts[i * 9..(i + 1) * 9];
                    assert_eq!((row[0], row[8]), (r.near, r.far), "ray {i}");
                }
            }
            assert!(stats.span_sum > low as f64 && stats.span_sum <= 9.0);
        } else {
            assert!(!config.keeps_empty_rays(&grid));
            assert_eq!(use_grid, GridUse::Model);
            assert_eq!(stats.kept, 9 - low, "update {update}");
            let kept = out.kept.expect("the low rays dropped");
            assert_eq!(kept.len(), 9 - low);
            assert!(kept.iter().all(|&i| rays[i].origin[1] >= 0.0));
            assert!(stats.span_sum <= (9 - low) as f64);
        }
    }
}

/// The observer sees `(rays done, rays to render)` after every chunk, and
/// returning `false` stops the render after the first chunk.
#[test]
fn the_observer_follows_the_chunks_and_cancels_after_the_first() {
    let device = Device::flex();
    device.seed(6);
    let model = small(None, &device);
    let rays = camera_rays(12, 1);
    let seen = RefCell::new(Vec::new());
    let stop = |done: usize, total: usize| {
        seen.borrow_mut().push((done, total));
        false
    };
    let request = RenderRequest::inference(&rays).with_chunk(4);
    let cancelled = model.render(&request.with_observer(Some(&stop)));
    assert_eq!(cancelled, Err(Cancelled));
    assert_eq!(*seen.borrow(), vec![(4, 12)]);
    seen.borrow_mut().clear();
    let go = |done: usize, total: usize| {
        seen.borrow_mut().push((done, total));
        true
    };
    let done = model.render(&request.with_observer(Some(&go)));
    assert_eq!(*seen.borrow(), vec![(4, 12), (8, 12), (12, 12)]);
    assert_eq!(done, model.render(&request));
    assert_eq!(done.expect("not cancelled").depth.len(), 12);
}

/// Without termination the marched fine level is the dense one, exactly:
/// one segment from zero optical depth composites as the dense level does
/// (the top-k head's candidates start as zero weights, which add exact
/// zeros).
#[test]
fn dense_and_marched_agree_without_termination() {
    for (name, device) in devices(false) {
        device.seed(7);
        let rays = camera_rays(10, 2);
        let bg = Some([0.9, 0.1, 0.3]);
        for (top_k, mode) in [
            (None, FeatureMode::None),
            (None, FeatureMode::PerSample),
            (None, FeatureMode::Composited),
            (Some(3), FeatureMode::Composited),
        ] {
            let m = small(top_k, &device);
            let dense = m
                .render(
                    &RenderRequest::train(&rays)
                        .with_randomized(false)
                        .with_background(bg)
                        .with_features(mode),
                )
                .fine;
            let marched = m
                .render(
                    &RenderRequest::inference(&rays)
                        .with_termination(Termination::off())
                        .with_background(bg)
                        .with_features(mode),
                )
                .expect("no observer");
            let what = format!("{name} {mode:?} top-k {top_k:?}");
            assert_eq!(marched.samples_evaluated, 2 * 10 * 8, "{what}");
            assert_eq!(marched.rgb, vec(dense.rgb), "{what}");
            assert_eq!(marched.depth, vec(dense.depth), "{what}");
            assert_eq!(marched.acc, vec(dense.acc), "{what}");
            match dense.feature {
                None => assert!(marched.feature.is_empty(), "{what}"),
                Some(f) => assert_eq!(marched.feature, vec(f), "{what}"),
            }
        }
    }
}
