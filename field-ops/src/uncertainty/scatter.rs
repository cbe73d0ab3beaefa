//! The uncertainty-against-error scatter plot.

use std::path::Path;

use plotters::prelude::*;

use super::UncertaintyMap;
use crate::error::OpsError;
use crate::plot::draw_png;

/// Most points drawn (an even subsample beyond that keeps the file small).
const MAX_DOTS: usize = 20_000;

/// Draws `log det` (x) against the feature error (y) of the points seen at
/// least twice with a finite error, with Pearson's r in the caption.
pub fn scatter(
    path: &Path,
    map: &UncertaintyMap,
    errors: &[f64],
    r: Option<f64>,
) -> Result<(), OpsError> {
    let pts: Vec<(f64, f64)> = (0..map.counts.len())
        .filter(|&i| map.counts[i] >= 2 && errors[i].is_finite())
        .map(|i| (map.log_det[i], errors[i]))
        .collect();
    let step = pts.len().div_ceil(MAX_DOTS).max(1);
    let dots: Vec<(f64, f64)> = pts.iter().step_by(step).copied().collect();
    let (x0, x1) = range(dots.iter().map(|d| d.0));
    let (y0, y1) = range(dots.iter().map(|d| d.1));
    let (w, h) = (800u32, 600u32);
    draw_png(path, w, h, |root| {
        let caption = match r {
            Some(r) => format!(
                "uncertainty vs feature error (Pearson r = {r:.3}, {} points)",
                pts.len()
            ),
            None => format!("uncertainty vs feature error ({} points)", pts.len()),
        };
        let mut chart = ChartBuilder::on(root)
            .caption(caption, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(format!("log det(Sigma + eps I), k = {}", map.k))
            .y_desc("1 - cos(mean feature, class embedding)")
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(
                dots.iter()
                    .map(|&(x, y)| Circle::new((x, y), 2, BLUE.mix(0.25).filled())),
            )
            .map_err(|e| e.to_string())?;
        Ok(())
    })
    .map_err(OpsError::Invalid)
}

/// A padded `[min, max]` of finite values (`[0, 1]` when there are none).
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-6);
    (lo - pad, hi + pad)
}
