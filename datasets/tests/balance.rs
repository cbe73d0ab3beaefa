//! Feature-balanced ray sampling against the closed-form shares of a scene
//! with one common and one rare feature.

mod common;

use datasets::balance::{BalanceConfig, BalancedSampler};
use datasets::features::{FeatureSet, PcaSetting};
use datasets::sampler::SamplerConfig;
use datasets::{FeatureMap, Frame, RgbImage, Scene};
use half::f16;
use model::geometry::{Camera, Intrinsics, look_at};

const W: u32 = 40;
/// The rare feature covers columns 0..4 of rows 0..20: 80 of 1600 pixels.
fn rare(x: u32, y: u32) -> bool {
    x < 4 && y < 20
}

fn scene() -> Scene {
    let frame = Frame {
        name: "f0".into(),
        camera: Camera {
            intrinsics: Intrinsics::from_fov_x(W, W, 1.0),
            pose: look_at([3.0, 0.0, 1.0], [0.0; 3], [0.0, 0.0, 1.0]).expect("pose"),
        },
        rgb: RgbImage {
            width: W,
            height: W,
            data: datasets::RgbData::F32(vec![0.5; (W * W * 3) as usize]),
        },
        depth: None,
        depth_weight: 1.0,
        color_weight: 1.0,
        labels: None,
        mask: None,
    };
    let mut data = Vec::new();
    for y in 0..W {
        for x in 0..W {
            let v = if rare(x, y) { [0.0, 1.0] } else { [1.0, 0.0] };
            data.extend(v.map(f16::from_f32));
        }
    }
    let map = FeatureMap {
        width: W,
        height: W,
        dim: 2,
        data,
    };
    common::scene_of(
        "balance",
        vec![frame],
        Some(FeatureSet::from_maps(vec![map], PcaSetting::Off, 0).expect("maps")),
    )
}

/// Share of rays on the rare feature for rarity exponent `power`:
/// `f^(1-p) / (f^(1-p) + (1-f)^(1-p))` with `f = 0.05`.
fn expected_share(power: f64) -> f64 {
    let f: f64 = 80.0 / 1600.0;
    let a = f.powf(1.0 - power);
    a / (a + (1.0 - f).powf(1.0 - power))
}

#[test]
fn rare_features_get_their_closed_form_share_of_rays() {
    let s = scene();
    let config = SamplerConfig {
        rays_per_batch: 20_000,
        border_margin: 0,
        min_near: 0.05,
        ..SamplerConfig::default()
    };
    let seed = 3;
    for power in [0.0, 0.5, 1.0] {
        let balance = BalanceConfig { clusters: 2, power };
        let sampler = BalancedSampler::new(&s, &[0], 0, &balance, 1)
            .expect("builds")
            .expect("features");
        let fr = &sampler.cluster_fractions;
        assert_eq!(fr.len(), 3, "two clusters and 'no target'");
        assert!(fr.iter().any(|&f| (f - 0.05).abs() < 1e-9), "{fr:?}");
        let b = sampler.batch(&config, seed, &s, 7);
        assert_eq!(
            b,
            sampler.batch(&config, seed, &s, 7),
            "a pure function of the index"
        );
        let feats = b.features.as_ref().expect("targets");
        let mut on_rare = 0usize;
        for (k, &[_, x, y]) in b.pixels.iter().enumerate() {
            // Each ray carries the target of the pixel it was drawn at.
            let want = if rare(x, y) { [0.0, 1.0] } else { [1.0, 0.0] };
            assert_eq!(&feats[2 * k..2 * k + 2], &want);
            on_rare += rare(x, y) as usize;
        }
        let share = on_rare as f64 / b.len() as f64;
        let want = expected_share(power);
        // Binomial standard deviation is below 0.0036 for these shares.
        assert!(
            (share - want).abs() < 0.015,
            "power {power}: share {share} vs {want}"
        );
    }
    assert!(expected_share(0.5) > 3.0 * expected_share(0.0));
}

#[test]
fn scenes_without_maps_or_bad_settings() {
    let mut s = scene();
    let ok = BalanceConfig {
        clusters: 4,
        power: 0.5,
    };
    for bad in [
        BalanceConfig { clusters: 0, ..ok },
        BalanceConfig {
            power: f64::NAN,
            ..ok
        },
        BalanceConfig { power: -1.0, ..ok },
    ] {
        assert!(
            BalancedSampler::new(&s, &[0], 10, &bad, 0).is_err(),
            "{bad:?}"
        );
    }
    assert!(
        BalancedSampler::new(&s, &[3], 10, &ok, 0).is_err(),
        "frame out of range"
    );
    s.features = None;
    assert!(
        BalancedSampler::new(&s, &[0], 10, &ok, 0)
            .expect("no error")
            .is_none()
    );
}
