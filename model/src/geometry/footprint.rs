//! The turn about the vertical that fits a scene's box tightly: a room's
//! walls need not run along its capture's x and y (a phone's world starts
//! wherever the phone pointed), and an axis-aligned box around a room turned
//! by 30 degrees is a third wider than the room, which coarsens the field
//! (its coordinates are normalised by the box's largest half-extent).

use super::{Similarity, Vec3};

/// The angle (radians, in `(-π/4, π/4]`) to turn points about the z axis
/// by so that the smallest-area rectangle around their footprint on the
/// xy plane has its sides along x and y; 0 for fewer than three distinct
/// footprint points or a footprint on a line.
///
/// The smallest rectangle has a side along an edge of the footprint's
/// convex hull, so only the hull's edge directions are tried (exact, not a
/// search over angles). Of the four turns by quarter turns that align the
/// rectangle, the smallest is returned, so that an already aligned scene
/// is not turned.
pub fn aligning_yaw(points: &[Vec3]) -> f64 {
    let hull = convex_hull(points.iter().map(|p| [p[0], p[1]]).collect());
    if hull.len() < 3 {
        return 0.0;
    }
    let mut best: (f64, f64) = (f64::INFINITY, 0.0);
    for (i, a) in hull.iter().enumerate() {
        let b = hull[(i + 1) % hull.len()];
        let yaw = quarter_turn_reduced(-(b[1] - a[1]).atan2(b[0] - a[0]));
        let area = footprint_area(&hull, yaw);
        // Ties (a rectangle's other edges) keep the smaller turn.
        let tie = (area - best.0).abs() <= 1e-9 * best.0;
        if best.0.is_infinite() || (!tie && area < best.0) || (tie && yaw.abs() < best.1.abs()) {
            best = (area, yaw);
        }
    }
    best.1
}

/// The rotation about z by `yaw` radians, as a similarity.
pub fn yaw_rotation(yaw: f64) -> Similarity {
    let (s, c) = yaw.sin_cos();
    Similarity {
        rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        scale: 1.0,
        translation: [0.0; 3],
    }
}

/// The area of the axis-aligned rectangle around `points` (2-D) once they
/// are turned by `yaw` radians.
pub fn footprint_area(points: &[[f64; 2]], yaw: f64) -> f64 {
    let (s, c) = yaw.sin_cos();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in points {
        let q = [c * p[0] - s * p[1], s * p[0] + c * p[1]];
        for i in 0..2 {
            lo[i] = lo[i].min(q[i]);
            hi[i] = hi[i].max(q[i]);
        }
    }
    (hi[0] - lo[0]) * (hi[1] - lo[1])
}

/// `angle` moved into `(-π/4, π/4]` by quarter turns.
fn quarter_turn_reduced(angle: f64) -> f64 {
    let q = std::f64::consts::FRAC_PI_2;
    let r = angle - q * (angle / q).round();
    if r <= -q / 2.0 { r + q } else { r }
}

/// The convex hull of the finite points, counter-clockwise, without
/// collinear points (Andrew's monotone chain).
fn convex_hull(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.retain(|p| p[0].is_finite() && p[1].is_finite());
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * points.len());
    for pass in [points.clone(), points.into_iter().rev().collect()] {
        let start = hull.len();
        for p in pass {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream in [0, 1).
    fn uniform(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Points filling a `w` x `h` rectangle turned by `turn` about z, with
    /// its corners, at heights in [0, 2].
    fn turned_room(w: f64, h: f64, turn: f64, n: usize, seed: &mut u64) -> Vec<Vec3> {
        let r = yaw_rotation(turn);
        let mut local: Vec<Vec3> = (0..n)
            .map(|_| {
                [
                    (uniform(seed) - 0.5) * w,
                    (uniform(seed) - 0.5) * h,
                    2.0 * uniform(seed),
                ]
            })
            .collect();
        for sx in [-0.5, 0.5] {
            for sy in [-0.5, 0.5] {
                local.push([sx * w, sy * h, 1.0]);
            }
        }
        local
            .into_iter()
            .map(|p| {
                let q = r.apply_point(p);
                [q[0] + 3.0, q[1] - 1.0, q[2]]
            })
            .collect()
    }

    #[test]
    fn a_turned_rectangle_is_turned_back() {
        let mut seed = 7;
        for turn in [0.0, 0.3, -0.6, 1.2, 0.78] {
            let pts = turned_room(4.8, 3.1, turn, 400, &mut seed);
            let yaw = aligning_yaw(&pts);
            let want = quarter_turn_reduced(-turn);
            assert!((yaw - want).abs() < 1e-9, "turn {turn}: {yaw} vs {want}");
            let flat: Vec<[f64; 2]> = pts.iter().map(|p| [p[0], p[1]]).collect();
            assert!((footprint_area(&flat, yaw) - 4.8 * 3.1).abs() < 1e-9);
        }
    }

    #[test]
    fn no_turn_beats_the_hull_edges_on_random_clouds() {
        let mut seed = 11;
        for _ in 0..20 {
            let n = 3 + (uniform(&mut seed) * 60.0) as usize;
            let pts: Vec<Vec3> = (0..n)
                .map(|_| [uniform(&mut seed) * 5.0, uniform(&mut seed) * 2.0, 0.0])
                .collect();
            let flat: Vec<[f64; 2]> = pts.iter().map(|p| [p[0], p[1]]).collect();
            let yaw = aligning_yaw(&pts);
            assert!(yaw.abs() <= std::f64::consts::FRAC_PI_4 + 1e-12);
            let got = footprint_area(&flat, yaw);
            // Brute force: every angle of a quarter turn in 0.005-degree steps.
            let brute = (0..18_000)
                .map(|i| footprint_area(&flat, (i as f64 * 0.005).to_radians()))
                .fold(f64::INFINITY, f64::min);
            assert!(got <= brute + 1e-12, "{got} > {brute}");
            assert!(got >= brute * (1.0 - 1e-4), "{got} far below {brute}");
        }
    }

    #[test]
    fn degenerate_footprints_are_not_turned() {
        assert_eq!(aligning_yaw(&[]), 0.0);
        assert_eq!(aligning_yaw(&[[1.0, 2.0, 0.0], [1.0, 2.0, 5.0]]), 0.0);
        let line: Vec<Vec3> = (0..5).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        assert_eq!(aligning_yaw(&line), 0.0);
        let with_nan = [[0.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0], [1.0, 0.0, 0.0]];
        assert_eq!(aligning_yaw(&with_nan), 0.0);
    }

    #[test]
    fn the_hull_drops_inner_and_collinear_points() {
        let h = convex_hull(vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, 0.0],
            [2.0, 2.0],
            [0.0, 2.0],
            [1.0, 1.0],
        ]);
        assert_eq!(h, vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]);
    }
}
