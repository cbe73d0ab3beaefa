//! The sweep's report: `sweep.csv`, `sweep.json` and the accuracy-against-
//! seconds plots, marker area proportional to peak memory, the Pareto
//! points joined and labelled.

use std::path::Path;

use plotters::prelude::*;

use super::{SweepResult, pareto};

/// Writes `sweep.csv`, `sweep.json`, `psnr_vs_seconds.png` and, when any
/// point has an SSIM or a segmentation score, `ssim_vs_seconds.png` and
/// `miou_vs_seconds.png` into `dir`.
pub fn write_report(results: &[SweepResult], dir: &Path) -> Result<(), String> {
    let io = |p: &Path, e: std::io::Error| format!("{}: {e}", p.display());
    let psnr: Vec<(f64, f64)> = results
        .iter()
        .map(|r| (r.train_seconds, r.psnr_interior))
        .collect();
    let psnr_front = pareto(&psnr);
    let ssim: Vec<(f64, f64)> = results
        .iter()
        .map(|r| (r.train_seconds, r.ssim_interior.unwrap_or(f64::NAN)))
        .collect();
    let ssim_front = pareto(&ssim);
    let miou: Vec<(f64, f64)> = results
        .iter()
        .map(|r| (r.train_seconds, r.miou.unwrap_or(f64::NAN)))
        .collect();
    let miou_front = pareto(&miou);
    let opt = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:.4}"));
    let mut csv = String::from(
        "point,flags,budget_s,train_seconds,wall_seconds,iterations,rays_per_second,peak_memory_mb,psnr_interior,\
         psnr_whole,ssim_interior,depth_mae,miou,miou_tail,pareto_psnr,pareto_ssim,pareto_miou\n",
    );
    for (i, r) in results.iter().enumerate() {
        csv.push_str(&format!(
            "{},{},{},{:.2},{:.2},{},{:.1},{},{:.4},{},{},{},{},{},{},{},{}\n",
            r.point.name,
            r.point.flags.join(" "),
            r.point.budget,
            r.train_seconds,
            r.wall_seconds,
            r.iterations,
            r.rays_per_second,
            r.peak_memory_bytes
                .map_or(String::new(), |b| format!("{:.1}", b as f64 / 1e6)),
            r.psnr_interior,
            opt(r.psnr_whole),
            opt(r.ssim_interior),
            opt(r.depth_mae),
            opt(r.miou),
            opt(r.miou_tail),
            psnr_front.contains(&i),
            ssim_front.contains(&i),
            miou_front.contains(&i),
        ));
    }
    let path = dir.join("sweep.csv");
    std::fs::write(&path, csv).map_err(|e| io(&path, e))?;
    let json = serde_json::json!({
        "psnr_measured_on": "every held-out view rendered in full, interior pixels",
        "ssim_measured_on": "every held-out view rendered in full, interior window centres, mean over views",
        "miou": "hybrid 3D segmentation of the scene's labelled points, percent",
        "points": results,
        "pareto_psnr": psnr_front.iter().map(|&i| &results[i].point.name).collect::<Vec<_>>(),
        "pareto_ssim": ssim_front.iter().map(|&i| &results[i].point.name).collect::<Vec<_>>(),
        "pareto_miou": miou_front.iter().map(|&i| &results[i].point.name).collect::<Vec<_>>(),
    });
    let path = dir.join("sweep.json");
    let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
    std::fs::write(&path, text).map_err(|e| io(&path, e))?;
    let memory: Vec<f64> = results
        .iter()
        .map(|r| r.peak_memory_bytes.unwrap_or(0) as f64 / 1e6)
        .collect();
    let names: Vec<&str> = results.iter().map(|r| r.point.name.as_str()).collect();
    // PSNR always; SSIM and mIoU where some point has them.
    let plots = [
        (
            "psnr_vs_seconds.png",
            "held-out PSNR (dB, interior pixels)",
            &psnr,
            &psnr_front,
            true,
        ),
        (
            "ssim_vs_seconds.png",
            "held-out SSIM (interior pixels)",
            &ssim,
            &ssim_front,
            !ssim_front.is_empty(),
        ),
        (
            "miou_vs_seconds.png",
            "hybrid mIoU (%)",
            &miou,
            &miou_front,
            !miou_front.is_empty(),
        ),
    ];
    for (file, what, points, front, drawn) in plots {
        if drawn {
            let caption = format!("{what} against seconds; marker area = peak memory");
            scatter(&dir.join(file), &caption, points, &memory, &names, front)?;
        }
    }
    Ok(())
}

