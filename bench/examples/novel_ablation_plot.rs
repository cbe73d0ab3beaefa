//! The novel-view ablation as a picture: per run kind (none, trajectory,
//! random, guided, then any oracle or tagged variant), the mean mIoU over
//! the seeds as a bar with each seed as a dot, all classes on the left and
//! the tail classes on the right; the numbers beside it in a CSV.
//!
//! `cargo run -p bench --release --example novel_ablation_plot -- DIR [METHOD]`
//!
//! reads `DIR/seed-*/<run>/seg/segmentation_compare.json` (written by
//! `scripts/novel-ablation.sh`) and writes `DIR/ablation.png` and
//! `DIR/ablation.csv` (METHOD: the field mode scored, `hybrid` by default).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use field_ops::plot::draw_png;
use field_ops::scores::SegmentationScores;
use plotters::prelude::*;

/// The ablation's own modes, drawn first and in this order.
const MODES: [&str; 4] = ["none", "trajectory", "random", "guided"];

/// mIoU of one run kind, per seed: (all, tail), percent.
type Scores = BTreeMap<String, (f64, Option<f64>)>;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(
        args.next()
            .ok_or("usage: novel_ablation_plot DIR [METHOD]")?,
    );
    let method = args.next().unwrap_or_else(|| "hybrid".into());
    let runs = collect(&dir, &method)?;
    if runs.is_empty() {
        return Err(format!(
            "{}: no seed-*/<run>/seg/segmentation_compare.json with a `{method}` row",
            dir.display()
        )
        .into());
    }
    let csv = dir.join("ablation.csv");
    let mut text = String::from("run,seed,miou_all,miou_tail\n");
    for (run, seeds) in &runs {
        for (seed, (all, tail)) in seeds {
            let tail = tail.map_or(String::new(), |t| format!("{t:.2}"));
            text.push_str(&format!("{run},{seed},{all:.2},{tail}\n"));
        }
    }
    std::fs::write(&csv, text).map_err(|e| format!("{}: {e}", csv.display()))?;
    let png = dir.join("ablation.png");
    plot(&png, &runs, &method)?;
    println!("wrote {}", csv.display());
    println!("wrote {}", png.display());
    Ok(())
}

/// Every run kind found under `dir`, in drawing order, with its scores.
fn collect(dir: &Path, method: &str) -> Result<Vec<(String, Scores)>, String> {
    let read_dir = |d: &Path| -> Result<Vec<PathBuf>, String> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(d)
            .map_err(|e| format!("{}: {e}", d.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_dir())
            .collect();
        v.sort();
        Ok(v)
    };
    let mut by_run: BTreeMap<String, Scores> = BTreeMap::new();
    for seed in read_dir(dir)? {
        let Some(name) = seed.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        let Some(seed_name) = name.strip_prefix("seed-") else {
            continue;
        };
        for run in read_dir(&seed)? {
            let file = run.join("seg").join("segmentation_compare.json");
            if !file.exists() {
                continue;
            }
            let text =
                std::fs::read_to_string(&file).map_err(|e| format!("{}: {e}", file.display()))?;
            let rows: Vec<SegmentationScores> =
                serde_json::from_str(&text).map_err(|e| format!("{}: {e}", file.display()))?;
            let Some(row) = rows.iter().find(|r| r.mode == method) else {
                continue;
            };
            let Some(all) = row.all.miou else { continue };
            let tail = row.tail.and_then(|t| t.miou).map(|t| 100.0 * t);
            let run_name = run.file_name().and_then(|n| n.to_str()).unwrap_or("?");
            by_run
                .entry(run_name.to_string())
                .or_default()
                .insert(seed_name.to_string(), (100.0 * all, tail));
        }
    }
    let mut out: Vec<(String, Scores)> = MODES
        .iter()
        .filter_map(|m| by_run.remove(*m).map(|s| (m.to_string(), s)))
        .collect();
    out.extend(by_run);
    Ok(out)
}

/// Two panels of bars (mean over seeds) with a dot per seed.
fn plot(path: &Path, runs: &[(String, Scores)], method: &str) -> Result<(), String> {
    let (w, h) = (1100u32, 680u32);
    let n = runs.len();
    draw_png(path, w, h, |root| {
        let panels = root.split_evenly((1, 2));
        for (panel, tail) in panels.iter().zip([false, true]) {
            let values = |s: &Scores| -> Vec<f64> {
                s.values()
                    .filter_map(|&(a, t)| if tail { t } else { Some(a) })
                    .collect()
            };
            let top = runs
                .iter()
                .flat_map(|(_, s)| values(s))
                .fold(1.0f64, f64::max)
                * 1.15;
            let mut chart = ChartBuilder::on(panel)
                .caption(
                    format!(
                        "{} mIoU ({method}), bar = mean, dot = seed",
                        if tail { "tail" } else { "all classes" }
                    ),
                    ("sans-serif", 18),
                )
                .margin(12)
                .x_label_area_size(250)
                .y_label_area_size(50)
                .build_cartesian_2d(0f64..n as f64, 0f64..top)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(0)
                .y_desc("mIoU, percent")
                .draw()
                .map_err(|e| e.to_string())?;
            for (i, (name, scores)) in runs.iter().enumerate() {
                let v = values(scores);
                if v.is_empty() {
                    continue;
                }
                let mean = v.iter().sum::<f64>() / v.len() as f64;
                let x = i as f64;
                let color = Palette99::pick(i).mix(0.8);
                chart
                    .draw_series([Rectangle::new(
                        [(x + 0.15, 0.0), (x + 0.85, mean)],
                        color.filled(),
                    )])
                    .map_err(|e| e.to_string())?;
                chart
                    .draw_series(v.iter().enumerate().map(|(j, &y)| {
                        let dx = 0.3 + 0.4 * j as f64 / v.len().max(2) as f64;
                        Circle::new((x + dx, y), 4, BLACK.filled())
                    }))
                    .map_err(|e| e.to_string())?;
                // The mean inside the bar's foot, clear of the seeds' dots.
                chart
                    .draw_series([Text::new(
                        format!("{mean:.1}"),
                        (x + 0.22, top * 0.05),
                        ("sans-serif", 15),
                    )])
                    .map_err(|e| e.to_string())?;
                // Run names, written downwards under their bars, on the
                // whole canvas (the chart clips what lies outside its axes).
                let style = ("sans-serif", 13)
                    .into_font()
                    .transform(FontTransform::Rotate90)
                    .color(&BLACK);
                let (px, py) = chart.backend_coord(&(x + 0.5, 0.0));
                root.draw(&Text::new(
                    format!("{name} ({})", v.len()),
                    (px + 7, py + 6),
                    style,
                ))
                .map_err(|e| e.to_string())?;
            }
        }
        Ok(())
    })
}
