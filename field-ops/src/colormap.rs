//! Colour maps for depth and relevancy images.

/// Google's Turbo colour map at `x` in `[0, 1]` (clamped), as RGB in `[0, 1]`.
///
/// Uses the published degree-5 polynomial approximation of the lookup table
/// (Mikhailov, 2019): smooth and cheap, within about 0.13 per channel of the
/// table (closest in the middle, loosest at the dark ends).
pub fn turbo(x: f32) -> [f32; 3] {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x2 = x * x;
    let x3 = x2 * x;
    let x4 = x2 * x2;
    let x5 = x4 * x;
    let r = 0.135_721_38 + 4.615_392_6 * x - 42.660_324 * x2 + 132.131_08 * x3 - 152.942_4 * x4
        + 59.286_38 * x5;
    let g = 0.091_402_61 + 2.194_188_4 * x + 4.842_966_6 * x2 - 14.185_034 * x3
        + 4.277_298_6 * x4
        + 2.829_566 * x5;
    let b = 0.106_673_3 + 12.641_946 * x - 60.582_05 * x2 + 110.362_77 * x3 - 89.903_11 * x4
        + 27.348_25 * x5;
    [r.clamp(0.0, 1.0), g.clamp(0.0, 1.0), b.clamp(0.0, 1.0)]
}

/// A distinct colour for class `index` (golden-angle hue walk), for label images
/// and point clouds coloured by class.
pub fn class_color(index: usize) -> [u8; 3] {
    let h = (index as f32 * 0.618_034).fract();
    let s = if index.is_multiple_of(2) { 0.75 } else { 0.55 };
    let v = if (index / 2).is_multiple_of(2) {
        0.95
    } else {
        0.75
    };
    hsv_to_rgb(h, s, v)
}

fn hsv_to_rgb(h: f32, s: f32, v: f32) -> [u8; 3] {
    let i = (h * 6.0).floor();
    let f = h * 6.0 - i;
    let p = v * (1.0 - s);
    let q = v * (1.0 - f * s);
    let t = v * (1.0 - (1.0 - f) * s);
    let (r, g, b) = match (i as i32).rem_euclid(6) {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    [to_u8(r), to_u8(g), to_u8(b)]
}

/// `[0, 1]` to `0..=255`, rounding; NaN maps to 0.
pub fn to_u8(x: f32) -> u8 {
    if x.is_finite() {
        (x.clamp(0.0, 1.0) * 255.0).round() as u8
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values of the Turbo lookup table (entries 0, 64, 128, 192, 255).
    #[test]
    fn turbo_matches_reference_table() {
        let table: [(f32, [f32; 3]); 5] = [
            (0.0, [0.18995, 0.07176, 0.23217]),
            (64.0 / 255.0, [0.15844, 0.73551, 0.92305]),
            (128.0 / 255.0, [0.64362, 0.98999, 0.23356]),
            (192.0 / 255.0, [0.99314, 0.60746, 0.16368]),
            (1.0, [0.47960, 0.01583, 0.01055]),
        ];
        for (x, want) in table {
            let got = turbo(x);
            for c in 0..3 {
                assert!(
                    (got[c] - want[c]).abs() < 0.15,
                    "turbo({x}) channel {c}: {} vs {}",
                    got[c],
                    want[c]
                );
            }
        }
    }

    #[test]
    fn turbo_clamps_and_handles_nan() {
        assert_eq!(turbo(-3.0), turbo(0.0));
        assert_eq!(turbo(7.0), turbo(1.0));
        assert_eq!(turbo(f32::NAN), turbo(0.0));
    }

    #[test]
    fn class_colors_differ_for_neighbours() {
        for i in 0..60 {
            assert_ne!(class_color(i), class_color(i + 1));
        }
    }
}
