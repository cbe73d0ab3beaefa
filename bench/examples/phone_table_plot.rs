//! The phone loaders against the Replica loader as a picture: per loader,
//! each seed's held-out PSNR (left) and mIoU (right) as a dot and their
//! mean as a bar, over the band the loaders must stay in around the
//! Replica loader's mean (0.5 dB, 1 mIoU). Where the runs were paired
//! (`PAIRED=1`), a second row shows each phone run's difference with its
//! Replica run.
//!
//! `cargo run -p bench --release --example phone_table_plot -- OUT`
//!
//! reads `OUT/phone_runs.csv` (written by `scripts/phone-table.sh`) and
//! (and `OUT/phone_pairs.csv` where present) and writes
//! `OUT/phone_table.png`.

use std::path::{Path, PathBuf};

use bench::csv_table::CsvTable;
use field_ops::plot::{Canvas, draw_png};
use plotters::prelude::*;

/// One loader's runs: (held-out PSNR in dB, mIoU in percent) per seed.
type Runs = Vec<(String, Vec<(f64, f64)>)>;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: phone_table_plot OUT")?,
    );
    let csv = dir.join("phone_runs.csv");
    let runs = read(&csv, "heldout_psnr_db", "miou")?;
    if runs.first().is_none_or(|(name, _)| name != "replica") {
        return Err(format!("{}: no replica rows first", csv.display()).into());
    }
    let pairs_csv = dir.join("phone_pairs.csv");
    let pairs = if pairs_csv.exists() {
        Some(read(&pairs_csv, "psnr_vs_replica_db", "miou_vs_replica")?)
    } else {
        None
    };
    let png = dir.join("phone_table.png");
    plot(&png, &runs, pairs.as_ref())?;
    println!("wrote {}", png.display());
    Ok(())
}

/// The `(psnr, miou)` columns of `csv` (`phone_runs.csv` or
/// `phone_pairs.csv`) per loader, loaders in their order of appearance.
fn read(csv: &Path, psnr: &str, miou: &str) -> Result<Runs, String> {
    let t = CsvTable::read(csv)?;
    let (loader, psnr, miou) = (t.column("loader")?, t.column(psnr)?, t.column(miou)?);
    let mut runs: Runs = Vec::new();
    for r in 0..t.len() {
        let name = t.text(r, loader).to_string();
        let point = (t.number(r, psnr)?, t.number(r, miou)?);
        match runs.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push(point),
            None => runs.push((name, vec![point])),
        }
    }
    Ok(runs)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// What one panel shows: per group, a dot per run and the mean as a bar,
/// over a band of `band` around `base`, shaded green.
struct Panel<'a> {
    caption: String,
    unit: &'a str,
    groups: Vec<(String, Vec<f64>)>,
    base: f64,
    band: f64,
}

/// PSNR and mIoU per loader (top); where `pairs` holds the paired runs'
/// differences with the Replica loader, those per loader below, around 0.
fn plot(path: &Path, runs: &Runs, pairs: Option<&Runs>) -> Result<(), String> {
    let mut panels = Vec::new();
    for (k, (what, unit, band)) in [("held-out PSNR", "dB", 0.5), ("mIoU", "percent", 1.0)]
        .into_iter()
        .enumerate()
    {
        let pick = |v: &[(f64, f64)]| -> Vec<f64> {
            v.iter().map(|p| if k == 0 { p.0 } else { p.1 }).collect()
        };
        let groups: Vec<(String, Vec<f64>)> =
            runs.iter().map(|(n, v)| (n.clone(), pick(v))).collect();
        let base = mean(&groups[0].1);
        panels.push(Panel {
            caption: format!("{what} (green: Replica's mean +- {band})"),
            unit,
            groups,
            base,
            band,
        });
        if let Some(pairs) = pairs {
            panels.push(Panel {
                caption: format!("{what}, phone run - its Replica run (green: +- {band})"),
                unit,
                groups: pairs.iter().map(|(n, v)| (n.clone(), pick(v))).collect(),
                base: 0.0,
                band,
            });
        }
    }
    let rows = if pairs.is_some() { 2 } else { 1 };
    draw_png(path, 1000, 520 * rows as u32, |root| {
        // Panels are pushed PSNR, [PSNR pairs], mIoU, [mIoU pairs]: columns
        // are the quantity, rows absolute then paired.
        let areas = root.split_evenly((rows, 2));
        for (i, panel) in panels.iter().enumerate() {
            let (column, row) = (i / rows, i % rows);
            draw_panel(root, &areas[row * 2 + column], panel)?;
        }
        Ok(())
    })
}

fn draw_panel(root: &Canvas<'_>, area: &Canvas<'_>, panel: &Panel<'_>) -> Result<(), String> {
    let n = panel.groups.len();
    let (base, band) = (panel.base, panel.band);
    let (lo, hi) = panel
        .groups
        .iter()
        .flat_map(|(_, v)| v.iter())
        .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    let (lo, hi) = (lo.min(base - band) - 0.5, hi.max(base + band) + 0.5);
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.caption, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0f64..n as f64, lo..hi)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .y_desc(panel.unit)
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series([Rectangle::new(
            [(0.0, base - band), (n as f64, base + band)],
            RGBColor(120, 180, 120).mix(0.25).filled(),
        )])
        .map_err(|e| e.to_string())?;
    for (i, (name, v)) in panel.groups.iter().enumerate() {
        let (x, m) = (i as f64, mean(v));
        chart
            .draw_series([PathElement::new(
                vec![(x + 0.2, m), (x + 0.8, m)],
                Palette99::pick(i).stroke_width(4),
            )])
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(v.iter().enumerate().map(|(j, &y)| {
                let dx = 0.3 + 0.4 * j as f64 / (v.len() as f64 - 1.0).max(1.0);
                Circle::new((x + dx, y), 4, BLACK.filled())
            }))
            .map_err(|e| e.to_string())?;
        let (px, py) = chart.backend_coord(&(x + 0.5, lo));
        root.draw(&Text::new(
            format!("{name} ({})", v.len()),
            (px - 35, py + 10),
            ("sans-serif", 13).into_font().color(&BLACK),
        ))
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}
