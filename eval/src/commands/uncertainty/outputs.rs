//! The files of `eval uncertainty`: `uncertainty.json` (the summary),
//! `uncertainty.csv` (each point's figures), `uncertainty.ply` (the points
//! coloured by uncertainty) and, with feature errors, the scatter plot of
//! uncertainty against error.

use std::io::Write;
use std::path::{Path, PathBuf};

use datasets::points::{PointCloud, write_ply};
use field_ops::OpsError;
use field_ops::colormap::{to_u8, turbo};
use field_ops::json::write_json;
use field_ops::uncertainty::UncertaintyMap;
use field_ops::uncertainty::scatter::scatter;
use model::geometry::Vec3;

use super::Measured;

/// Writes the files into `out` (made if missing), the points at `points`
/// (in the output frame); returns the files written. A scatter plot that
/// cannot be drawn is a warning only.
pub(super) fn write_outputs(
    out: &Path,
    measured: &Measured,
    points: &[Vec3],
) -> Result<Vec<PathBuf>, OpsError> {
    let Measured {
        map,
        errors,
        summary,
    } = measured;
    std::fs::create_dir_all(out).map_err(|e| OpsError::io(out, e))?;
    let mut written = Vec::new();
    let json = out.join("uncertainty.json");
    write_json(&json, summary)?;
    written.push(json);
    let csv = out.join("uncertainty.csv");
    write_csv(&csv, points, map, errors.as_deref())?;
    written.push(csv);
    let ply = out.join("uncertainty.ply");
    write_uncertainty_ply(&ply, points, map)?;
    written.push(ply);
    if let Some(e) = errors {
        let png = out.join("uncertainty_scatter.png");
        // The numbers are in the CSV: a missing font costs the picture only.
        match scatter(&png, map, e, summary.pearson_r) {
            Ok(()) => written.push(png),
            Err(e) => eprintln!("warning: {e}"),
        }
    }
    Ok(written)
}

fn write_csv(
    path: &Path,
    points: &[Vec3],
    map: &UncertaintyMap,
    errors: Option<&[f64]>,
) -> Result<(), OpsError> {
    let io = |e| OpsError::io(path, e);
    let mut w = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
    writeln!(w, "x,y,z,views,log_det,uncertainty,feature_error").map_err(io)?;
    for (i, p) in points.iter().enumerate() {
        let e = errors.map_or(f64::NAN, |e| e[i]);
        writeln!(
            w,
            "{:.4},{:.4},{:.4},{},{:.5},{:.5},{}",
            p[0],
            p[1],
            p[2],
            map.counts[i],
            map.log_det[i],
            map.normalised[i],
            if e.is_finite() {
                format!("{e:.5}")
            } else {
                String::new()
            }
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)
}

fn write_uncertainty_ply(
    path: &Path,
    points: &[Vec3],
    map: &UncertaintyMap,
) -> Result<(), OpsError> {
    let colors = map
        .normalised
        .iter()
        .map(|&u| turbo(u as f32).map(to_u8))
        .collect();
    let cloud = PointCloud {
        positions: points.to_vec(),
        colors: Some(colors),
        labels: None,
    };
    let u: Vec<f32> = map.normalised.iter().map(|&u| u as f32).collect();
    let views: Vec<f32> = map.counts.iter().map(|&c| c as f32).collect();
    write_ply(path, &cloud, &[("uncertainty", &u), ("views", &views)]).map_err(OpsError::from)
}
