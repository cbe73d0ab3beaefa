//! End to end on the synthetic outdoor scene (objects under a backdrop 12 m
//! away, seen from a ring of cameras; its box holds the objects only): the
//! unbounded field `--field auto` chooses for it beats the box field on
//! held-out views at the same iterations, and a resumed run of the
//! unbounded field with the proposal sampler ends with the uninterrupted
//! run's weights, as do one with the unseen patches' depth smoothness
//! (which moves the weights), one that learns pose corrections and
//! appearance codes (which move) and one with the hash encoding (whose
//! tables learn); the fast field's held-out depth there is read as the
//! median depth, which the expected depth's far weight cannot pull out.

use std::sync::OnceLock;

use datasets::Scene;
use datasets::synthetic::{SceneSize, generate};
use tests::{max_abs_diff, run_weights, scratch_dir, serial, tiny_config};
use train::TrainConfig;
use train::settings::args::{FieldArg, SamplerArg};
use train::settings::choices::Flags;
use train::settings::table::{Extent, Sampler};
use train::settings::{choices_for, write};

fn outdoor() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| generate(0, SceneSize::Outdoor).expect("the outdoor scene generates"))
}

/// The tiny configuration with the field and sampler `field` and `sampler`
/// give on the outdoor scene.
fn config(field: FieldArg, sampler: SamplerArg, iterations: usize) -> TrainConfig {
    let scene = outdoor();
    let mut c = tiny_config(scene, iterations);
    let choices = choices_for(
        scene,
        &Flags {
            field,
            sampler,
            ..Flags::default()
        },
    );
    println!("{}", write::field_line(&choices));
    write::apply_field(&choices, &mut c.model, scene);
    c
}

#[test]
fn auto_contracts_the_outdoor_scene_and_beats_the_box() {
    let _guard = serial();
    let scene = outdoor();
    let auto = choices_for(scene, &Flags::default());
    assert!(
        auto.extent.value == Extent::Unbounded && auto.sampler().value == Sampler::CoarseFine,
        "{}",
        write::field_line(&auto)
    );
    let iterations = 300;
    let mut psnr = Vec::new();
    for field in [FieldArg::Box, FieldArg::Auto] {
        let dir = scratch_dir();
        let c = config(field, SamplerArg::Auto, iterations);
        let out = train::train_new(scene, c, 8, dir.path(), &tests::flex_session(None))
            .expect("training");
        println!("{field:?}: {:?}", out.summary.heldout_interior);
        psnr.push(out.summary.heldout_interior.psnr);
    }
    // The box renders black wherever a ray misses it (most of each view).
    assert!(
        psnr[1] > psnr[0] + 5.0,
        "unbounded {:.2} dB against box {:.2} dB",
        psnr[1],
        psnr[0]
    );
}

#[test]
fn an_unbounded_proposal_run_resumes_to_the_same_weights() {
    let _guard = serial();
    let scene = outdoor();
    let n = 10;
    let mut c = config(FieldArg::Unbounded, SamplerArg::Proposal, 2 * n);
    c.logging.eval_every = 0;
    c.logging.checkpoint_every = n;
    let whole = scratch_dir();
    train::train_new(
        scene,
        c.clone(),
        8,
        whole.path(),
        &tests::flex_session(None),
    )
    .expect("uninterrupted");
    let parts = scratch_dir();
    let half = train::train_new(scene, c, 8, parts.path(), &tests::flex_session(Some(n)))
        .expect("first half");
    assert_eq!(half.summary.iterations, n);
    let resumed = train::resume(parts.path(), None, &tests::flex_session(None)).expect("resumed");
    assert_eq!(resumed.summary.iterations, 2 * n);
    let (a, b) = (run_weights(whole.path()), run_weights(parts.path()));
    assert_eq!(a.len(), b.len());
    assert_eq!(max_abs_diff(&a, &b), 0.0, "the same weights, bit for bit");
}

#[test]
fn a_run_with_unseen_patches_resumes_to_the_same_weights_and_moves_them() {
    let _guard = serial();
    let scene = outdoor();
    let n = 4;
    let with_unseen = || {
        let mut c = config(FieldArg::Box, SamplerArg::Auto, 2 * n);
        c.logging.eval_every = 0;
        c.logging.checkpoint_every = n;
        c.losses.unseen_depth_weight = 10.0;
        c.losses.unseen_patches = 2;
        c.losses.unseen_patch_side = 4;
        c
    };
    let session = tests::flex_session(None);
    let (_whole, a) = resumes_bit_for_bit(scene, with_unseen, n);
    let mut plain = with_unseen();
    plain.losses.unseen_depth_weight = 0.0;
    let without = scratch_dir();
    train::train_new(scene, plain, 8, without.path(), &session).expect("without");
    let moved = max_abs_diff(&a, &run_weights(without.path()));
    assert!(moved > 0.0, "the regulariser changes the weights");
}

#[test]
fn a_run_with_pose_corrections_and_appearance_codes_resumes_to_the_same_weights() {
    let _guard = serial();
    let scene = outdoor();
    let n = 4;
    let frames = scene.frames.len();
    let with_both = || {
        let mut c = config(FieldArg::Unbounded, SamplerArg::Auto, 2 * n);
        c.logging.eval_every = 0;
        c.logging.checkpoint_every = n;
        c.model.pose = Some(model::PoseCorrectionConfig::new(frames));
        c.model.appearance = Some(model::AppearanceCodesConfig::new(frames).with_dim(4));
        c
    };
    let (whole, _) = resumes_bit_for_bit(scene, with_both, n);
    // The corrections and codes are among the weights, and they moved.
    let device = burn::tensor::Device::flex();
    let loaded = field_ops::run_dir::load_run(whole.path(), &device).expect("loads");
    for (name, values) in [
        ("pose", loaded.model.pose.as_ref().map(|p| p.params.val())),
        (
            "appearance",
            loaded.model.appearance.as_ref().map(|a| a.codes.val()),
        ),
    ] {
        let v: Vec<f32> = values
            .unwrap_or_else(|| panic!("{name} loaded"))
            .try_into_vec_as::<f32>()
            .expect("f32");
        assert!(v.iter().any(|&x| x != 0.0), "{name} moved");
    }
}