fn scatter(
    path: &Path,
    caption: &str,
    points: &[(f64, f64)],
    memory_mb: &[f64],
    names: &[&str],
    front: &[usize],
) -> Result<(), String> {
    let finite: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect();
    // Room on the right for the label of the slowest front point.
    let t_max = finite.iter().map(|p| p.0).fold(1.0, f64::max) * 1.3;
    let y_lo = finite.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let y_hi = finite.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let (y_lo, y_hi) = if y_lo.is_finite() {
        let pad = 0.1 * (y_hi - y_lo).max(0.5);
        (y_lo - pad, y_hi + pad)
    } else {
        (0.0, 1.0)
    };
    let m_max = memory_mb.iter().copied().fold(1.0, f64::max);
    let (w, h) = (1000u32, 650u32);
    field_ops::plot::draw_png(path, w, h, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(caption, ("sans-serif", 17))
            .margin(14)
            .x_label_area_size(35)
            .y_label_area_size(50)
            .build_cartesian_2d(0f64..t_max, y_lo..y_hi)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("seconds of training")
            .draw()
            .map_err(|e| e.to_string())?;
        let radius = |i: usize| (3.0 + 12.0 * (memory_mb[i] / m_max).sqrt()) as i32;
        chart
            .draw_series(
                (0..points.len())
                    .filter(|&i| points[i].0.is_finite() && points[i].1.is_finite())
                    .map(|i| Circle::new(points[i], radius(i), BLUE.mix(0.35).filled())),
            )
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(LineSeries::new(
                front.iter().map(|&i| points[i]),
                RED.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(front.iter().map(|&i| {
                Text::new(
                    names[i].to_string(),
                    (points[i].0, points[i].1),
                    ("sans-serif", 13).into_font().color(&RED),
                )
            }))
            .map_err(|e| e.to_string())?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::SweepPoint;

    fn result(name: &str, seconds: f64, psnr: f64, ssim: Option<f64>) -> SweepResult {
        SweepResult {
            point: SweepPoint {
                name: name.into(),
                flags: vec![],
                budget: seconds,
            },
            train_seconds: seconds,
            wall_seconds: seconds + 1.0,
            iterations: 10,
            rays_per_second: 100.0,
            peak_memory_bytes: Some(1_000_000),
            psnr_interior: psnr,
            psnr_whole: None,
            ssim_interior: ssim,
            depth_mae: None,
            miou: None,
            miou_tail: None,
        }
    }

    #[test]
    fn ssim_has_its_column_and_front_where_points_have_it() {
        let dir = tempfile::tempdir().unwrap();
        // `b` is slower and more accurate in PSNR, less in SSIM: it is on the
        // PSNR front only.
        let results = [
            result("a", 10.0, 20.0, Some(0.8)),
            result("b", 20.0, 22.0, Some(0.7)),
        ];
        write_report(&results, dir.path()).unwrap();
        let csv = std::fs::read_to_string(dir.path().join("sweep.csv")).unwrap();
        let lines: Vec<&str> = csv.lines().collect();
        assert!(
            lines[0].contains(",psnr_whole,ssim_interior,depth_mae,")
                && lines[0].ends_with(",pareto_psnr,pareto_ssim,pareto_miou"),
            "{csv}"
        );
        assert!(lines[1].ends_with(",0.8000,,,,true,true,false"), "{csv}");
        assert!(lines[2].ends_with(",0.7000,,,,true,false,false"), "{csv}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("sweep.json")).unwrap())
                .unwrap();
        assert_eq!(json["pareto_ssim"], serde_json::json!(["a"]));
        assert!(dir.path().join("ssim_vs_seconds.png").exists());
        assert!(!dir.path().join("miou_vs_seconds.png").exists());

        // A sweep without SSIM draws no SSIM front.
        let old = tempfile::tempdir().unwrap();
        write_report(&[result("a", 10.0, 20.0, None)], old.path()).unwrap();
        assert!(old.path().join("psnr_vs_seconds.png").exists());
        assert!(!old.path().join("ssim_vs_seconds.png").exists());
    }
}
