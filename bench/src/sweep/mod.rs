//! The speed/accuracy sweep: the grid of settings each scene is trained
//! with, what each point measured, the non-dominated (Pareto) points, and
//! their plot. The `sweep` binary runs the points.

use serde::{Deserialize, Serialize};

mod plot;

pub use plot::write_report;

/// One setting of the sweep: a name and the `train` flags that make it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepPoint {
    /// Short name (also the run directory's name).
    pub name: String,
    /// Flags given to `train` after the scene's own.
    pub flags: Vec<String>,
    /// Seconds of training (the time budget the schedule is fitted to).
    pub budget: f64,
}

fn point(name: &str, flags: &[&str], budget: f64) -> SweepPoint {
    SweepPoint {
        name: name.into(),
        flags: flags.iter().map(|s| s.to_string()).collect(),
        budget,
    }
}

/// The points common to every scene, around the default run, each changing
/// one knob (samples per ray, trunk width and depth, rays per batch, the
/// occupancy grid, the time budget, the field model) at `budget` seconds.
pub fn common_points(budget: f64) -> Vec<SweepPoint> {
    let b = budget;
    let mut points = vec![
        point("default", &[], b),
        point("samples-16", &["--samples", "16"], b),
        point("samples-32", &["--samples", "32"], b),
        point("samples-96", &["--samples", "96"], b),
        point("width-48", &["--width", "48"], b),
        point("width-192", &["--width", "192"], b),
        point("depth-2", &["--depth", "2"], b),
        point("depth-8", &["--depth", "8"], b),
        point("rays-128", &["--rays", "128"], b),
        point("rays-1024", &["--rays", "1024"], b),
        point("grid", &["--occupancy-grid"], b),
        point(
            "grid-samples-24",
            &["--occupancy-grid", "--samples", "24"],
            b,
        ),
        point("grid-width-192", &["--occupancy-grid", "--width", "192"], b),
        point(
            "grid-res-64",
            &["--occupancy-grid", "--grid-resolution", "64"],
            b,
        ),
        point("budget-half", &[], 0.5 * b),
        point("budget-double", &[], 2.0 * b),
        point("grid-budget-half", &["--occupancy-grid"], 0.5 * b),
        point("grid-budget-double", &["--occupancy-grid"], 2.0 * b),
        point("samples-16-budget-half", &["--samples", "16"], 0.5 * b),
        point(
            "grid-samples-16",
            &["--occupancy-grid", "--samples", "16"],
            b,
        ),
        point(
            "grid-samples-24-budget-half",
            &["--occupancy-grid", "--samples", "24"],
            0.5 * b,
        ),
        point(
            "grid-samples-24-budget-double",
            &["--occupancy-grid", "--samples", "24"],
            2.0 * b,
        ),
        point(
            "grid-samples-24-budget-4x",
            &["--occupancy-grid", "--samples", "24"],
            4.0 * b,
        ),
        point(
            "grid-samples-32-budget-4x",
            &["--occupancy-grid", "--samples", "32"],
            4.0 * b,
        ),
        point("grid-budget-4x", &["--occupancy-grid"], 4.0 * b),
    ];
    points.extend(fast_points(b));
    points
}

/// The fast field's points (`--field-model fast`): with its hash-grid
/// proposal networks (its own sampler) and with the coarse and fine
/// sampler, at the budget, at half and at double it, and with nerfacto's
/// learning rate (1e-2).
pub fn fast_points(budget: f64) -> Vec<SweepPoint> {
    let b = budget;
    let fast = ["--field-model", "fast"];
    let coarse_fine = ["--field-model", "fast", "--sampler", "coarse-fine"];
    let with = |base: &[&'static str], more: &[&'static str]| -> Vec<&'static str> {
        base.iter().chain(more).copied().collect()
    };
    vec![
        point("fast", &fast, b),
        point("fast-budget-half", &fast, 0.5 * b),
        point("fast-budget-double", &fast, 2.0 * b),
        point("fast-lr-1e-2", &with(&fast, &["--lr", "1e-2"]), b),
        point("fast-coarse-fine", &coarse_fine, b),
        point("fast-coarse-fine-budget-half", &coarse_fine, 0.5 * b),
        point("fast-coarse-fine-budget-double", &coarse_fine, 2.0 * b),
        point(
            "fast-coarse-fine-lr-1e-2",
            &with(&coarse_fine, &["--lr", "1e-2"]),
            b,
        ),
    ]
}

/// The points of a scene with feature maps: the common ones plus the
/// feature knobs (PCA off / auto / 8 / 32, head top-k) and 128 rays with
/// 16 samples, with and without the grid.
pub fn feature_points(budget: f64) -> Vec<SweepPoint> {
    let b = budget;
    let mut points = common_points(budget);
    points.extend([
        point("pca-off", &["--pca", "off"], b),
        point("pca-8", &["--pca", "8"], b),
        point("pca-32", &["--pca", "32"], b),
        point("head-top-k-4", &["--head-top-k", "4"], b),
        point("head-top-k-16", &["--head-top-k", "16"], b),
        // The two knobs that gain most on the room, together.
        point(
            "rays-128-samples-16",
            &["--rays", "128", "--samples", "16"],
            b,
        ),
        point(
            "grid-rays-128-samples-16",
            &["--occupancy-grid", "--rays", "128", "--samples", "16"],
            b,
        ),
    ]);
    points
}

