//! Rendering with early ray termination on a trained field: the CI room's
//! views render with the same PSNR (within 0.05 dB) and the same colours
//! and features as the plain deterministic render (every sample evaluated:
//! the dense pass, [`model::Train`] without jitter).

use burn::tensor::Device;
use field_ops::render::{camera_rays, tensor_to_vec};
use model::{FeatureMode, RenderRequest, Termination};
use tests::{ci_scene, flex_session as session, scratch_dir, serial, tiny_config};

/// PSNR of `a` against `b`.
fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let sq: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
        .sum();
    field_ops::metrics::psnr(sq / a.len() as f64)
}

/// The smallest cosine between corresponding `dim`-vectors of `a` and `b`.
fn worst_cosine(a: &[f32], b: &[f32], dim: usize) -> f64 {
    a.chunks(dim)
        .zip(b.chunks(dim))
        .map(|(a, b)| field_ops::metrics::cosine(a, b))
        .fold(1.0, f64::min)
}

#[test]
fn terminated_rays_render_the_trained_room_as_the_plain_render_does() {
    let _guard = serial();
    let scene = ci_scene();
    let mut config = tiny_config(scene, 400);
    config.logging.eval_every = 0;
    let dir = scratch_dir();
    train::train_new(scene, config, 4, dir.path(), &session(None)).unwrap();
    let device = Device::flex();
    let run = field_ops::run_dir::load_run(dir.path(), &device).unwrap();
    let bg = run.meta.background;
    for transmittance in [1e-4, 2e-2] {
        let term = Termination {
            transmittance,
            ..Termination::default()
        };
        for frame in scene.frames.iter().step_by(5) {
            let rays = camera_rays(&frame.camera, &run.meta.scene_box);
            let mode = FeatureMode::Composited;
            let fast = run
                .model
                .render(
                    &RenderRequest::inference(&rays)
                        .with_termination(term)
                        .with_features(mode)
                        .with_background(bg),
                )
                .expect("never cancelled without an observer");
            let dense = RenderRequest::train(&rays)
                .with_randomized(false)
                .with_features(mode)
                .with_background(bg);
            let plain = run.model.render(&dense).fine;
            let plain_rgb = tensor_to_vec(plain.rgb);
            let truth = &frame.rgb.to_f32();
            let (p_fast, p_plain) = (psnr(&fast.rgb, truth), psnr(&plain_rgb, truth));
            let what = format!("{} at {transmittance}", frame.name);
            assert!(
                (p_fast - p_plain).abs() < 0.05,
                "{what}: {p_fast:.3} dB terminated vs {p_plain:.3} dB"
            );
            let worst = fast
                .rgb
                .iter()
                .zip(&plain_rgb)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(worst < 0.05, "{what}: a colour moved by {worst}");
            let plain_feature = tensor_to_vec(plain.feature.expect("a feature head"));
            let cos = worst_cosine(&fast.feature, &plain_feature, fast.feature_dim);
            assert!(cos > 0.99, "{what}: feature cosine down to {cos}");
        }
    }
}
