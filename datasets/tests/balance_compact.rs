//! The compact feature-balanced sampler against an independent copy of the
//! per-cell sampler it replaced (one record and one CDF entry per map cell):
//! the same clusters, the same distribution over pixels (chi-square tests
//! over clusters, frames and pixels), masked pixels never drawn, about 4
//! bytes a cell, and batches a pure function of `(seed, index)`.

mod common;

use std::collections::HashMap;

use datasets::balance::{BalanceConfig, BalancedSampler};
use datasets::features::{FeatureSet, PcaSetting};
use datasets::sampler::{SamplerConfig, interior};
use datasets::{FeatureMap, Frame, Scene};
use half::f16;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Channels per map pixel: more than the sampler's 16 distance lanes, so
/// that its vectorised distance is the one compared.
const DIM: usize = 20;
const MARGIN: u32 = 20;

/// A deterministic hash of `(a, b, c)` in `[0, 1)`.
fn hash(a: u32, b: u32, c: u32) -> f32 {
    let mut z = (a as u64) << 42 ^ (b as u64) << 21 ^ c as u64;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

/// Which of five features map pixel `(x, y)` of a `w x h` map of frame `i`
/// carries: a common background, a band, a blob, a rare corner and (for
/// `None`) no target at all.
fn feature(i: usize, x: u32, y: u32, w: u32, h: u32) -> Option<usize> {
    if i == 0 && x == w - 3 && y < 4 {
        return None;
    }
    Some(if x < 2 && y < 2 {
        3
    } else if (x + 2 * y + i as u32).is_multiple_of(7) {
        1
    } else if x > w / 2 && y > h / 2 && x < w / 2 + 4 {
        2
    } else {
        0
    })
}

fn map(i: usize, w: u32, h: u32) -> FeatureMap {
    let mut data = Vec::with_capacity((w * h) as usize * DIM);
    for y in 0..h {
        for x in 0..w {
            for c in 0..DIM {
                let v = match feature(i, x, y, w, h) {
                    None => 0.0,
                    Some(f) => {
                        let on = (c % 5 == f) as u8 as f32;
                        on + 0.05 * hash(i as u32 * 1000 + x, y, c as u32)
                    }
                };
                data.push(f16::from_f32(v));
            }
        }
    }
    FeatureMap {
        width: w,
        height: h,
        dim: DIM,
        data,
    }
}

/// Frame 1's mask: a diagonal cut through cells and a wholly masked block.
fn keep(x: u32, y: u32) -> bool {
    x + y > 20 && !((24..34).contains(&x) && (4..14).contains(&y))
}

/// An image size and its map's, `None` for a frame without a map.
type FrameSize = ((u32, u32), Option<(u32, u32)>);

/// Frames of `sizes`, frame 1 masked with [`keep`] when
/// `masked`; frames past the maps given have no map.
fn scene(sizes: &[FrameSize], masked: bool) -> Scene {
    let frames: Vec<Frame> = sizes
        .iter()
        .enumerate()
        .map(|(i, &((w, h), _))| {
            let mask = (masked && i == 1).then(|| {
                (0..h)
                    .flat_map(|y| (0..w).map(move |x| keep(x, y)))
                    .collect()
            });
            common::grey_frame(i, w, h, mask)
        })
        .collect();
    let maps = sizes
        .iter()
        .enumerate()
        .map_while(|(i, &(_, m))| m.map(|(w, h)| map(i, w, h)))
        .collect();
    common::scene_of(
        "balance-compact",
        frames,
        Some(FeatureSet::from_maps(maps, PcaSetting::Off, 0).expect("maps")),
    )
}

/// Maps coarser than the images (cells of 2 to 4 pixels a side), a mask on
/// frame 1, two frames of one geometry and a last frame without a map.
fn small_scene() -> Scene {
    scene(
        &[
            ((48, 36), Some((20, 15))),
            ((40, 30), Some((13, 10))),
            ((48, 36), Some((20, 15))),
            ((30, 30), None),
        ],
        true,
    )
}

/// `(frame, x range, y range, unmasked pixels)` of a cell.
type OldCell = (usize, (u32, u32), (u32, u32), u32);

/// The per-cell sampler as it was, written plainly: every cell of every
/// frame with its pixels, cluster and weight.
struct Oracle {
    /// Every cell drawn from.
    cells: Vec<OldCell>,
    cluster: Vec<usize>,
    weight: Vec<f64>,
    share: Vec<f64>,
}

fn old_spans(image_len: u32, map_len: u32, lo: u32, hi: u32) -> Vec<(u32, u32, u32)> {
    let mut out: Vec<(u32, u32, u32)> = Vec::new();
    for p in lo..hi {
        let m = (((p as f64 + 0.5) * map_len as f64 / image_len as f64).floor() as u32)
            .min(map_len - 1);
        match out.last_mut() {
            Some(last) if last.0 == m => last.2 = p + 1,
            _ => out.push((m, p, p + 1)),
        }
    }
    out
}

fn old_nearest(v: &[f32], centres: &[f32], dim: usize) -> usize {
    let mut best = (0, f32::INFINITY);
    for (c, centre) in centres.chunks_exact(dim).enumerate() {
        let d: f32 = v.iter().zip(centre).map(|(x, y)| (x - y) * (x - y)).sum();
        if d < best.1 {
            best = (c, d);
        }
    }
    best.0
}

fn old_kmeans(fit: &[Vec<f32>], k: usize, dim: usize) -> Vec<f32> {
    let mut centres: Vec<f32> = Vec::new();
    for i in 0..k.min(fit.len()) {
        centres.extend_from_slice(&fit[i * fit.len() / k.min(fit.len())]);
    }
    let k = centres.len() / dim;
    for _ in 0..10 {
        let mut sums = vec![0f64; k * dim];
        let mut counts = vec![0usize; k];
        for v in fit {
            let c = old_nearest(v, &centres, dim);
            counts[c] += 1;
            for (s, &x) in sums[c * dim..(c + 1) * dim].iter_mut().zip(v) {
                *s += x as f64;
            }
        }
        for c in 0..k {
            if counts[c] > 0 {
                for j in 0..dim {
                    centres[c * dim + j] = (sums[c * dim + j] / counts[c] as f64) as f32;
                }
            }
        }
    }
    centres
}

fn oracle(s: &Scene, frames: &[usize], balance: &BalanceConfig, seed: u64) -> Oracle {
    let fs = s.features.as_ref().expect("features");
    let mut cells = Vec::new();
    let mut target: Vec<Option<Vec<f32>>> = Vec::new();
    for &fi in frames {
        let f = &s.frames[fi];
        let (w, h) = (f.rgb.width, f.rgb.height);
        let ((x0, x1), (y0, y1)) = interior(MARGIN, w, h);
        let m = fs.maps.get(fi);
        let (mw, mh) = m.map_or((w, h), |m| (m.width, m.height));
        for (my, ya, yb) in old_spans(h, mh, y0, y1) {
            for (mx, xa, xb) in old_spans(w, mw, x0, x1) {
                let px = (ya..yb)
                    .flat_map(|y| (xa..xb).map(move |x| (x, y)))
                    .filter(|&(x, y)| f.is_target_pixel(x, y))
                    .count() as u32;
                if px == 0 {
                    continue;
                }
                cells.push((fi, (xa, xb), (ya, yb), px));
                let v = m.map(|m| m.pixel(mx, my)).filter(|v| fs.is_target(v));
                target.push(v.map(|v| v.iter().map(|x| x.to_f32()).collect()));
            }
        }
    }
    let valid: Vec<usize> = (0..cells.len()).filter(|&i| target[i].is_some()).collect();
    let k = balance.clusters.min(valid.len()).max(1);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xba1a_9ce5);
    let fit: Vec<Vec<f32>> = (0..16_384.min(valid.len()))
        .filter_map(|_| target[valid[rng.random_range(0..valid.len())]].clone())
        .collect();
    let centres = old_kmeans(&fit, k, DIM);
    let k = centres.len() / DIM;
    let cluster: Vec<usize> = target
        .iter()
        .map(|t| t.as_ref().map_or(k, |v| old_nearest(v, &centres, DIM)))
        .collect();
    let mut share = vec![0f64; k + 1];
    for (c, &g) in cells.iter().zip(&cluster) {
        share[g] += c.3 as f64;
    }
    let total: f64 = share.iter().sum::<f64>().max(1.0);
    share.iter_mut().for_each(|x| *x /= total);
    let weight = cells
        .iter()
        .zip(&cluster)
        .map(|(c, &g)| c.3 as f64 * share[g].max(1e-12).powf(-balance.power))
        .collect();
    Oracle {
        cells,
        cluster,
        weight,
        share,
    }
}

