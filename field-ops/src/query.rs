//! Relevancy queries: how strongly each pixel of a rendered view, or each
//! point of a cloud, matches one query embedding (a class name's text
//! embedding or a raw vector).

use std::path::Path;

use datasets::features::PcaBasis;
use datasets::npy::read_npy_f32;
use datasets::text::TextEmbeddings;

use crate::OpsError;
use crate::colormap::{to_u8, turbo};
use crate::render::RenderedView;
use crate::similarity::ClassScorer;

/// Relevancy below this (after scaling to `[0, 1]`) leaves the rendered colour.
pub const RELEVANCY_THRESHOLD: f32 = 0.5;

/// The query vector: the embedding of class `name` in `texts`.
pub fn embedding_by_name(texts: &TextEmbeddings, name: &str) -> Result<Vec<f32>, OpsError> {
    let i = texts.index_of(name).ok_or_else(|| {
        let some: Vec<&str> = texts.names.iter().take(8).map(String::as_str).collect();
        OpsError::Invalid(format!(
            "no class {name:?} among {} class names (e.g. {})",
            texts.names.len(),
            some.join(", ")
        ))
    })?;
    Ok(texts.row(i).to_vec())
}

/// The query vector stored in `path` (`.npy` of shape `[D]` or `[1, D]`).
pub fn embedding_from_npy(path: &Path) -> Result<Vec<f32>, OpsError> {
    let (shape, data) = read_npy_f32(path)?;
    let ok = matches!(shape.as_slice(), [_] | [1, _]);
    if !ok || data.is_empty() || data.iter().any(|v| !v.is_finite()) {
        return Err(OpsError::Invalid(format!(
            "{}: expected one finite embedding of shape [D] or [1, D], got {shape:?}",
            path.display()
        )));
    }
    Ok(data)
}

/// Cosine similarity of every row of `features` (`[n, k]`, the field's
/// output space) with `query` (`[D]`), exact in the lifted space.
pub fn cosine_scores(
    features: &[f32],
    query: &[f32],
    pca: Option<&PcaBasis>,
) -> Result<Vec<f64>, OpsError> {
    let scorer = ClassScorer::new(query, query.len(), pca)?;
    let k = scorer.dim;
    if k == 0 || !features.len().is_multiple_of(k) {
        return Err(OpsError::Invalid(format!(
            "features of {} values do not split into rows of {k}",
            features.len()
        )));
    }
    let mut out = [0.0];
    Ok(features
        .chunks(k)
        .map(|f| {
            scorer.cosines(f, &mut out);
            out[0]
        })
        .collect())
}

/// Scales scores to `[0, 1]` over the whole set (min to 0, max to 1; a
/// constant set maps to 0).
pub fn normalize_scores(scores: &[f64]) -> Vec<f32> {
    let lo = scores.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = hi - lo;
    scores
        .iter()
        .map(|&s| {
            if span > 1e-12 {
                ((s - lo) / span) as f32
            } else {
                0.0
            }
        })
        .collect()
}

/// One linear map from cosine similarity to relevancy in `[0, 1]`, shared
/// by every view of a query: the lowest cosine over all views maps to 0, the
/// highest to 1. Scaling each view on its own would give every view a "hot"
/// region, even one that does not show the queried class at all.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelevancyScale {
    /// Cosine at relevancy 0.
    pub lo: f64,
    /// Cosine at relevancy 1.
    pub hi: f64,
}

