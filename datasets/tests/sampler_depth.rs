//! Rays drawn from the pixels with a depth target (sparse depth: a few
//! pixels an image): which pixels qualify, and that the draws are uniform
//! over them and a pure function of the seed and the batch index.

mod common;

use datasets::sampler::{SamplerConfig, depth_pixels, sample_listed};
use datasets::{DepthImage, Frame, Scene};

/// A 40x30 grey frame (`common::grey_frame`) whose depth is set at
/// `targets` (`(x, y, depth)`) only, with pixel (20, 20) masked out.
fn frame(i: usize, targets: &[(u32, u32, f32)]) -> Frame {
    let (w, h) = (40u32, 30u32);
    let mut depth = vec![0.0; (w * h) as usize];
    for &(x, y, d) in targets {
        depth[(y * w + x) as usize] = d;
    }
    let mut mask = vec![true; (w * h) as usize];
    mask[(20 * w + 20) as usize] = false;
    Frame {
        depth: Some(DepthImage {
            width: w,
            height: h,
            data: datasets::DepthData::F32(depth),
        }),
        depth_weight: 1.0,
        ..common::grey_frame(i, w, h, Some(mask))
    }
}

fn scene() -> Scene {
    let frames = vec![
        // (1, 1) lies in the border margin, (20, 20) is masked out.
        frame(0, &[(5, 6, 2.0), (1, 1, 3.0), (20, 20, 4.0), (30, 12, 5.0)]),
        frame(1, &[(10, 10, 6.0)]),
        frame(2, &[(12, 8, 7.0), (13, 8, 8.0)]),
    ];
    common::scene_of("sparse", frames, None)
}

#[test]
fn depth_pixels_are_the_interior_unmasked_pixels_with_a_target() {
    let s = scene();
    // 10 px at a 360-px side is 1 px on a 30-px side: (1, 1) is inside.
    assert_eq!(
        depth_pixels(&s, &[0, 1, 2], 10),
        [
            (0, 1, 1),
            (0, 5, 6),
            (0, 30, 12),
            (1, 10, 10),
            (2, 12, 8),
            (2, 13, 8)
        ]
    );
    // 40 px is 3 px: (1, 1) is left out; frame 1 is not listed.
    assert_eq!(
        depth_pixels(&s, &[0, 2], 40),
        [(0, 5, 6), (0, 30, 12), (2, 12, 8), (2, 13, 8)]
    );
}

#[test]
fn listed_draws_are_uniform_seeded_and_carry_their_depth() {
    let s = scene();
    let frames = [0, 1, 2];
    let pixels = depth_pixels(&s, &frames, 40);
    let config = SamplerConfig::default();
    let draw = |seed, index| sample_listed(&config, seed, &s, &frames, &pixels, 3000, index);
    let b = draw(5, 0);
    assert_eq!(b.len(), 3000);
    assert_eq!(draw(5, 0), b);
    assert_ne!(draw(5, 1).pixels, b.pixels);
    assert_ne!(draw(6, 0).pixels, b.pixels);
    let depth = b.depth.as_ref().expect("depth");
    let mut counts = vec![0usize; pixels.len()];
    for (p, d) in b.pixels.iter().zip(depth) {
        let k = pixels
            .iter()
            .position(|&(f, x, y)| [f as u32, x, y] == *p)
            .expect("a listed pixel");
        counts[k] += 1;
        let frame = &s.frames[p[0] as usize];
        assert_eq!(*d, frame.depth.as_ref().expect("depth").get(p[1], p[2]));
        assert!(*d > 0.0);
    }
    // Uniform over the 5 pixels: 600 each, give or take 4 standard deviations.
    assert_eq!(counts.len(), 5);
    let sd = (3000.0f64 * 0.2 * 0.8).sqrt();
    for c in counts {
        assert!((c as f64 - 600.0).abs() < 4.0 * sd, "{c}");
    }
    assert!(sample_listed(&config, 5, &s, &frames, &[], 10, 0).is_empty());
}
