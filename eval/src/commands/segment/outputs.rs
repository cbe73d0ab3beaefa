//! What `eval segment` writes: `segmentation.json` with the prediction and
//! error PLYs for labelled points, or the prediction PLY and the class
//! counts for points without ground truth.

use std::path::Path;

use field_ops::OpsError;
use field_ops::frame::OutputFrame;
use field_ops::json::write_json;
use field_ops::scores::SegmentationScores;

use crate::segment::{EvalPoints, SegmentMode, write_prediction_plys};

/// Points without ground truth: the class counts printed and the
/// prediction PLY written, no scores.
pub(super) fn write_unscored(
    dir: &Path,
    mode: SegmentMode,
    points: &EvalPoints,
    pred: &[u32],
    seen: usize,
    views: usize,
    frame: &OutputFrame,
) -> Result<(), OpsError> {
    println!(
        "{} points, {} classes, {views} views; {seen} points seen by a view",
        points.positions.len(),
        points.names.len(),
    );
    println!("the points have no ground-truth labels: predicted classes only, no scores");
    for (c, name) in points.names.iter().enumerate() {
        let n = pred.iter().filter(|&&p| p == c as u32).count();
        println!("  {name:<24} {n:>8} points");
    }
    for path in write_prediction_plys(dir, &format!("segmentation_{mode}"), points, pred, frame)? {
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Writes `segmentation.json` and the prediction / error PLYs into `dir`.
pub(super) fn write_scores(
    dir: &Path,
    mode: SegmentMode,
    scores: &SegmentationScores,
    points: &EvalPoints,
    pred: &[u32],
    frame: &OutputFrame,
) -> Result<(), OpsError> {
    std::fs::create_dir_all(dir).map_err(|e| OpsError::io(dir, e))?;
    let out = dir.join("segmentation.json");
    write_json(&out, scores)?;
    let stem = format!("segmentation_{mode}");
    write_prediction_plys(dir, &stem, points, pred, frame)?;
    for path in [
        out,
        dir.join(format!("{stem}_pred.ply")),
        dir.join(format!("{stem}_error.ply")),
    ] {
        println!("wrote {}", path.display());
    }
    Ok(())
}