impl RelevancyScale {
    /// The scale spanning every finite score of `sets`.
    pub fn spanning<'a>(sets: impl IntoIterator<Item = &'a [f64]>) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &s in sets.into_iter().flatten() {
            if s.is_finite() {
                lo = lo.min(s);
                hi = hi.max(s);
            }
        }
        if lo > hi {
            (lo, hi) = (0.0, 0.0);
        }
        Self { lo, hi }
    }

    /// Relevancy of each score (0 for a constant scale).
    pub fn apply(&self, scores: &[f64]) -> Vec<f32> {
        let span = self.hi - self.lo;
        scores
            .iter()
            .map(|&s| {
                if span > 1e-12 && s.is_finite() {
                    ((s - self.lo) / span).clamp(0.0, 1.0) as f32
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// Cosine similarity of every pixel of `view`'s feature image with `query`.
pub fn view_cosines(
    view: &RenderedView,
    query: &[f32],
    pca: Option<&PcaBasis>,
) -> Result<Vec<f64>, OpsError> {
    if view.feature_dim == 0 {
        return Err(OpsError::Invalid("the view has no feature image".into()));
    }
    cosine_scores(&view.feature, query, pca)
}

/// Relevancy of every pixel of `view` in `[0, 1]`, scaled over this view
/// alone (see [`RelevancyScale`] for a scale shared across views).
pub fn relevancy_image(
    view: &RenderedView,
    query: &[f32],
    pca: Option<&PcaBasis>,
) -> Result<Vec<f32>, OpsError> {
    if view.feature_dim == 0 {
        return Err(OpsError::Invalid("the view has no feature image".into()));
    }
    Ok(normalize_scores(&cosine_scores(&view.feature, query, pca)?))
}

/// Overlay of relevancy on the rendered colour: pixels below
/// [`RELEVANCY_THRESHOLD`] keep their colour, the others take Turbo of
/// their relevancy. Returns `3 * n` bytes.
pub fn relevancy_overlay(rgb: &[f32], relevancy: &[f32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(rgb.len());
    for (i, &r) in relevancy.iter().enumerate() {
        let c = if r >= RELEVANCY_THRESHOLD {
            turbo(r)
        } else {
            [rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]]
        };
        out.extend(c.map(to_u8));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scores_normalise_and_overlay_thresholds() {
        let feats = [1.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let s = cosine_scores(&feats, &[1.0, 0.0], None).unwrap();
        assert!((s[0] - 1.0).abs() < 1e-12 && s[1].abs() < 1e-12);
        assert!((s[2] - 0.5f64.sqrt()).abs() < 1e-12);
        let n = normalize_scores(&s);
        assert_eq!(n[0], 1.0);
        assert_eq!(n[1], 0.0);
        assert!((n[2] - 0.5f32.sqrt()).abs() < 1e-6);
        let rgb = [0.2; 9];
        let o = relevancy_overlay(&rgb, &n);
        assert_eq!(&o[3..6], &[51, 51, 51]);
        assert_eq!(&o[0..3], &turbo(1.0).map(to_u8));
        assert_eq!(&o[6..9], &turbo(n[2]).map(to_u8));
        assert_eq!(normalize_scores(&[3.0, 3.0]), vec![0.0, 0.0]);
    }

    #[test]
    fn one_scale_across_views_leaves_a_view_without_the_class_cold() {
        // View a shows the class (cosine 0.9), view b does not (at most 0.3).
        let a = [0.9, 0.1, 0.2];
        let b = [0.3, 0.1, 0.25];
        let scale = RelevancyScale::spanning([&a[..], &b[..]]);
        assert_eq!((scale.lo, scale.hi), (0.1, 0.9));
        let rb = scale.apply(&b);
        assert!(rb.iter().all(|&r| r < RELEVANCY_THRESHOLD), "{rb:?}");
        assert_eq!(scale.apply(&a)[0], 1.0);
        // Scaled alone, view b would have been "hot" where it is least cold.
        assert_eq!(normalize_scores(&b)[0], 1.0);
        let flat = RelevancyScale::spanning([&[0.5, 0.5][..]]);
        assert_eq!(flat.apply(&[0.5]), vec![0.0]);
    }

    #[test]
    fn query_by_name_and_npy() {
        let t = TextEmbeddings {
            names: vec!["wall".into(), "chair".into()],
            dim: 2,
            data: vec![1.0, 0.0, 0.0, 1.0],
        };
        assert_eq!(embedding_by_name(&t, "chair").unwrap(), vec![0.0, 1.0]);
        assert!(embedding_by_name(&t, "sofa").is_err());
        let dir = std::env::temp_dir().join(format!("eval-query-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("q.npy");
        datasets::npy::write_npy_f32(&p, &[1, 3], &[0.5, 0.5, 0.0]).unwrap();
        assert_eq!(embedding_from_npy(&p).unwrap(), vec![0.5, 0.5, 0.0]);
        datasets::npy::write_npy_f32(&p, &[2, 2], &[0.5, 0.5, 0.0, 1.0]).unwrap();
        assert!(embedding_from_npy(&p).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
