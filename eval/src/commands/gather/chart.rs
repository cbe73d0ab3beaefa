//! `benchmark.png`: mIoU of each class group per scene, bars at the mean
//! with the runs' standard deviation as whiskers.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::table::SceneRow;

/// The groups drawn and their column in the table.
const GROUPS: [(&str, usize, RGBColor); 4] = [
    ("all", 2, RGBColor(60, 60, 60)),
    ("head", 4, RGBColor(31, 119, 180)),
    ("common", 6, RGBColor(255, 127, 14)),
    ("tail", 8, RGBColor(44, 160, 44)),
];

/// Draws the chart; `Ok(false)` (nothing written) when no scene has
/// segmentation scores.
pub fn draw(rows: &[SceneRow], path: &Path) -> Result<bool, String> {
    let top = rows
        .iter()
        .flat_map(|r| GROUPS.iter().filter_map(|g| r.row.stats[g.1]))
        .map(|s| s.mean + s.std)
        .fold(f64::NAN, f64::max);
    if !top.is_finite() {
        return Ok(false);
    }
    let width = (160 + 110 * rows.len() as u32).max(480);
    field_ops::plot::draw_png(path, width, 420, |root| {
        let e = |e: &dyn std::fmt::Display| e.to_string();
        let n = rows.len() as f64;
        let mut chart = ChartBuilder::on(root)
            .caption(
                "3D segmentation mIoU per scene (mean ± std over runs)",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d(0.0..n, 0.0..(top * 1.15).max(1.0))
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_desc("mIoU (%)")
            .draw()
            .map_err(|x| e(&x))?;
        // One name under each group of bars (the axis' own ticks fall
        // where its scale puts them, not one per scene).
        let style =
            TextStyle::from(("sans-serif", 14).into_font()).pos(Pos::new(HPos::Center, VPos::Top));
        for (i, r) in rows.iter().enumerate() {
            let (x, y) = chart.backend_coord(&(i as f64 + 0.5, 0.0));
            root.draw(&Text::new(r.scene.clone(), (x, y + 8), style.clone()))
                .map_err(|x| e(&x))?;
        }
        let bar = 0.8 / GROUPS.len() as f64;
        for (g, (name, column, colour)) in GROUPS.iter().enumerate() {
            let bars: Vec<(f64, f64, f64)> = rows
                .iter()
                .enumerate()
                .filter_map(|(i, r)| {
                    let s = r.row.stats[*column]?;
                    Some((i as f64 + 0.1 + g as f64 * bar, s.mean, s.std))
                })
                .collect();
            chart
                .draw_series(bars.iter().map(|&(x, m, _)| {
                    Rectangle::new([(x, 0.0), (x + bar * 0.9, m)], colour.filled())
                }))
                .map_err(|x| e(&x))?
                .label(*name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 10, y + 5)], colour.filled())
                });
            chart
                .draw_series(bars.iter().filter(|b| b.2 > 0.0).map(|&(x, m, s)| {
                    let c = x + bar * 0.45;
                    PathElement::new(
                        vec![(c, (m - s).max(0.0)), (c, m + s)],
                        BLACK.stroke_width(2),
                    )
                }))
                .map_err(|x| e(&x))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|x| e(&x))?;
        Ok(())
    })?;
    Ok(true)
}
