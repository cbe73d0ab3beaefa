//! The real-capture defaults, each turned the other way, as a picture: per
//! setting, one bar per capture of the flipped run's held-out PSNR minus
//! the mean of that capture's runs with the defaults, over the band of
//! 0.3 dB either side of zero (the rule's loss), with the spread of the
//! defaults' own runs as a whisker at the bar's end.
//!
//! `cargo run -p bench --release --example capture_defaults_plot -- OUT`
//!
//! reads `OUT/colmap_defaults.csv` (written by `scripts/colmap-defaults.sh`)
//! and writes `OUT/colmap_defaults.png`.

use std::path::{Path, PathBuf};

use bench::csv_table::CsvTable;
use field_ops::plot::draw_png;
use plotters::prelude::*;

/// The loss past which a default is not kept.
const BAND_DB: f64 = 0.3;

/// One flipped run: its capture, setting, the flags that flipped it, its
/// difference with the defaults and the spread of the defaults' runs.
struct Flip {
    capture: String,
    setting: String,
    value: String,
    difference: f64,
    spread: f64,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: capture_defaults_plot OUT")?,
    );
    let flips = read(&dir.join("colmap_defaults.csv"))?;
    let png = dir.join("colmap_defaults.png");
    plot(&png, &flips)?;
    println!("wrote {}", png.display());
    Ok(())
}

fn read(csv: &Path) -> Result<Vec<Flip>, String> {
    let t = CsvTable::read(csv)?;
    let (capture, setting, value) = (
        t.column("capture")?,
        t.column("setting")?,
        t.column("value")?,
    );
    let (difference, spread) = (t.column("difference_db")?, t.column("defaults_spread_db")?);
    let flips = (0..t.len())
        .map(|r| {
            Ok(Flip {
                capture: t.text(r, capture).to_string(),
                setting: t.text(r, setting).to_string(),
                value: t.text(r, value).to_string(),
                difference: t.number(r, difference)?,
                spread: t.number(r, spread)?,
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    if flips.is_empty() {
        return Err(format!("{}: no runs", csv.display()));
    }
    Ok(flips)
}

/// Settings along x in their order of appearance, a bar per capture in
/// each, coloured by capture.
fn plot(path: &Path, flips: &[Flip]) -> Result<(), String> {
    let mut settings: Vec<&str> = Vec::new();
    let mut captures: Vec<&str> = Vec::new();
    for f in flips {
        if !settings.contains(&f.setting.as_str()) {
            settings.push(&f.setting);
        }
        if !captures.contains(&f.capture.as_str()) {
            captures.push(&f.capture);
        }
    }
    let (lo, hi) = flips.iter().fold((-BAND_DB, BAND_DB), |(a, b), f| {
        (
            a.min(f.difference - f.spread),
            b.max(f.difference + f.spread),
        )
    });
    let (lo, hi) = (lo - 0.3, hi + 0.3);
    let n = settings.len() as f64;
    draw_png(path, 1100, 560, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "each default turned the other way: held-out PSNR minus the defaults' \
                 (green: +-0.3 dB; whisker: the defaults' own spread)",
                ("sans-serif", 16),
            )
            .margin(14)
            .x_label_area_size(70)
            .y_label_area_size(60)
            .build_cartesian_2d(0f64..n, lo..hi)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_desc("dB")
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series([Rectangle::new(
                [(0.0, -BAND_DB), (n, BAND_DB)],
                RGBColor(120, 180, 120).mix(0.25).filled(),
            )])
            .map_err(|e| e.to_string())?;
        let width = 0.8 / captures.len() as f64;
        for f in flips {
            let s = settings.iter().position(|x| *x == f.setting).unwrap_or(0);
            let c = captures.iter().position(|x| *x == f.capture).unwrap_or(0);
            let x0 = s as f64 + 0.1 + c as f64 * width;
            let colour = Palette99::pick(c);
            chart
                .draw_series([Rectangle::new(
                    [(x0, 0.0), (x0 + width * 0.9, f.difference)],
                    colour.filled(),
                )])
                .map_err(|e| e.to_string())?;
            let mid = x0 + width * 0.45;
            chart
                .draw_series([PathElement::new(
                    vec![
                        (mid, f.difference - f.spread / 2.0),
                        (mid, f.difference + f.spread / 2.0),
                    ],
                    BLACK.stroke_width(2),
                )])
                .map_err(|e| e.to_string())?;
            let (px, py) = chart.backend_coord(&(x0, lo));
            root.draw(&Text::new(
                format!("{} {}", f.capture, f.value.trim_start_matches("--")),
                (px, py + 8 + 16 * (c as i32 % 3)),
                ("sans-serif", 11).into_font().color(&colour),
            ))
            .map_err(|e| e.to_string())?;
        }
        Ok(())
    })
}
