//! End-to-end empty-space skipping: a run with the occupancy grid resumes
//! to the same weights and grid as an uninterrupted one, logs what it
//! skipped, and evaluation renders with the saved grid.

use std::path::Path;

use burn::tensor::Device;
use field_ops::render::ViewSettings;
use model::{OccupancyConfig, OccupancyGrid};
use tests::{
    ci_scene, flex_session as session, max_abs_diff, scratch_dir, serial, tiny_config, weights,
};

fn grid_of(dir: &Path) -> OccupancyGrid {
    OccupancyGrid::from_bytes(&std::fs::read(dir.join("occupancy.bin")).unwrap()).unwrap()
}

#[test]
fn a_grid_run_resumes_identically_and_evaluation_renders_with_its_grid() {
    let _guard = serial();
    let scene = ci_scene();
    let n = 30;
    let mut config = tiny_config(scene, 2 * n);
    config.logging.eval_every = 0;
    config.logging.checkpoint_every = n;
    config.logging.log_every = 5;
    config.occupancy = OccupancyConfig::new()
        .with_enabled(true)
        .with_resolution(16)
        .with_warmup(10)
        .with_update_every(5);
    let whole = scratch_dir();
    let a = train::train_new(scene, config.clone(), 4, whole.path(), &session(None)).unwrap();
    let parts = scratch_dir();
    train::train_new(scene, config, 4, parts.path(), &session(Some(n))).unwrap();
    // The grid at the stop is the one of iteration n, saved with its checkpoint.
    assert_eq!(
        grid_of(parts.path()).updates(),
        4,
        "updates at 10, 15, 20, 25"
    );
    let b = train::resume(parts.path(), None, &session(None)).unwrap();
    assert_eq!(a.summary.iterations, b.summary.iterations);

    let (ga, gb) = (grid_of(whole.path()), grid_of(parts.path()));
    assert_eq!(
        ga, gb,
        "the resumed run refreshed its grid as the uninterrupted one did"
    );
    assert_eq!(ga.updates(), 10, "updates at 10, 15, ..., 55");
    let load = |dir: &Path| field_ops::run_dir::load_run(dir, &Device::flex()).unwrap();
    let (ra, rb) = (load(whole.path()), load(parts.path()));
    assert_eq!(ra.model.occupancy(), Some(&ga));
    let wa = weights(&ra.model);
    let wb = weights(&rb.model);
    let max_diff = max_abs_diff(&wa, &wb);
    assert!(max_diff < 1e-4, "weights differ by up to {max_diff}");

    // Training lines report the skipping.
    let log = std::fs::read_to_string(whole.path().join("metrics.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = log
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .filter(|v: &serde_json::Value| v["event"] == "train")
        .collect();
    assert!(!lines.is_empty());
    for v in &lines {
        let f = |k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k} in {v}"));
        assert!(f("occupied_cells") > 0.0 && f("occupied_cells") <= 1.0);
        assert!(f("rays_rendered") > 0.0 && f("rays_rendered") <= 1.0);
        assert!(
            f("ray_length_sampled") > 0.0 && f("ray_length_sampled") <= f("rays_rendered") + 1e-9
        );
    }

    // Rendering a view: pixels whose ray crosses no occupied cell show the
    // background with zero opacity; the others are rendered by the field
    // over their clipped span.
    let frame = &scene.frames[1];
    let settings = ViewSettings::new(scene.background, 512).with_features(true);
    let render = |m: &model::OpenNerf| {
        field_ops::render::render_view(m, &frame.camera, &scene.scene_box, &settings)
            .expect("never cancelled without an observer")
    };
    let with = render(&ra.model);
    let rays = field_ops::render::camera_rays(&frame.camera, &scene.scene_box);
    let clipped = ga.clip(&rays);
    let without = render(&ra.model.clone().with_occupancy(None));
    // Index into the clipped rays of each input ray that was kept.
    let mut kept = vec![None; rays.len()];
    for (j, &i) in clipped.kept.iter().enumerate() {
        kept[i] = Some(j);
    }
    for (i, k) in kept.iter().enumerate() {
        let Some(j) = *k else {
            assert_eq!(with.acc[i], 0.0);
            assert_eq!(with.depth[i], 0.0);
            continue;
        };
        if clipped.rays[j] == rays[i] {
            // An unclipped ray renders as without the grid.
            for c in 3 * i..3 * i + 3 {
                assert!((with.rgb[c] - without.rgb[c]).abs() < 1e-5, "pixel {i}");
            }
        }
    }
}
