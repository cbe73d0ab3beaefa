//! The training-curve picture of a run (`training_curve.png`): PSNR and
//! losses against wall-clock seconds, read back from `metrics.jsonl`, so a
//! resumed run draws its whole history.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::metrics_log::{self, MetricsEvent};

/// The series of one run, in log order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Curves {
    /// `(seconds, batch PSNR)` of the training log lines.
    pub batch_psnr: Vec<(f64, f64)>,
    /// `(seconds, held-out PSNR on interior pixels)` of the evaluations.
    pub heldout_psnr: Vec<(f64, f64)>,
    /// `(name, [(seconds, value)])` of the loss terms (total, rgb, open, depth).
    pub losses: Vec<(&'static str, Vec<(f64, f64)>)>,
    /// Seconds at which novel views joined the training frames.
    pub novel_views: Vec<f64>,
    /// `(share of rays rendered, share of their length sampled)` of the
    /// training lines of a run with the occupancy grid.
    pub skipping: Vec<(f64, f64)>,
}

impl Curves {
    /// Means of [`Curves::skipping`] (`None` without the grid).
    pub fn mean_skipping(&self) -> Option<(f64, f64)> {
        let n = self.skipping.len();
        (n > 0).then(|| {
            let (r, l) = self
                .skipping
                .iter()
                .fold((0.0, 0.0), |(r, l), &(a, b)| (r + a, l + b));
            (r / n as f64, l / n as f64)
        })
    }
}

/// Names of the loss terms, in [`Curves::losses`] order.
const LOSS_NAMES: [&str; 4] = ["total loss", "colour MSE", "feature loss", "depth loss"];

/// Reads the series from the lines of `metrics.jsonl`; lines that are not
/// events (a line cut by a kill) and non-finite values are skipped.
pub fn parse(jsonl: &str) -> Curves {
    from_events(&metrics_log::parse(jsonl))
}

/// The series of the events of a log; non-finite values are skipped.
pub fn from_events(events: &[MetricsEvent]) -> Curves {
    let mut c = Curves {
        losses: LOSS_NAMES.iter().map(|&n| (n, Vec::new())).collect(),
        ..Curves::default()
    };
    for event in events {
        let Some(t) = event.wall_seconds().filter(|t| t.is_finite()) else {
            continue;
        };
        match event {
            MetricsEvent::Train(l) => {
                if l.psnr.is_finite() {
                    c.batch_psnr.push((t, l.psnr));
                }
                let terms = [l.loss, l.rgb_mse, l.open, l.depth];
                for (x, (_, series)) in terms.into_iter().zip(c.losses.iter_mut()) {
                    if x.is_finite() && x > 0.0 {
                        series.push((t, x));
                    }
                }
                if let Some(g) = l.grid
                    && g.rays_rendered.is_finite()
                    && g.ray_length_sampled.is_finite()
                {
                    c.skipping.push((g.rays_rendered, g.ray_length_sampled));
                }
            }
            MetricsEvent::Eval(l) | MetricsEvent::Final(l) => {
                if l.interior.psnr.is_finite() {
                    c.heldout_psnr.push((t, l.interior.psnr));
                }
            }
            MetricsEvent::NovelViews(_) => c.novel_views.push(t),
            MetricsEvent::Nonfinite(_) => {}
        }
    }
    c
}

/// Draws `curves` into a PNG at `path`: PSNR on top, losses (log scale)
/// below, a grey line where novel views joined.
pub fn draw(curves: &Curves, path: &Path) -> Result<(), String> {
    let (w, h) = (900u32, 800u32);
    field_ops::plot::draw_png(path, w, h, |root| {
        let (top, bottom) = root.split_vertically(h / 2);
        let all_t = curves
            .batch_psnr
            .iter()
            .chain(&curves.heldout_psnr)
            .map(|p| p.0);
        let t_max = all_t.fold(1e-9f64, f64::max) * 1.02;
        draw_psnr(curves, &top, t_max)?;
        draw_losses(curves, &bottom, t_max)
    })
}

/// One half of the picture.
type Half<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// The PSNR chart: the training batches' and the held-out evaluations'.
fn draw_psnr(curves: &Curves, area: &Half<'_>, t_max: f64) -> Result<(), String> {
    let psnr = curves
        .batch_psnr
        .iter()
        .chain(&curves.heldout_psnr)
        .map(|p| p.1);
    let (p0, p1) = padded(psnr, 0.0, 30.0);
    let mut chart = ChartBuilder::on(area)
        .caption("PSNR (dB) against training seconds", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(0f64..t_max, p0..p1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("seconds")
        .y_desc("PSNR (dB)")
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(LineSeries::new(
            curves.batch_psnr.iter().copied(),
            BLUE.mix(0.35),
        ))
        .map_err(|e| e.to_string())?
        .label("training batch")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], BLUE.mix(0.35)));
    chart
        .draw_series(LineSeries::new(
            curves.heldout_psnr.iter().copied(),
            RED.stroke_width(2),
        ))
        .map_err(|e| e.to_string())?
        .label("held-out views, interior pixels")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], RED.stroke_width(2)));
    chart
        .draw_series(
            curves
                .heldout_psnr
                .iter()
                .map(|&p| Circle::new(p, 3, RED.filled())),
        )
        .map_err(|e| e.to_string())?;
    for &t in &curves.novel_views {
        chart
            .draw_series(LineSeries::new([(t, p0), (t, p1)], BLACK.mix(0.4)))
            .map_err(|e| e.to_string())?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(())
}

