//! The picture of the scale report: two panels of grouped bars, each
//! stage's wall seconds and peak resident memory, one colour per scene
//! size; a panel whose values span more than a factor of 30 has a
//! logarithmic axis, so small stages stay visible beside large ones.

use std::path::Path;

use plotters::chart::{SeriesAnno, SeriesLabelStyle};
use plotters::coord::Shift;
use plotters::prelude::*;

use super::Cell;

/// One colour per size, in column order.
const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Writes the two panels to `path`: `columns` is `(size, one cell per
/// stage)`.
pub fn draw(path: &Path, stages: &[String], columns: &[(String, Vec<Cell>)]) -> Result<(), String> {
    let seconds: Vec<(String, Vec<Option<f64>>)> = columns
        .iter()
        .map(|(n, c)| (n.clone(), c.iter().map(|c| Some(c.seconds)).collect()))
        .collect();
    let peaks: Vec<(String, Vec<Option<f64>>)> = columns
        .iter()
        .map(|(n, c)| (n.clone(), c.iter().map(|c| c.peak_mb).collect()))
        .collect();
    field_ops::plot::draw_png(path, 1500, 620, |root| {
        let panels = root.split_evenly((1, 2));
        panel(
            &panels[0],
            "Wall time of each stage (seconds)",
            stages,
            &seconds,
        )?;
        panel(
            &panels[1],
            "Peak resident memory of each stage (MiB, VmHWM)",
            stages,
            &peaks,
        )
    })
}

/// One panel of grouped bars: a group per stage, a bar per size.
fn panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    caption: &str,
    stages: &[String],
    series: &[(String, Vec<Option<f64>>)],
) -> Result<(), String> {
    let values: Vec<f64> = series
        .iter()
        .flat_map(|(_, v)| v.iter().flatten().copied())
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    let hi = values.iter().copied().fold(1e-3, f64::max) * 1.3;
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let log = lo.is_finite() && hi / lo > 30.0;
    let n = stages.len().max(1) as f64;
    let x = -0.5..n - 0.5;
    let label = |v: &f64| {
        let i = v.round();
        if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < stages.len() {
            stages[i as usize].clone()
        } else {
            String::new()
        }
    };
    let width = 0.8 / series.len().max(1) as f64;
    let bar_x = |stage: usize, s: usize| stage as f64 - 0.4 + s as f64 * width;
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60);
    if log {
        let floor = lo / 2.0;
        let mut chart = builder
            .build_cartesian_2d(x, (floor..hi).log_scale())
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_labels(stages.len() + 1)
            .x_label_formatter(&label)
            .y_desc("log scale")
            .draw()
            .map_err(|x| e(&x))?;
        for (s, (name, v)) in series.iter().enumerate() {
            let colour = COLOURS[s % COLOURS.len()];
            let bars = v.iter().enumerate().filter_map(|(i, v)| {
                let v = (*v)?.max(floor);
                let x0 = bar_x(i, s);
                Some(Rectangle::new(
                    [(x0, floor), (x0 + width, v)],
                    colour.filled(),
                ))
            });
            legend(chart.draw_series(bars).map_err(|x| e(&x))?, name, colour);
        }
        finish_legend(&mut chart.configure_series_labels())
    } else {
        let mut chart = builder.build_cartesian_2d(x, 0f64..hi).map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_labels(stages.len() + 1)
            .x_label_formatter(&label)
            .draw()
            .map_err(|x| e(&x))?;
        for (s, (name, v)) in series.iter().enumerate() {
            let colour = COLOURS[s % COLOURS.len()];
            let bars = v.iter().enumerate().filter_map(|(i, v)| {
                let x0 = bar_x(i, s);
                Some(Rectangle::new(
                    [(x0, 0.0), (x0 + width, (*v)?)],
                    colour.filled(),
                ))
            });
            legend(chart.draw_series(bars).map_err(|x| e(&x))?, name, colour);
        }
        finish_legend(&mut chart.configure_series_labels())
    }
}

/// Names a series in the legend with a square of its colour.
fn legend<DB: DrawingBackend>(anno: &mut SeriesAnno<'_, DB>, name: &str, colour: RGBColor) {
    anno.label(name.to_string())
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], colour.filled()));
}

/// Draws the legend in the upper left corner.
fn finish_legend<'a, 'b, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    labels: &mut SeriesLabelStyle<'a, 'b, DB, CT>,
) -> Result<(), String> {
    labels
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())
}
