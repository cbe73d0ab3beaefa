//! Ray sampler: determinism, resume, border margin, targets and rays.

mod common;

use datasets::features::{FeatureSet, PcaSetting};
use datasets::sampler::{
    RaySampler, SamplerConfig, frame_rays, sample_batch, sample_batch_from, scaled_margin,
};
use datasets::{DepthImage, FeatureMap, Frame, RgbImage, Scene};
use half::f16;
use model::geometry::{Camera, Intrinsics, look_at};

/// Frame `i` encodes its pixel coordinates in the colour and depth, so a
/// target can be checked against the pixel it claims to come from.
fn frame(i: usize, w: u32, h: u32, depth: bool) -> Frame {
    let mut rgb = Vec::new();
    let mut d = Vec::new();
    for y in 0..h {
        for x in 0..w {
            rgb.extend([x as f32 / w as f32, y as f32 / h as f32, i as f32 / 10.0]);
            d.push(1.0 + x as f32 + 100.0 * y as f32);
        }
    }
    let pose = look_at([3.0, i as f64, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).expect("pose");
    Frame {
        name: format!("f{i}"),
        camera: Camera {
            intrinsics: Intrinsics::from_fov_x(w, h, 1.0),
            pose,
        },
        rgb: RgbImage {
            width: w,
            height: h,
            data: datasets::RgbData::F32(rgb),
        },
        depth: depth.then_some(DepthImage {
            width: w,
            height: h,
            data: datasets::DepthData::F32(d),
        }),
        depth_weight: 0.5 + i as f32,
        color_weight: 1.0,
        labels: None,
        mask: None,
    }
}

/// Map value at map pixel (x, y), channel c.
fn map_value(i: usize, x: u32, y: u32, c: usize) -> f32 {
    (i * 1000 + y as usize * 40 + x as usize) as f32 + 0.25 * c as f32
}

fn scene(with_features: bool) -> Scene {
    let frames = vec![
        frame(0, 40, 30, true),
        frame(1, 40, 30, false),
        frame(2, 24, 24, true),
    ];
    let features = with_features.then(|| {
        let maps = frames
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let (w, h) = (f.rgb.width / 2, f.rgb.height / 2);
                let mut data = Vec::new();
                for y in 0..h {
                    for x in 0..w {
                        data.extend((0..2).map(|c| f16::from_f32(map_value(i, x, y, c))));
                    }
                }
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
    common::scene_of("test", frames, features)
}

fn config() -> SamplerConfig {
    SamplerConfig {
        rays_per_batch: 512,
        border_margin: 10,
        min_near: 0.05,
        ..SamplerConfig::default()
    }
}

#[test]
fn batches_are_deterministic_and_resumable() {
    let s = scene(true);
    let mut a = RaySampler::new(config(), 7);
    let batches: Vec<_> = (0..3).map(|_| a.next_batch(&s).expect("batch")).collect();
    assert_eq!(a.batches_drawn(), 3);
    assert_ne!(batches[0].pixels, batches[1].pixels);
    let mut b = RaySampler::new(config(), 7);
    b.set_batches_drawn(2);
    assert_eq!(b.next_batch(&s).expect("batch"), batches[2]);
    assert_eq!(
        sample_batch(&config(), 7, &s, 1).expect("batch"),
        batches[1]
    );
    let other = RaySampler::new(config(), 8).next_batch(&s).expect("batch");
    assert_ne!(other.pixels, batches[0].pixels);
}

#[test]
fn pixels_respect_border_and_cover_frames_evenly() {
    let s = scene(false);
    // 60 px at a 360-px side: 5 px on the 40x30 frames, 4 px on the 24x24 one.
    let mut sampler = RaySampler::new(
        SamplerConfig {
            rays_per_batch: 6000,
            border_margin: 60,
            ..config()
        },
        1,
    );
    let b = sampler.next_batch(&s).expect("batch");
    let mut counts = [0usize; 3];
    let (mut xmin, mut xmax) = (u32::MAX, 0);
    for &[f, x, y] in &b.pixels {
        let img = &s.frames[f as usize].rgb;
        let m = scaled_margin(60, img.width, img.height);
        assert_eq!(m, if f == 2 { 4 } else { 5 });
        assert!(
            x >= m && x < img.width - m && y >= m && y < img.height - m,
            "{f} {x} {y}"
        );
        counts[f as usize] += 1;
        if f == 0 {
            xmin = xmin.min(x);
            xmax = xmax.max(x);
        }
    }
    // Every allowed column is reachable (5..35 for a 40-wide frame).
    assert_eq!((xmin, xmax), (5, 34));
    // Frames are drawn uniformly: 2000 expected each, sd ~ 37.
    for c in counts {
        assert!((c as f64 - 2000.0).abs() < 200.0, "{counts:?}");
    }
}

/// The margin is given for a 360-px shorter side and scales with the
/// image, so small images are not mostly border.
#[test]
fn the_margin_scales_with_the_image() {
    assert_eq!(scaled_margin(10, 640, 360), 10);
    assert_eq!(scaled_margin(10, 320, 180), 5);
    assert_eq!(scaled_margin(10, 96, 54), 2);
    assert_eq!(scaled_margin(10, 1200, 680), 19);
    assert_eq!(scaled_margin(0, 1200, 680), 0);
    // Never more than a quarter of the shorter side.
    assert_eq!(scaled_margin(10_000, 40, 30), 7);
}

/// Zero feature vectors (extractors write them where they have no
/// prediction) are not targets: rays there are masked, whether the maps are
/// stored at full dimension or PCA-compressed (where a zero vector would
/// otherwise compress to `-U m`, a valid-looking target), and they are left
/// out of the PCA fit.
#[test]
fn pixels_without_a_feature_target_are_masked() {
    for compress in [false, true] {
        let mut s = scene(true);
        let mut fs = s.features.take().expect("features");
        // Frame 0 has no prediction anywhere.
        fs.maps[0].data.iter_mut().for_each(|v| *v = f16::ZERO);
        let maps = fs.maps.clone();
        if compress {
            fs = FeatureSet::from_maps(maps.clone(), PcaSetting::Components(1), 0).expect("pca");
            // The fit saw every pixel of frames 1 and 2 and none of frame 0.
            let mut mean = [0f64; 2];
            let mut n = 0.0;
            for m in &maps[1..] {
                for px in m.data.chunks(2) {
                    mean[0] += px[0].to_f64();
                    mean[1] += px[1].to_f64();
                    n += 1.0;
                }
            }
            let pca = fs.pca.as_ref().expect("basis");
            for (c, (&sum, &got)) in mean.iter().zip(&pca.mean).enumerate() {
                let want = sum / n;
                assert!(
                    (got as f64 - want).abs() < 1e-3 * want.abs(),
                    "mean[{c}] {got} vs {want}"
                );
            }
        }
        s.features = Some(fs);
        let b = RaySampler::new(config(), 4).next_batch(&s).expect("batch");
        let mask = b.feature_mask.as_ref().expect("mask");
        let feats = b.features.as_ref().expect("features");
        let dim = b.feature_dim;
        for (k, &[f, _, _]) in b.pixels.iter().enumerate() {
            let row = &feats[k * dim..(k + 1) * dim];
            if f == 0 {
                assert_eq!(mask[k], 0.0, "compress {compress}");
                assert!(row.iter().all(|&v| v == 0.0));
            } else {
                assert_eq!(mask[k], 1.0, "compress {compress}");
                assert!(row.iter().all(|v| v.is_finite()));
            }
        }
        assert!(b.pixels.iter().any(|p| p[0] == 0));
    }
}

#[test]
fn targets_and_rays_match_their_pixels() {
    let s = scene(true);
    let b = RaySampler::new(config(), 3).next_batch(&s).expect("batch");
    let depth = b.depth.as_ref().expect("depth");
    let weight = b.depth_weight.as_ref().expect("weights");
    let feats = b.features.as_ref().expect("features");
    assert_eq!(b.feature_dim, 2);
    for (k, &[f, x, y]) in b.pixels.iter().enumerate() {
        let fr = &s.frames[f as usize];
        let (w, h) = (fr.rgb.width, fr.rgb.height);
        assert_eq!(
            b.rgb[k],
            [x as f32 / w as f32, y as f32 / h as f32, f as f32 / 10.0]
        );
        if f == 1 {
            assert_eq!((depth[k], weight[k]), (0.0, 0.0));
        } else {
            assert_eq!(depth[k], 1.0 + x as f32 + 100.0 * y as f32);
            assert_eq!(weight[k], 0.5 + f as f32);
        }
        // Half-resolution map: image pixel (x, y) lies in map pixel (x/2, y/2).
        for c in 0..2 {
            let want = f16::from_f32(map_value(f as usize, x / 2, y / 2, c)).to_f32();
            assert_eq!(feats[k * 2 + c], want);
        }
        let expect = s
            .scene_box
            .normalize_ray(&fr.camera.ray(x as f64, y as f64), 0.05);
        assert_eq!(b.rays[k], expect);
    }
}

#[test]
fn frame_rays_are_row_major() {
    let s = scene(false);
    let cam = s.frames[2].camera;
    let rays = frame_rays(&s.scene_box, &cam, 0.1);
    assert_eq!(rays.len(), 24 * 24);
    let (x, y) = (5u32, 17u32);
    let want = s.scene_box.normalize_ray(&cam.ray(x as f64, y as f64), 0.1);
    assert_eq!(rays[(y * 24 + x) as usize], want);
    // Rays from outside the box toward its centre start where they enter it.
    let centre = &rays[12 * 24 + 12];
    assert!(centre.far > centre.near && centre.near > 0.1);
}

#[test]
fn tiny_images_keep_pixels_to_draw() {
    let mut s = scene(false);
    s.frames = vec![frame(0, 3, 2, false)];
    let b = RaySampler::new(
        SamplerConfig {
            border_margin: 10_000,
            ..config()
        },
        0,
    )
    .next_batch(&s)
    .expect("batch");
    // The margin is capped at a quarter of the shorter side (0 here), so
    // every pixel of a 3x2 image can be drawn.
    for x in 0..3 {
        for y in 0..2 {
            assert!(b.pixels.iter().any(|p| p[1] == x && p[2] == y), "{x} {y}");
        }
    }
    s.frames.clear();
    let err = RaySampler::new(config(), 0)
        .next_batch(&s)
        .expect_err("no frames");
    assert!(err.to_string().contains("no frames"));
}

#[test]
fn a_frame_subset_is_respected_and_deterministic() {
    let s = scene(true);
    let subset = [0usize, 2];
    let batch = |seed: u64, index: u64| {
        sample_batch_from(&config(), seed, &s, &subset, index).expect("batch")
    };
    let b = batch(5, 3);
    assert_eq!(b.len(), 512);
    // Only listed frames are drawn, both of them, with the scene's indices.
    assert!(b.pixels.iter().all(|p| p[0] == 0 || p[0] == 2));
    assert!(b.pixels.iter().any(|p| p[0] == 0) && b.pixels.iter().any(|p| p[0] == 2));
    for (k, &[f, x, y]) in b.pixels.iter().enumerate() {
        let fr = &s.frames[f as usize];
        let m = scaled_margin(10, fr.rgb.width, fr.rgb.height);
        assert!(x >= m && x < fr.rgb.width - m && y >= m && y < fr.rgb.height - m);
        assert_eq!(b.rgb[k][2], f as f32 / 10.0);
        assert_eq!(b.depth_weight.as_ref().expect("weights")[k], 0.5 + f as f32);
    }
    // A pure function of (seed, index): same pair, same batch; either changed,
    // another batch; a sampler restricted to the subset resumes onto it.
    assert_eq!(batch(5, 3), b);
    assert_ne!(batch(5, 4).pixels, b.pixels);
    assert_ne!(batch(6, 3).pixels, b.pixels);
    let mut sampler = RaySampler::new(config(), 5).with_frames(subset.to_vec());
    sampler.set_batches_drawn(3);
    assert_eq!(sampler.next_batch(&s).expect("batch"), b);
    // Listing every frame gives the unrestricted batch.
    assert_eq!(
        sample_batch_from(&config(), 5, &s, &[0, 1, 2], 3).expect("batch"),
        sample_batch(&config(), 5, &s, 3).expect("batch")
    );
    // Frames without depth leave no depth targets even if others have some.
    let no_depth = sample_batch_from(&config(), 5, &s, &[1], 0).expect("batch");
    assert!(no_depth.depth.is_none() && no_depth.depth_weight.is_none());
    // Bad subsets are errors, not panics.
    let err = sample_batch_from(&config(), 5, &s, &[0, 3], 0).expect_err("out of range");
    assert!(err.to_string().contains("out of range"), "{err}");
    let err = sample_batch_from(&config(), 5, &s, &[], 0).expect_err("empty");
    assert!(err.to_string().contains("no frames"), "{err}");
}

/// Joining two batches keeps every ray with its own targets and fills what
/// one side lacks as the loss reads a missing target.
#[test]
fn appended_batches_keep_their_targets_and_fill_the_missing_ones() {
    let mut s = scene(true);
    s.frames[0].color_weight = 0.25;
    let cfg = SamplerConfig {
        rays_per_batch: 16,
        ..config()
    };
    // Frame 1 has no depth and weighs its colour 1; frame 0 has both.
    let mut a = sample_batch_from(&cfg, 3, &s, &[1], 0).expect("a");
    assert!(a.depth.is_none() && a.rgb_weight.is_none());
    let b = sample_batch_from(&cfg, 4, &s, &[0], 0).expect("b");
    assert!(b.depth.is_some() && b.rgb_weight.is_some());
    let (a0, b0) = (a.clone(), b.clone());
    a.append(b).expect("append");
    assert_eq!(a.len(), 32);
    assert_eq!(a.pixels[..16], a0.pixels[..]);
    assert_eq!(a.pixels[16..], b0.pixels[..]);
    assert_eq!(a.rgb[16..], b0.rgb[..]);
    let depth = a.depth.as_ref().expect("depth");
    let weight = a.depth_weight.as_ref().expect("weights");
    assert!(depth[..16].iter().chain(&weight[..16]).all(|&v| v == 0.0));
    assert_eq!(depth[16..], b0.depth.as_ref().expect("d")[..]);
    assert_eq!(weight[16..], b0.depth_weight.as_ref().expect("w")[..]);
    let rgb_weight = a.rgb_weight.as_ref().expect("colour weights");
    assert!(rgb_weight[..16].iter().all(|&w| w == 1.0));
    assert!(rgb_weight[16..].iter().all(|&w| w == 0.25));
    assert_eq!(a.features.as_ref().expect("f").len(), 32 * 2);
    assert_eq!(
        a.feature_mask.as_ref().expect("m")[16..],
        b0.feature_mask.as_ref().expect("m")[..]
    );
    // A batch without feature maps joins with no feature target.
    let bare = sample_batch_from(&cfg, 5, &scene(false), &[0], 0).expect("bare");
    assert!(bare.features.is_none());
    let mut with = b0.clone();
    with.append(bare).expect("append bare");
    assert_eq!(with.feature_dim, 2);
    assert_eq!(with.features.as_ref().expect("f").len(), 32 * 2);
    assert!(
        with.features.as_ref().expect("f")[32..]
            .iter()
            .all(|&v| v == 0.0)
    );
    assert!(
        with.feature_mask.as_ref().expect("m")[16..]
            .iter()
            .all(|&v| v == 0.0)
    );
    // Batches of different feature channels cannot be joined.
    let mut wide = b0.clone();
    wide.feature_dim = 3;
    wide.features = Some(vec![0.0; 16 * 3]);
    let e = a0.clone().append(wide).expect_err("channels");
    assert!(e.to_string().contains("feature channels"), "{e}");
}
