//! Inference with early ray termination: segment-by-segment compositing
//! against a float64 oracle, the marcher (the inference pass) without
//! termination against the plain deterministic render (the dense pass
//! without jitter) in every feature mode, and an opaque field that ends its
//! rays early and still renders what the plain render does (the median
//! depth too, against the plain render's weights).

mod common;

use burn::module::Param;
use burn::tensor::{Device, Tensor};
use common::{assert_close, camera_rays, devices, tensor, vec};
use model::composite::segment_weights;
use model::geometry::NormalizedRay;
use model::{
    FeatureHeadConfig, FeatureMode, LevelOutputs, MipMlpConfig, OpenNerf, OpenNerfConfig,
    RenderRequest, RenderedRays, Termination,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn model(samples: usize, top_k: Option<usize>, device: &Device) -> OpenNerf {
    OpenNerfConfig::new(FeatureHeadConfig::new(5).with_width(16))
        .with_mlp(
            MipMlpConfig::new()
                .with_depth(4)
                .with_width(32)
                .with_skip_layer(2)
                .with_max_deg(8),
        )
        .with_num_samples(samples)
        .with_head_top_k(top_k)
        .init(device)
}

/// Segments composited in order give the weights of the whole ray
/// (`(1 - exp(-tau_i)) exp(-sum_{j<i} tau_j)` in float64) and its optical depth.
#[test]
fn chained_segments_equal_the_whole_ray() {
    let (rays, s) = (6, 10);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut density = vec![0.0f32; rays * s];
    let mut t = vec![0.0f32; rays * (s + 1)];
    for r in 0..rays {
        let mut acc = rng.random_range(0.0..1.0f32);
        for i in 0..=s {
            t[r * (s + 1) + i] = acc;
            acc += rng.random_range(0.0..0.4f32);
        }
        for i in 0..s {
            // Empty, moderate and opaque samples.
            density[r * s + i] = [0.0, rng.random_range(0.0..3.0), 40.0][rng.random_range(0..3)];
        }
    }
    let norms: Vec<f32> = (0..rays).map(|r| 0.5 + r as f32 * 0.3).collect();
    for (name, device) in devices(false) {
        let d = tensor(density.clone(), [rays, s], &device);
        let tv = tensor(t.clone(), [rays, s + 1], &device);
        let nrm = tensor(norms.clone(), [rays, 1], &device);
        let mut tau = Tensor::<2>::zeros([rays, 1], &device);
        let mut parts = Vec::new();
        for (a, b) in [(0, 3), (3, 4), (4, 10)] {
            let (w, after) = segment_weights(
                d.clone().slice_dim(1, a..b),
                tv.clone().slice_dim(1, a..b + 1),
                nrm.clone(),
                tau,
            );
            tau = after;
            parts.push(w);
        }
        let got = vec(Tensor::cat(parts, 1));
        let got_tau = vec(tau);
        for r in 0..rays {
            let mut before = 0.0f64;
            for i in 0..s {
                let delta = (t[r * (s + 1) + i + 1] - t[r * (s + 1) + i]) as f64 * norms[r] as f64;
                let tau_i = density[r * s + i] as f64 * delta;
                let w = (1.0 - (-tau_i).exp()) * (-before).exp();
                let g = got[r * s + i] as f64;
                assert!(
                    (g - w).abs() < 1e-6,
                    "{name} ray {r} sample {i}: {g} vs {w}"
                );
                before += tau_i;
            }
            let g = got_tau[r] as f64;
            assert!(
                (g - before).abs() < 1e-4 * before.max(1.0),
                "{name} tau {g} vs {before}"
            );
        }
    }
}

/// The fine level of the deterministic dense render of `rays`.
fn dense(
    m: &OpenNerf,
    rays: &[NormalizedRay],
    bg: Option<[f32; 3]>,
    mode: FeatureMode,
) -> LevelOutputs {
    let request = RenderRequest::train(rays)
        .with_randomized(false)
        .with_background(bg)
        .with_features(mode);
    m.render(&request).fine
}

/// The inference pass over `rays` in one chunk.
fn marched(
    m: &OpenNerf,
    rays: &[NormalizedRay],
    bg: Option<[f32; 3]>,
    mode: FeatureMode,
    termination: Termination,
) -> RenderedRays {
    let request = RenderRequest::inference(rays)
        .with_background(bg)
        .with_features(mode)
        .with_termination(termination);
    m.render(&request).expect("no observer")
}

/// The median depth of the dense level: its weights turned back into
/// optical depths in float64 (the weight reaches a half where the optical
/// depth reaches `ln 2`), or its expected depth where the weight never
/// reaches a half.
fn dense_median(want: &LevelOutputs) -> Vec<f32> {
    let (w, t, mean) = (
        vec(want.weights.clone()),
        vec(want.t_vals.clone()),
        vec(want.depth.clone()),
    );
    let n = mean.len();
    let s = w.len() / n;
    (0..n)
        .map(|r| {
            let mut ahead = 0.0f64;
            for i in 0..s {
                let wi = w[r * s + i] as f64;
                if ahead + wi >= 0.5 {
                    let trans = 1.0 - ahead;
                    let alpha = (wi / trans).min(1.0);
                    let f = if alpha >= 1.0 {
                        0.0
                    } else {
                        ((0.5 / trans).ln() / (1.0 - alpha).ln()).clamp(0.0, 1.0)
                    };
                    let (lo, hi) = (t[r * (s + 1) + i] as f64, t[r * (s + 1) + i + 1] as f64);
                    return (lo + f * (hi - lo)) as f32;
                }
                ahead += wi;
            }
            mean[r]
        })
        .collect()
}

fn compare(got: &RenderedRays, want: &LevelOutputs, tol: f32, what: &str) {
    assert_close(
        &got.rgb,
        &vec(want.rgb.clone()),
        tol,
        tol,
        &format!("{what} rgb"),
    );
    assert_close(
        &got.acc,
        &vec(want.acc.clone()),
        tol,
        tol,
        &format!("{what} acc"),
    );
    assert_close(
        &got.depth,
        &vec(want.depth.clone()),
        tol,
        tol,
        &format!("{what} depth"),
    );
    // The march finds the median from the densities, the oracle from the
    // weights in float32: good to about 1e-4 of the depth.
    let median_tol = tol.max(1e-4);
    assert_close(
        &got.median_depth,
        &dense_median(want),
        median_tol,
        median_tol,
        &format!("{what} median depth"),
    );
    match &want.feature {
        Some(f) => assert_close(
            &got.feature,
            &vec(f.clone()),
            tol,
            tol,
            &format!("{what} feature"),
        ),
        None => assert!(got.feature.is_empty(), "{what}: no feature asked for"),
    }
}

/// Without termination the marcher (segments of 5 of 12 samples, so the
/// last one is short) renders what the plain deterministic render does, in
/// every feature mode and with a background, evaluating every sample.
#[test]
fn without_termination_the_march_is_the_plain_render() {
    let bg = Some([0.2, 0.5, 0.9]);
    let off = Termination {
        transmittance: 0.0,
        segment: 5,
    };
    for (name, device) in devices(false) {
        device.seed(11);
        let rays = camera_rays(9, 2);
        for (top_k, mode) in [
            (None, FeatureMode::None),
            (None, FeatureMode::PerSample),
            (None, FeatureMode::Composited),
            (Some(4), FeatureMode::Composited),
        ] {
            let m = model(12, top_k, &device);
            let want = dense(&m, &rays, bg, mode);
            let got = marched(&m, &rays, bg, mode, off);
            let what = format!("{name} {mode:?} top-k {top_k:?}");
            compare(&got, &want, 2e-5, &what);
            assert_eq!(got.samples_evaluated, 2 * 9 * 12, "{what}: every sample");
            let whole = marched(&m, &rays, bg, mode, Termination::off());
            compare(&whole, &want, 2e-5, &format!("{what} one segment"));
        }
    }
}

/// A field made opaque (a large density bias) stops its rays within a few
/// samples, and what the march renders stays within a transmittance's
/// worth of the full render.
#[test]
fn an_opaque_field_ends_rays_early_and_renders_the_same() {
    for (name, device) in devices(false) {
        device.seed(5);
        let rays = camera_rays(16, 7);
        for (top_k, mode) in [
            (Some(4), FeatureMode::Composited),
            (None, FeatureMode::PerSample),
        ] {
            let mut m = model(16, top_k, &device);
            let bias = Tensor::<1>::from_data([12.0f32], &device);
            m.mlp.as_mut().expect("the Mip-NeRF field").density.bias =
                Some(Param::from_tensor(bias));
            let want = dense(&m, &rays, None, mode);
            let term = Termination {
                segment: 4,
                ..Termination::default()
            };
            let got = marched(&m, &rays, None, mode, term);
            let what = format!("{name} {mode:?}");
            let all = 2 * 16 * 16;
            assert!(
                got.samples_evaluated * 10 < all * 7,
                "{what}: {} of {all} samples evaluated",
                got.samples_evaluated
            );
            assert!(
                vec(want.acc.clone()).iter().all(|&a| a > 1.0 - 1e-4),
                "{what}: the field is opaque"
            );
            compare(&got, &want, 1e-3, &what);
        }
    }
}

/// No rays, no outputs.
#[test]
fn no_rays_render_nothing() {
    let device = Device::flex();
    let m = model(8, Some(2), &device);
    let got = marched(
        &m,
        &[],
        None,
        FeatureMode::Composited,
        Termination::default(),
    );
    assert!(got.rgb.is_empty() && got.feature.is_empty() && got.samples_evaluated == 0);
}
