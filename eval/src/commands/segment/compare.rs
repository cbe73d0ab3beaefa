//! `segment --compare`: every field mode, the projection of the scene's own
//! 2D feature maps (no field: the bound the field is measured against) and
//! the ground-truth-feature oracle, scored in one table and written to
//! `segmentation_compare.json`.

use std::path::Path;

use datasets::features::FeatureSet;
use field_ops::OpsError;
use field_ops::json::write_json;
use field_ops::scores::SegmentationScores;

use super::SegmentViews;
use crate::metrics::format_table;
use crate::segment::{
    EvalPoints, SegmentMode, SegmentOptions, View, segment_oracle, segment_with_2d_features,
};

/// What is compared: the field's predictions in each mode and what the
/// bounds are computed from.
pub(super) struct Compared<'a> {
    /// `(mode, prediction, points seen)` of each field mode.
    pub(super) field_modes: &'a [(SegmentMode, Vec<u32>, usize)],
    /// The scene's 2D feature maps, if it has them.
    pub(super) features: Option<&'a FeatureSet>,
    pub(super) views: &'a SegmentViews<'a>,
    pub(super) points: &'a EvalPoints,
    pub(super) opts: &'a SegmentOptions,
}

/// Scores every row with `score_of`, prints the table and writes it to
/// `segmentation_compare.json` in `dir`.
pub(super) fn write_comparison(
    dir: &Path,
    compared: &Compared<'_>,
    score_of: &dyn Fn(&str, &[u32]) -> SegmentationScores,
) -> Result<(), OpsError> {
    let mut rows: Vec<SegmentationScores> = compared
        .field_modes
        .iter()
        .map(|(m, p, _)| score_of(&m.to_string(), p))
        .collect();
    rows.extend(bounds(
        compared.features,
        compared.views.frames.as_deref(),
        compared.points,
        &compared.views.views,
        compared.opts,
        score_of,
    )?);
    let table: Vec<(&str, &SegmentationScores)> =
        rows.iter().map(|r| (r.mode.as_str(), r)).collect();
    print!("{}", format_table(&table));
    let compare = dir.join("segmentation_compare.json");
    write_json(&compare, &rows)?;
    println!("wrote {}", compare.display());
    Ok(())
}

/// The comparison's bounds: the 2D feature maps projected without the
/// field (when the views are scene frames with maps) and the oracle.
fn bounds(
    features: Option<&FeatureSet>,
    view_frames: Option<&[usize]>,
    points: &EvalPoints,
    views: &[View<'_>],
    opts: &SegmentOptions,
    score_of: &dyn Fn(&str, &[u32]) -> SegmentationScores,
) -> Result<Vec<SegmentationScores>, OpsError> {
    let mut rows = Vec::new();
    let maps = match (view_frames, features) {
        (Some(frames), Some(set)) => frames
            .iter()
            .map(|&i| set.maps.get(i))
            .collect::<Option<Vec<_>>>(),
        _ => None,
    };
    match (maps, features) {
        (Some(maps), Some(set)) => {
            let pred = segment_with_2d_features(set, &maps, points, views, &opts.project)?;
            rows.push(score_of("2D-feature projection", &pred));
        }
        _ => {
            eprintln!("note: no 2D feature maps for these cameras; the 2D-feature bound is skipped")
        }
    }
    rows.push(score_of("oracle (GT features)", &segment_oracle(points)?));
    Ok(rows)
}
