//! Scene boxes of a transforms file's scene: the region the cameras look
//! at, or the robust box of the capture's point cloud.

use model::geometry::{Camera, SceneBox, Vec3};

/// Points a robust box needs at least (fewer: too few to take percentiles of).
pub const MIN_BOX_POINTS: usize = 100;

/// Lower and upper percentiles of each axis a robust box spans.
pub const BOX_PERCENTILES: (f64, f64) = (0.02, 0.98);

/// The box spanning, on each axis, the 2nd to the 98th percentile of the
/// finite `points` (stray points of a structure-from-motion cloud, far
/// behind the scene or floating in front of the cameras, fall outside),
/// grown by `margin` times its largest extent. `None` with fewer than
/// [`MIN_BOX_POINTS`] finite points.
pub fn robust_points_box(points: &[Vec3], margin: f64) -> Option<SceneBox> {
    let finite: Vec<&Vec3> = points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .collect();
    let n = finite.len();
    if n < MIN_BOX_POINTS {
        return None;
    }
    let lo = (BOX_PERCENTILES.0 * (n - 1) as f64).floor() as usize;
    let hi = (BOX_PERCENTILES.1 * (n - 1) as f64).ceil() as usize;
    let mut min = [0.0; 3];
    let mut max = [0.0; 3];
    for k in 0..3 {
        let mut axis: Vec<f64> = finite.iter().map(|p| p[k]).collect();
        axis.sort_by(f64::total_cmp);
        min[k] = axis[lo];
        max[k] = axis[hi];
    }
    SceneBox::from_points([min, max], margin)
}

/// [`robust_points_box`] grown to hold what each camera sees at the
/// median depth of the points in its view (its image corners there): the
/// region of the capture, where sparse points cover only its textured
/// surfaces. `None` with fewer than [`MIN_BOX_POINTS`] finite points.
pub fn seen_points_box(points: &[Vec3], cameras: &[Camera], margin: f64) -> Option<SceneBox> {
    let finite: Vec<Vec3> = points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .copied()
        .collect();
    let robust = robust_points_box(&finite, 0.0)?;
    let (mut lo, mut hi) = (robust.min, robust.max);
    let corners = crate::colmap::frame::seen_corners(cameras, &finite);
    if let Some((clo, chi)) = crate::colmap::frame::robust_box(&corners) {
        for k in 0..3 {
            lo[k] = lo[k].min(clo[k]);
            hi[k] = hi[k].max(chi[k]);
        }
    }
    SceneBox::from_points([lo, hi], margin)
}

/// The point minimising the summed squared distance to all optical axes.
/// `None` when the axes are (nearly) parallel.
pub fn focus_point(cameras: &[Camera]) -> Option<Vec3> {
    // sum (I - d d^T) p = sum (I - d d^T) c
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for cam in cameras {
        let d = cam.pose.forward();
        let n = model::geometry::norm(d);
        let d = [d[0] / n, d[1] / n, d[2] / n];
        let c = cam.pose.center();
        for r in 0..3 {
            for col in 0..3 {
                let m = if r == col { 1.0 } else { 0.0 } - d[r] * d[col];
                a[r][col] += m;
                b[r] += m * c[col];
            }
        }
    }
    solve3(a, b)
}

/// Solves the 3x3 system by Cramer's rule; `None` when near-singular.
fn solve3(a: [[f64; 3]; 3], b: Vec3) -> Option<Vec3> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    let scale = a.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    if d.abs() <= 1e-9 * scale.powi(3) || !d.is_finite() {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut m = a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        *xk = det(m) / d;
    }
    Some(x)
}

/// Cube centred on [`focus_point`] with half-extent the largest half-width
/// (horizontal or vertical) any camera sees at its distance to that point,
/// grown by `margin`. `None` without a well-defined focus point.
pub fn viewed_region_box(cameras: &[Camera], margin: f64) -> Option<SceneBox> {
    let p = focus_point(cameras)?;
    let mut half: f64 = 0.0;
    for cam in cameras {
        let k = &cam.intrinsics;
        let dist = model::geometry::norm(model::geometry::sub(p, cam.pose.center()));
        let tan = (0.5 * k.width as f64 / k.fx).max(0.5 * k.height as f64 / k.fy);
        half = half.max(dist * tan);
    }
    if !(half > 0.0 && half.is_finite()) {
        return None;
    }
    let h = half * (1.0 + margin);
    Some(SceneBox {
        min: [p[0] - h, p[1] - h, p[2] - h],
        max: [p[0] + h, p[1] + h, p[2] + h],
    })
}
