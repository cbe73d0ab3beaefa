//! Checks shared by the subcommands, of arguments and of inputs that parse
//! but cannot be right, run before anything is loaded or rendered (each
//! subcommand checks its own flags with these). Each error names the
//! flag or the file and says what would work, instead of an out-of-range
//! value being rendered, scored or silently replaced.

use std::path::Path;

use datasets::SceneMeta;
use datasets::points::ClassMap;

use field_ops::OpsError;

pub(crate) fn invalid(message: String) -> OpsError {
    OpsError::Invalid(message)
}

/// `--NAME 0` for counts that must be at least one.
pub fn at_least_one(flag: &str, value: Option<usize>, hint: &str) -> Result<(), OpsError> {
    if value == Some(0) {
        return Err(invalid(format!("--{flag} 0: must be at least 1{hint}")));
    }
    Ok(())
}

/// `--max-views`: at least one when given.
pub fn max_views(value: Option<usize>) -> Result<(), OpsError> {
    at_least_one(
        "max-views",
        value,
        " (leave the flag out to use every camera)",
    )
}

/// A query radius: a finite, non-negative number of metres.
pub fn radius(value: f64) -> Result<(), OpsError> {
    if !(value.is_finite() && value >= 0.0) {
        return Err(invalid(format!(
            "--radius {value}: must be a finite, non-negative number of metres"
        )));
    }
    Ok(())
}

/// The query embedding must live in the run's feature space: as many values
/// as the feature maps it was trained on had channels. `source` names where
/// the embedding came from (the `.npy` file or the class name).
pub fn query_dimension(
    query: &[f32],
    meta: &SceneMeta,
    run: &Path,
    source: &str,
) -> Result<(), OpsError> {
    match meta.feature_dim {
        None => Err(invalid(format!(
            "{}: the run was trained without feature maps, so it cannot be queried \
             (train with --features)",
            run.display()
        ))),
        Some(d) if d != query.len() => Err(invalid(format!(
            "{source}: the query embedding has {} values but the run's features have {d} \
             (use an embedding from the model that made the feature maps)",
            query.len()
        ))),
        Some(_) => Ok(()),
    }
}

/// Point labels must name classes: with an identity map every non-negative
/// id must index a class name (negative ids mean "unlabelled"); with a
/// `--class-map` at least one id must be a mapped class. Otherwise every
/// point would be ignored and every score come out empty.
pub fn labels_in_range(
    raw: &[i64],
    map: &ClassMap,
    source: &Path,
    class_map: Option<&Path>,
) -> Result<(), OpsError> {
    let mapped = map.map(raw);
    match class_map {
        None => {
            let classes = map.names.len() as i64;
            let outside: Vec<i64> = raw.iter().copied().filter(|&l| l >= classes).collect();
            if let Some(max) = outside.iter().max() {
                return Err(invalid(format!(
                    "{}: {} of {} point labels are outside the {classes} classes \
                     (labels must be 0..{}, or negative for unlabelled; the largest is {max}); \
                     give --class-map for raw ids, or matching --embeddings/--names",
                    source.display(),
                    outside.len(),
                    raw.len(),
                    classes - 1
                )));
            }
        }
        Some(m) => {
            if mapped.iter().all(|&l| l == datasets::points::IGNORE_LABEL) {
                return Err(invalid(format!(
                    "{}: none of its {} point labels is a class id of {}",
                    source.display(),
                    raw.len(),
                    m.display()
                )));
            }
        }
    }
    if !raw.is_empty() && raw.iter().all(|&l| l < 0) {
        return Err(invalid(format!(
            "{}: every point is unlabelled (all labels negative); nothing can be scored",
            source.display()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_outside_the_classes_are_reported() {
        let map = ClassMap::identity(vec!["wall".into(), "floor".into()]);
        let src = Path::new("/d/cloud.ply");
        assert!(labels_in_range(&[0, 1, -1], &map, src, None).is_ok());
        let e = labels_in_range(&[0, 5, 7], &map, src, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/d/cloud.ply") && e.contains("2 of 3") && e.contains("7"),
            "{e}"
        );
        assert!(labels_in_range(&[-1, -1], &map, src, None).is_err());
        let cm = Path::new("/d/map.txt");
        assert!(labels_in_range(&[9, 9], &map, src, Some(cm)).is_err());
        assert!(labels_in_range(&[9, 1], &map, src, Some(cm)).is_ok());
    }
}