/// What one point measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepResult {
    /// The setting.
    pub point: SweepPoint,
    /// Seconds of training (periodic evaluations included; the start-up and
    /// the final render of the held-out views not): the x axis of the plots.
    pub train_seconds: f64,
    /// Wall-clock seconds of the whole run, the final render included.
    pub wall_seconds: f64,
    /// Training iterations done.
    pub iterations: usize,
    /// Rays drawn per second of training.
    pub rays_per_second: f64,
    /// Peak resident memory of the training process, bytes.
    pub peak_memory_bytes: Option<u64>,
    /// Held-out PSNR over the interior pixels of the held-out views (on the
    /// bench room, over the final evaluation's sample of them).
    pub psnr_interior: f64,
    /// Held-out PSNR over every pixel of the held-out views (`None` where
    /// they were not rendered in full).
    pub psnr_whole: Option<f64>,
    /// Held-out SSIM over the interior pixels of the held-out views (`None`
    /// where they were not rendered in full, and in sweeps written before
    /// it was recorded).
    #[serde(default)]
    pub ssim_interior: Option<f64>,
    /// Held-out depth MAE (metres), where the scene has depth.
    pub depth_mae: Option<f64>,
    /// Hybrid 3D segmentation mIoU over all classes (percent), when measured.
    pub miou: Option<f64>,
    /// Hybrid mIoU over the tail classes (percent), when measured.
    pub miou_tail: Option<f64>,
}

/// Relative difference in seconds below which two points count as equally
/// fast: runs given the same time budget end a few per cent apart, and that
/// jitter must not decide which of them is on the front.
pub const TIME_TOLERANCE: f64 = 0.05;

/// Indices of the `(seconds, accuracy)` points not dominated by another,
/// sorted by time. A point is dominated by one that is at least as accurate
/// and faster, or more accurate and at most `tolerance` (relative) slower.
pub fn pareto_within(points: &[(f64, f64)], tolerance: f64) -> Vec<usize> {
    let dominated = |i: usize| {
        let (t, a) = points[i];
        points
            .iter()
            .any(|&(u, b)| (u < t && b >= a) || (u <= t * (1.0 + tolerance) && b > a))
    };
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].0.is_finite() && points[i].1.is_finite() && !dominated(i))
        .collect();
    front.sort_by(|&i, &j| points[i].0.total_cmp(&points[j].0));
    front
}

/// [`pareto_within`] with [`TIME_TOLERANCE`].
pub fn pareto(points: &[(f64, f64)]) -> Vec<usize> {
    pareto_within(points, TIME_TOLERANCE)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over every pair, independent of `pareto`'s formulation.
    fn front_by_pairs(p: &[(f64, f64)]) -> Vec<usize> {
        let mut out = Vec::new();
        'outer: for i in 0..p.len() {
            for j in 0..p.len() {
                let better_or_equal = p[j].0 <= p[i].0 && p[j].1 >= p[i].1;
                if i != j && better_or_equal && p[j] != p[i] {
                    continue 'outer;
                }
            }
            out.push(i);
        }
        out.sort_by(|&a, &b| p[a].0.total_cmp(&p[b].0));
        out
    }

    #[test]
    fn the_front_keeps_exactly_the_non_dominated_points() {
        let p = [
            (10.0, 20.0),
            (20.0, 25.0),
            (15.0, 19.0), // dominated by (10, 20)
            (30.0, 24.0), // dominated by (20, 25)
            (40.0, 27.0),
            (20.0, 25.0), // a tie is not domination
        ];
        assert_eq!(pareto_within(&p, 0.0), vec![0, 1, 5, 4]);
        // Within 5 %, a slightly slower but more accurate run wins.
        let q = [(60.0, 18.8), (61.0, 23.2), (30.0, 15.0), (120.0, 23.1)];
        assert_eq!(pareto(&q), vec![2, 1]);
        assert_eq!(pareto_within(&q, 0.0), vec![2, 0, 1]);
        // Pseudo-random clouds against the brute force.
        let mut s = 7u64;
        for _ in 0..50 {
            let pts: Vec<(f64, f64)> = (0..12)
                .map(|_| {
                    s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
                    ((s >> 40) as f64 % 50.0, (s >> 20) as f64 % 30.0)
                })
                .collect();
            let mut a = pareto_within(&pts, 0.0);
            let mut b = front_by_pairs(&pts);
            a.sort();
            b.sort();
            assert_eq!(a, b, "{pts:?}");
        }
    }

    #[test]
    fn points_have_unique_names_and_positive_budgets() {
        let pts = feature_points(100.0);
        let mut names: Vec<&str> = pts.iter().map(|p| p.name.as_str()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), pts.len());
        assert!(pts.iter().all(|p| p.budget > 0.0));
        assert!(common_points(60.0).len() >= 16);
    }
}