/// The 0.999 quantile of the chi-square distribution with `df` degrees of
/// freedom (Wilson–Hilferty).
fn chi2_999(df: usize) -> f64 {
    let z = 3.090_232_306;
    let d = df as f64;
    let a = 2.0 / (9.0 * d);
    d * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Pearson's statistic of `observed` counts against probabilities `p`
/// (bins expected below 5 pooled into one) and its degrees of freedom.
/// A draw in a bin of probability 0 fails.
fn chi2(observed: &[u64], p: &[f64]) -> (f64, usize) {
    let n: u64 = observed.iter().sum();
    let (mut stat, mut bins) = (0.0, 0usize);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (&o, &q) in observed.iter().zip(p) {
        let e = q * n as f64;
        assert!(e > 0.0 || o == 0, "{o} draws in a bin of probability 0");
        if e >= 5.0 {
            stat += (o as f64 - e).powi(2) / e;
            bins += 1;
        } else {
            pool_o += o as f64;
            pool_e += e;
        }
    }
    if pool_e > 0.0 {
        stat += (pool_o - pool_e).powi(2) / pool_e;
        bins += 1;
    }
    (stat, bins - 1)
}

#[test]
fn draws_the_distribution_of_the_per_cell_sampler() {
    let s = small_scene();
    let frames = [0, 1, 2, 3];
    for (power, clusters) in [(1.0, 4), (0.5, 6)] {
        let balance = BalanceConfig { clusters, power };
        let seed = 11;
        let old = oracle(&s, &frames, &balance, seed);
        let new = BalancedSampler::new(&s, &frames, MARGIN, &balance, seed)
            .expect("builds")
            .expect("features");
        assert_eq!(new.cluster_fractions, old.share, "the same clusters");
        let k = old.share.len();

        // Which oracle cell each pixel is in, and the oracle probabilities.
        let mut cell_at: HashMap<(usize, u32, u32), usize> = HashMap::new();
        for (c, &(fi, (xa, xb), (ya, yb), _)) in old.cells.iter().enumerate() {
            for y in ya..yb {
                for x in xa..xb {
                    cell_at.insert((fi, x, y), c);
                }
            }
        }
        let total: f64 = old.weight.iter().sum();
        let mut p_cluster = vec![0.0; k];
        let mut p_frame = vec![0.0; frames.len()];
        for (c, &w) in old.weight.iter().enumerate() {
            p_cluster[old.cluster[c]] += w / total;
            p_frame[old.cells[c].0] += w / total;
        }
        // Pixels: unmasked ones of each cell share its weight equally.
        let mut pixel_index: HashMap<(usize, u32, u32), usize> = HashMap::new();
        let mut p_pixel = Vec::new();
        for (&(fi, x, y), &c) in &cell_at {
            if s.frames[fi].is_target_pixel(x, y) {
                pixel_index.insert((fi, x, y), p_pixel.len());
                p_pixel.push(old.weight[c] / old.cells[c].3 as f64 / total);
            }
        }

        let config = SamplerConfig {
            rays_per_batch: 4000,
            border_margin: MARGIN,
            ..SamplerConfig::default()
        };
        let mut n_cluster = vec![0u64; k];
        let mut n_frame = vec![0u64; frames.len()];
        let mut n_pixel = vec![0u64; p_pixel.len()];
        for b in 0..50 {
            for &[f, x, y] in &new.batch(&config, seed, &s, b).pixels {
                let key = (f as usize, x, y);
                assert!(s.frames[key.0].is_target_pixel(x, y), "masked {key:?}");
                let c = *cell_at.get(&key).expect("a pixel of a drawn cell");
                n_cluster[old.cluster[c]] += 1;
                n_frame[key.0] += 1;
                n_pixel[pixel_index[&key]] += 1;
            }
        }
        for (what, observed, p) in [
            ("clusters", &n_cluster, &p_cluster),
            ("frames", &n_frame, &p_frame),
            ("pixels", &n_pixel, &p_pixel),
        ] {
            let (stat, df) = chi2(observed, p);
            let limit = chi2_999(df);
            println!(
                "power {power}, {what}: chi2 {stat:.2} on {df} df (0.999 quantile {limit:.2})"
            );
            assert!(stat < limit, "power {power}, {what}: {stat} >= {limit}");
        }
    }
}

#[test]
fn wholly_masked_cells_are_never_drawn() {
    let s = small_scene();
    let balance = BalanceConfig {
        clusters: 4,
        power: 1.0,
    };
    let sampler = BalancedSampler::new(&s, &[1], MARGIN, &balance, 2)
        .expect("builds")
        .expect("features");
    let config = SamplerConfig {
        rays_per_batch: 5000,
        border_margin: MARGIN,
        ..SamplerConfig::default()
    };
    let mut partly_masked = 0;
    for b in 0..10 {
        for &[f, x, y] in &sampler.batch(&config, 4, &s, b).pixels {
            assert_eq!(f, 1);
            assert!(keep(x, y), "masked pixel ({x}, {y})");
            // Beside the diagonal: cells the cut goes through.
            partly_masked += usize::from(x + y <= 23);
        }
    }
    assert!(partly_masked > 0, "the unmasked part of cut cells is drawn");
    // A frame masked everywhere has nothing to draw.
    let mut all = small_scene();
    all.frames[1].mask = Some(vec![false; 40 * 30]);
    let err = BalancedSampler::new(&all, &[1], MARGIN, &balance, 2).expect_err("all masked");
    assert!(err.to_string().contains("masked out"), "{err}");
}

#[test]
fn memory_is_four_bytes_a_cell() {
    // Full-resolution maps (a cell per pixel) as in the paper's setting,
    // and coarse ones; no masks.
    for (image, map) in [((120, 90), (120, 90)), ((120, 90), (50, 36))] {
        let s = scene(&[(image, Some(map)); 4], false);
        let frames = [0, 1, 2, 3];
        let balance = BalanceConfig {
            clusters: 8,
            power: 1.0,
        };
        let old = oracle(&s, &frames, &balance, 3);
        let n = old.cells.len();
        let sampler = BalancedSampler::new(&s, &frames, MARGIN, &balance, 3)
            .expect("builds")
            .expect("features");
        // Enough cells for the assignment to run on several threads.
        assert_eq!(sampler.cluster_fractions, old.share);
        let bytes = sampler.memory_bytes();
        // Frames and clusters cost a few dozen bytes each; the one grid
        // these frames share holds a span per map row and column.
        let overhead = 256 * (frames.len() + balance.clusters + 1) + 12 * (map.0 + map.1) as usize;
        println!(
            "{n} cells ({map:?} maps): {bytes} bytes, {:.3} a cell (the per-cell sampler held 40)",
            bytes as f64 / n as f64
        );
        assert!(bytes >= 4 * n, "{bytes} for {n} cells");
        assert!(bytes <= 4 * n + overhead, "{bytes} for {n} cells");
    }
}

#[test]
fn batches_are_a_pure_function_of_seed_and_index() {
    let s = small_scene();
    let frames = [0, 1, 2, 3];
    let balance = BalanceConfig {
        clusters: 4,
        power: 1.0,
    };
    let build = || {
        BalancedSampler::new(&s, &frames, MARGIN, &balance, 9)
            .expect("builds")
            .expect("features")
    };
    let (a, b) = (build(), build());
    assert_eq!(a.cluster_fractions, b.cluster_fractions);
    let config = SamplerConfig {
        rays_per_batch: 256,
        border_margin: MARGIN,
        ..SamplerConfig::default()
    };
    for index in [0, 1, 17, u64::MAX] {
        let batch = a.batch(&config, 5, &s, index);
        assert_eq!(batch, b.batch(&config, 5, &s, index), "rebuilt sampler");
        assert_eq!(batch, a.clone().batch(&config, 5, &s, index), "cloned");
        assert_ne!(batch.pixels, a.batch(&config, 5, &s, index ^ 1).pixels);
        assert_ne!(batch.pixels, a.batch(&config, 6, &s, index).pixels);
    }
}
