//! SSIM against scikit-image's `structural_similarity` on fixed image pairs
//! (the values printed by `scripts/ssim-reference.py`) and against a
//! brute-force float64 oracle that weighs every window with the 2D Gaussian
//! directly.

use field_ops::ssim::{SSIM_RADIUS, SSIM_SIGMA, ssim, ssim_map};

/// 0.5 + 0.4 sin(0.3 (x + shift) + 0.2 y + c), as the reference script makes it.
fn smooth(w: u32, h: u32, shift: u32) -> Vec<f32> {
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let t = 0.3 * (x + shift) as f64 + 0.2 * y as f64 + c as f64;
                out.push((0.5 + 0.4 * t.sin()) as f32);
            }
        }
    }
    out
}

/// `img` plus uniform noise in `[-amplitude, amplitude]` from the script's
/// 64-bit LCG, clamped to `[0, 1]`.
fn noisy(img: &[f32], seed: u64, amplitude: f64) -> Vec<f32> {
    let mut state = seed;
    img.iter()
        .map(|&v| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            (v as f64 + amplitude * (2.0 * u - 1.0)).clamp(0.0, 1.0) as f32
        })
        .collect()
}

/// SSIM by definition: at every centre whose window fits, the 2D Gaussian
/// weights of the window (not a separable filter), the weighted means,
/// variances and covariance per channel, the SSIM formula, averaged.
fn oracle(a: &[f32], b: &[f32], w: usize, h: usize) -> f64 {
    let r = SSIM_RADIUS as i64;
    let weight =
        |dx: i64, dy: i64| (-((dx * dx + dy * dy) as f64) / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    let total: f64 = (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| weight(dx, dy)))
        .sum();
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let (mut sum, mut n) = (0.0, 0usize);
    for cy in SSIM_RADIUS..h - SSIM_RADIUS {
        for cx in SSIM_RADIUS..w - SSIM_RADIUS {
            for c in 0..3 {
                let (mut mx, mut my) = (0.0, 0.0);
                for dy in -r..=r {
                    for dx in -r..=r {
                        let p = 3 * ((cy as i64 + dy) as usize * w + (cx as i64 + dx) as usize) + c;
                        let k = weight(dx, dy) / total;
                        mx += k * a[p] as f64;
                        my += k * b[p] as f64;
                    }
                }
                let (mut vx, mut vy, mut vxy) = (0.0, 0.0, 0.0);
                for dy in -r..=r {
                    for dx in -r..=r {
                        let p = 3 * ((cy as i64 + dy) as usize * w + (cx as i64 + dx) as usize) + c;
                        let k = weight(dx, dy) / total;
                        let (p, q) = (a[p] as f64 - mx, b[p] as f64 - my);
                        vx += k * p * p;
                        vy += k * q * q;
                        vxy += k * p * q;
                    }
                }
                sum += ((2.0 * mx * my + c1) * (2.0 * vxy + c2))
                    / ((mx * mx + my * my + c1) * (vx + vy + c2));
                n += 1;
            }
        }
    }
    sum / n as f64
}

/// A named image pair of `width x height`, with scikit-image's SSIM of it.
type Pair = (&'static str, u32, u32, Vec<f32>, Vec<f32>, f64);

/// The pairs of `scripts/ssim-reference.py`.
fn pairs() -> Vec<Pair> {
    let base = |w, h| smooth(w, h, 0);
    vec![
        (
            "identical",
            32,
            24,
            base(32, 24),
            base(32, 24),
            1.000000000000,
        ),
        (
            "noisy",
            40,
            30,
            base(40, 30),
            noisy(&base(40, 30), 7, 0.1),
            0.901466752908,
        ),
        (
            "shifted",
            37,
            23,
            base(37, 23),
            smooth(37, 23, 2),
            0.679364843506,
        ),
        (
            "noise against noise",
            16,
            12,
            noisy(&base(16, 12), 1, 0.3),
            noisy(&base(16, 12), 2, 0.3),
            0.326332933244,
        ),
    ]
}

#[test]
fn ssim_matches_scikit_image_on_fixed_pairs() {
    for (name, w, h, a, b, reference) in pairs() {
        let s = ssim(&a, &b, w, h).expect("large enough");
        assert!(
            (s - reference).abs() < 1e-4,
            "{name}: {s} vs scikit-image {reference}"
        );
        // Far tighter in fact: the same float64 arithmetic up to summation order.
        assert!(
            (s - reference).abs() < 1e-9,
            "{name}: {s} vs scikit-image {reference}"
        );
    }
}

#[test]
fn ssim_matches_the_brute_force_oracle_and_is_symmetric() {
    for (name, w, h, a, b, _) in pairs() {
        let s = ssim(&a, &b, w, h).expect("large enough");
        let o = oracle(&a, &b, w as usize, h as usize);
        assert!((s - o).abs() < 1e-12, "{name}: {s} vs oracle {o}");
        let back = ssim(&b, &a, w, h).expect("large enough");
        assert!((s - back).abs() < 1e-12, "{name}: not symmetric");
    }
}

#[test]
fn the_map_has_one_value_per_centre_and_partial_means_select_them() {
    let (w, h) = (20u32, 15u32);
    let a = smooth(w, h, 0);
    let b = noisy(&a, 3, 0.2);
    let map = ssim_map(&a, &b, w, h).expect("large enough");
    let r = SSIM_RADIUS as u32;
    assert_eq!(map.values.len(), ((w - 2 * r) * (h - 2 * r)) as usize);
    assert_eq!(map.mean_where(|_, _| true), Some(map.mean()));
    assert_eq!(map.mean_where(|_, _| false), None);
    // The centre (r, r) is the map's first value.
    assert_eq!(map.mean_where(|x, y| (x, y) == (r, r)), Some(map.values[0]));
    let last = (w - r - 1, h - r - 1);
    assert_eq!(
        map.mean_where(|x, y| (x, y) == last),
        map.values.last().copied()
    );
}

#[test]
fn images_smaller_than_the_window_or_of_the_wrong_length_have_no_ssim() {
    let a = smooth(10, 20, 0);
    assert_eq!(ssim(&a, &a, 10, 20), None);
    let a = smooth(11, 11, 0);
    assert_eq!(ssim(&a, &a, 11, 11), Some(1.0));
    assert_eq!(ssim(&a, &a[3..], 11, 11), None);
}
