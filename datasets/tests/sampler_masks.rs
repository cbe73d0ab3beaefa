//! Frame masks: masked-out pixels are never drawn, by the uniform sampler
//! or the feature-balanced one, and every frame's unmasked part still is.

mod common;

use datasets::balance::{BalanceConfig, BalancedSampler};
use datasets::features::{FeatureSet, PcaSetting};
use datasets::sampler::{SamplerConfig, interior, sample_batch, sample_batch_from};
use datasets::{FeatureMap, Frame, Scene};
use half::f16;

/// Frame `i` keeps its right half (even frames) or bottom half (odd ones).
fn keep(i: usize, x: u32, y: u32, w: u32, h: u32) -> bool {
    if i.is_multiple_of(2) {
        x >= w / 2
    } else {
        y >= h / 2
    }
}

fn frame(i: usize, w: u32, h: u32) -> Frame {
    let mask = (0..h)
        .flat_map(|y| (0..w).map(move |x| keep(i, x, y, w, h)))
        .collect();
    common::grey_frame(i, w, h, Some(mask))
}

fn scene(features: bool) -> Scene {
    let frames: Vec<Frame> = (0..4).map(|i| frame(i, 40 + 8 * i as u32, 30)).collect();
    let features = features.then(|| {
        let maps = frames
            .iter()
            .map(|f| {
                let (w, h) = (f.rgb.width / 2, f.rgb.height / 2);
                // Two feature values: a rare corner and the rest.
                let data = (0..w * h)
                    .flat_map(|p| {
                        let v = if p % w < 3 && p / w < 3 { 1.0 } else { 0.0 };
                        [f16::from_f32(v), f16::from_f32(1.0 - v)]
                    })
                    .collect();
                FeatureMap {
                    width: w,
                    height: h,
                    dim: 2,
                    data,
                }
            })
            .collect();
        FeatureSet::from_maps(maps, PcaSetting::Off, 0).expect("maps")
    });
    common::scene_of("masked", frames, features)
}

fn config() -> SamplerConfig {
    SamplerConfig {
        rays_per_batch: 512,
        border_margin: 20,
        ..SamplerConfig::default()
    }
}

/// Checks that no pixel is masked or outside the interior, and that every
/// frame's unmasked interior is reached in all four quadrants of it.
fn check(s: &Scene, pixels: impl Iterator<Item = [u32; 3]>) {
    let mut seen = vec![[false; 4]; s.frames.len()];
    let mut n = 0;
    for [f, x, y] in pixels {
        let frame = &s.frames[f as usize];
        let (w, h) = (frame.rgb.width, frame.rgb.height);
        assert!(frame.is_target_pixel(x, y), "masked pixel {f} ({x}, {y})");
        assert!(keep(f as usize, x, y, w, h));
        let ((x0, x1), (y0, y1)) = interior(config().border_margin, w, h);
        assert!((x0..x1).contains(&x) && (y0..y1).contains(&y));
        // Which quarter of the unmasked interior the pixel is in.
        let (kx0, ky0) = if f.is_multiple_of(2) {
            (w / 2, y0)
        } else {
            (x0, h / 2)
        };
        let q = usize::from(x >= (kx0 + x1) / 2) + 2 * usize::from(y >= (ky0 + y1) / 2);
        seen[f as usize][q] = true;
        n += 1;
    }
    assert!(n > 0);
    for (f, quarters) in seen.iter().enumerate() {
        assert!(quarters.iter().all(|&q| q), "frame {f}: {quarters:?}");
    }
}

#[test]
fn uniform_batches_never_draw_masked_pixels() {
    let s = scene(false);
    let pixels: Vec<[u32; 3]> = (0..50)
        .flat_map(|b| sample_batch(&config(), 3, &s, b).expect("batch").pixels)
        .collect();
    check(&s, pixels.iter().copied());
    // A frame subset too.
    let sub = sample_batch_from(&config(), 3, &s, &[1, 2], 0).expect("batch");
    for &[f, x, y] in &sub.pixels {
        assert!(f == 1 || f == 2);
        assert!(s.frames[f as usize].is_target_pixel(x, y));
    }
    // The batch is still a pure function of (seed, index).
    assert_eq!(
        sample_batch(&config(), 3, &s, 7).expect("batch"),
        sample_batch(&config(), 3, &s, 7).expect("batch")
    );
}

#[test]
fn balanced_batches_never_draw_masked_pixels() {
    let s = scene(true);
    let frames: Vec<usize> = (0..4).collect();
    let balance = BalanceConfig {
        clusters: 2,
        power: 1.0,
    };
    let sampler = BalancedSampler::new(&s, &frames, config().border_margin, &balance, 5)
        .expect("sampler")
        .expect("features");
    let pixels: Vec<[u32; 3]> = (0..50)
        .flat_map(|b| sampler.batch(&config(), 5, &s, b).pixels)
        .collect();
    check(&s, pixels.into_iter());
}

#[test]
fn nearly_and_wholly_masked_frames() {
    let mut s = scene(false);
    // Frame 0 keeps one interior pixel, the others none: the rejection
    // draws give up and the listed pixel is drawn.
    for (i, f) in s.frames.iter_mut().enumerate() {
        let m = f.mask.as_mut().expect("mask");
        m.iter_mut().for_each(|v| *v = false);
        if i == 0 {
            m[15 * f.rgb.width as usize + 21] = true;
        }
    }
    let b = sample_batch(&config(), 1, &s, 0).expect("batch");
    assert!(
        b.pixels.iter().all(|&p| p == [0, 21, 15]),
        "{:?}",
        &b.pixels[..4]
    );
    s.frames[0].mask.as_mut().expect("mask")[15 * 40 + 21] = false;
    let err = sample_batch(&config(), 1, &s, 0).expect_err("all masked");
    assert!(err.to_string().contains("masked out"), "{err}");
    // A mask of the wrong size is refused.
    s.frames[1].mask = Some(vec![true; 3]);
    let err = sample_batch(&config(), 1, &s, 0).expect_err("bad mask");
    assert!(err.to_string().contains("mask does not match"), "{err}");
}