/// The losses chart, log scale.
fn draw_losses(curves: &Curves, area: &Half<'_>, t_max: f64) -> Result<(), String> {
    let values = curves
        .losses
        .iter()
        .flat_map(|(_, s)| s.iter().map(|p| p.1));
    let (l0, l1) = values
        .filter(|v| *v > 0.0)
        .fold((f64::INFINITY, 0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (l0, l1) = if l0.is_finite() && l1 > l0 {
        (l0 / 1.5, l1 * 1.5)
    } else {
        (1e-4, 1.0)
    };
    let mut chart = ChartBuilder::on(area)
        .caption("losses against training seconds", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..t_max, (l0..l1).log_scale())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("seconds")
        .y_desc("loss (log scale)")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| e.to_string())?;
    let colours = [BLACK, BLUE, GREEN, MAGENTA];
    for ((name, series), colour) in curves.losses.iter().zip(colours) {
        if series.is_empty() {
            continue;
        }
        chart
            .draw_series(LineSeries::new(series.iter().copied(), colour))
            .map_err(|e| e.to_string())?
            .label(*name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour));
    }
    for &t in &curves.novel_views {
        chart
            .draw_series(LineSeries::new([(t, l0), (t, l1)], BLACK.mix(0.4)))
            .map_err(|e| e.to_string())?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(())
}

/// `[min, max]` of finite values with 5% padding (`[lo, hi]` without any).
fn padded(values: impl Iterator<Item = f64>, lo: f64, hi: f64) -> (f64, f64) {
    let (a, b) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !a.is_finite() {
        return (lo, hi);
    }
    let pad = ((b - a) * 0.05).max(0.5);
    (a - pad, b + pad)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_are_read_from_the_log_and_bad_lines_skipped() {
        let log = [
            r#"{"event":"eval","iteration":0,"psnr_interior":11.5,"wall_seconds":0.0}"#,
            r#"{"event":"train","iteration":25,"loss":0.14,"rgb_mse":0.03,"open":0.07,"depth":0.25,"psnr":15.1,"wall_seconds":6.0}"#,
            r#"{"event":"novel_views","iteration":30,"wall_seconds":7.5}"#,
            r#"{"event":"train","iteration":50,"loss":0.12,"rgb_mse":0.02,"open":0.07,"depth":0.0,"psnr":"NaN","wall_seconds":12.0,"rays_rendered":0.5,"ray_length_sampled":0.25}"#,
            r#"{"event":"train","iteration":60,"loss":0.11,"wall_seconds":14.0,"rays_rendered":1.0,"ray_length_sampled":0.75}"#,
            r#"{"event":"nonfinite","iteration":51,"loss":"NaN"}"#,
            r#"{"event":"final","iteration":50,"psnr_interior":17.25,"wall_seconds":13.0}"#,
            r#"{"event":"train","iteration":75,"loss":0.1"#,
        ]
        .join("\n");
        let c = parse(&log);
        assert_eq!(c.batch_psnr, vec![(6.0, 15.1)]);
        assert_eq!(c.heldout_psnr, vec![(0.0, 11.5), (13.0, 17.25)]);
        assert_eq!(c.novel_views, vec![7.5]);
        let total = &c.losses[0];
        assert_eq!(
            (total.0, total.1.clone()),
            ("total loss", vec![(6.0, 0.14), (12.0, 0.12), (14.0, 0.11)])
        );
        // A zero loss has no place on a log scale.
        assert_eq!(c.losses[3].1, vec![(6.0, 0.25)]);
        // The grid's figures, where the lines have them, and their means.
        assert_eq!(c.skipping, vec![(0.5, 0.25), (1.0, 0.75)]);
        assert_eq!(c.mean_skipping(), Some((0.75, 0.5)));
        assert_eq!(parse("").mean_skipping(), None);
    }

    #[test]
    fn the_picture_is_drawn_also_from_an_empty_log() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("curve.png");
        if let Err(e) = draw(&parse(""), &path) {
            // Only a machine without any font may fail, and says so.
            assert!(e.contains("font"), "{e}");
            eprintln!("skipped: {e}");
            return;
        }
        let img = image::open(&path).unwrap();
        assert_eq!((img.width(), img.height()), (900, 800));
    }
}