/// Trains `make()` for its iterations in one go, and again stopped after
/// `n` and resumed; asserts both end with the same weights, bit for bit.
/// Returns the uninterrupted run's directory and weights.
fn resumes_bit_for_bit(
    scene: &Scene,
    make: impl Fn() -> TrainConfig,
    n: usize,
) -> (tempfile::TempDir, Vec<f32>) {
    let whole = scratch_dir();
    let session = tests::flex_session(None);
    train::train_new(scene, make(), 8, whole.path(), &session).expect("uninterrupted");
    let parts = scratch_dir();
    let half = train::train_new(
        scene,
        make(),
        8,
        parts.path(),
        &tests::flex_session(Some(n)),
    )
    .expect("first half");
    assert_eq!(half.summary.iterations, n);
    train::resume(parts.path(), None, &session).expect("resumed");
    let (a, b) = (run_weights(whole.path()), run_weights(parts.path()));
    assert_eq!(max_abs_diff(&a, &b), 0.0, "the same weights, bit for bit");
    (whole, a)
}

#[test]
fn a_hash_grid_run_resumes_to_the_same_weights_and_learns_its_table() {
    let _guard = serial();
    let scene = outdoor();
    let n = 4;
    let with_hash = || {
        let mut c = config(FieldArg::Unbounded, SamplerArg::Auto, 2 * n);
        c.logging.eval_every = 0;
        c.logging.checkpoint_every = n;
        c.model.hash = Some(
            model::HashGridConfig::new()
                .with_levels(4)
                .with_log2_table(10)
                .with_max_resolution(128),
        );
        c
    };
    let (whole, _) = resumes_bit_for_bit(scene, with_hash, n);
    // The tables are among the weights and left their start (uniform in
    // +-1e-4): Adam's first steps move an entry by about the rate, 5e-3.
    let device = burn::tensor::Device::flex();
    let loaded = field_ops::run_dir::load_run(whole.path(), &device).expect("loads");
    let hash = loaded.model.hash.as_ref().expect("the hash grid loaded");
    assert_eq!(hash.resolutions.len(), 4);
    let table: Vec<f32> = hash.table.val().try_into_vec_as::<f32>().expect("f32");
    assert_eq!(table.len(), 4 * 1024 * 2);
    assert!(table.iter().all(|v| v.is_finite()));
    assert!(table.iter().any(|v| v.abs() > 1e-3), "the table learned");
}

/// The fast field trained on the outdoor scene leaves a little weight in the
/// last interval of its unbounded rays, 10,000 radii long: its held-out
/// views' expected depth is pulled metres out, their median depth stays
/// near the backdrop and the objects, and the held-out depth error `train`
/// reports is the median's.
#[test]
fn the_outdoor_depth_is_read_as_the_median() {
    let _guard = serial();
    let scene = outdoor();
    let mut c = config(FieldArg::Unbounded, SamplerArg::Proposal, 300);
    let grid = model::HashGridConfig::new()
        .with_levels(6)
        .with_log2_table(12)
        .with_max_resolution(128);
    c.model.fast = Some(model::FastFieldConfig::new().with_grid(grid.clone()));
    let proposal = c.model.proposal.take().expect("the proposal sampler");
    c.model.proposal = Some(
        proposal
            .with_samples(vec![32, 16])
            .with_hash(Some(grid.with_levels(3))),
    );
    c.model.num_samples = 16;
    let dir = scratch_dir();
    let out =
        train::train_new(scene, c, 8, dir.path(), &tests::flex_session(None)).expect("training");
    let reported = out.summary.heldout_interior.depth_mae.expect("depth");
    let device = burn::tensor::Device::flex();
    let run = field_ops::run_dir::load_run(dir.path(), &device).expect("loads");
    let (mut mean_err, mut median_err, mut n) = (0.0f64, 0.0f64, 0usize);
    for &f in &out.summary.heldout_frames {
        let frame = &scene.frames[f];
        let rays = field_ops::render::camera_rays(&frame.camera, &scene.scene_box);
        let r = run
            .model
            .render(&model::RenderRequest::inference(&rays))
            .expect("no observer");
        let depth = frame.depth.as_ref().expect("the outdoor scene has depth");
        let w = frame.camera.intrinsics.width;
        for (p, (mean, median)) in r.depth.iter().zip(&r.median_depth).enumerate() {
            let target = depth.get(p as u32 % w, p as u32 / w);
            if target > 0.0 {
                mean_err += (mean - target).abs() as f64;
                median_err += (median - target).abs() as f64;
                n += 1;
            }
        }
    }
    let (mean_err, median_err) = (mean_err / n as f64, median_err / n as f64);
    println!(
        "held-out depth error: expected {mean_err:.3} m, median {median_err:.3} m, reported {reported:.3} m"
    );
    assert!(
        median_err < 2.0 && mean_err > 3.0 * median_err,
        "expected depth {mean_err:.3} m, median {median_err:.3} m"
    );
    assert!(
        reported < 2.0 * median_err && reported < mean_err / 2.0,
        "reported {reported:.3} m: the median's is {median_err:.3} m, the mean's {mean_err:.3} m"
    );
}
