//! Text queries on the points and on rendered pixels: each positive is a
//! class name or free text; with negatives the score is LERF's relevancy
//! (the lowest, over negatives, of the pairwise softmax of the cosines),
//! without them the cosine. Several positives take the highest score.

use datasets::features::PcaBasis;
use field_ops::query::{RELEVANCY_THRESHOLD, RelevancyScale, cosine_scores};

use crate::ViewerError;
use crate::state::Viewer;

/// Items a list may hold (each side).
pub const MAX_ITEMS: usize = 16;
/// Characters an item may have.
pub const MAX_ITEM_CHARS: usize = 200;

/// LERF's canonical negatives, the default where free text can be embedded.
pub const CANONICAL_NEGATIVES: &str = "object;things;stuff;texture";

/// A query as the page sends it: `;`-separated lists.
#[derive(Debug, Clone, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QueryRequest {
    /// What to find.
    #[serde(default)]
    pub positives: String,
    /// What it should stand out from (may be empty).
    #[serde(default)]
    pub negatives: String,
}

/// A query with its embeddings.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedQuery {
    /// Positive texts and their embeddings.
    pub positives: Vec<(String, Vec<f32>)>,
    /// Negative texts and their embeddings.
    pub negatives: Vec<(String, Vec<f32>)>,
}

/// The items of a `;`-separated list (trimmed, empty ones dropped).
pub fn split_list(list: &str, what: &str) -> Result<Vec<String>, ViewerError> {
    let items: Vec<String> = list
        .split(';')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(String::from)
        .collect();
    if items.len() > MAX_ITEMS {
        return Err(ViewerError::BadRequest(format!(
            "{what}: {} items, at most {MAX_ITEMS}",
            items.len()
        )));
    }
    if let Some(long) = items.iter().find(|s| s.chars().count() > MAX_ITEM_CHARS) {
        return Err(ViewerError::BadRequest(format!(
            "{what}: an item of {} characters, at most {MAX_ITEM_CHARS}",
            long.chars().count()
        )));
    }
    Ok(items)
}

/// Embeddings of `texts`: a class name takes its class embedding, other
/// text is embedded by the viewer's text model.
fn embed(viewer: &Viewer, texts: &[String]) -> Result<Vec<Vec<f32>>, ViewerError> {
    let d = &viewer.data;
    let class = |t: &str| {
        let c = d.classes.as_ref()?;
        let i = c.names.iter().position(|n| n.eq_ignore_ascii_case(t))?;
        Some(c.data[i * c.dim..(i + 1) * c.dim].to_vec())
    };
    let known: Vec<Option<Vec<f32>>> = texts.iter().map(|t| class(t)).collect();
    let unknown: Vec<String> = texts
        .iter()
        .zip(&known)
        .filter(|(_, k)| k.is_none())
        .map(|(t, _)| t.clone())
        .collect();
    let mut free = Vec::new();
    if !unknown.is_empty() {
        let Some(dir) = &d.options.text_model else {
            let names = d
                .classes
                .as_ref()
                .map(|c| c.names.join(", "))
                .unwrap_or_default();
            return Err(ViewerError::BadRequest(format!(
                "{:?} is not a class of this run (classes: {}); free text needs a CLIP text \
                 model (--text-model DIR)",
                unknown[0],
                if names.is_empty() { "none" } else { &names }
            )));
        };
        let _one_at_a_time = viewer.embedding.lock().unwrap_or_else(|e| e.into_inner());
        let e = field_ops::text_query::embed(dir, &unknown, &d.run.dir, &d.meta, &viewer.device)?;
        free = e.data.chunks(e.dim.max(1)).map(<[f32]>::to_vec).collect();
    }
    let mut free = free.into_iter();
    texts
        .iter()
        .zip(known)
        .map(|(t, k)| {
            k.or_else(|| free.next())
                .ok_or_else(|| ViewerError::BadRequest(format!("{t:?} could not be embedded")))
        })
        .collect()
}

/// Embeds the request's positives and negatives.
pub fn resolve(viewer: &Viewer, req: &QueryRequest) -> Result<ResolvedQuery, ViewerError> {
    let positives = split_list(&req.positives, "positives")?;
    if positives.is_empty() {
        return Err(ViewerError::BadRequest(
            "positives: give a class name or text to look for".into(),
        ));
    }
    let negatives = split_list(&req.negatives, "negatives")?;
    let pe = embed(viewer, &positives)?;
    let ne = embed(viewer, &negatives)?;
    Ok(ResolvedQuery {
        positives: positives.into_iter().zip(pe).collect(),
        negatives: negatives.into_iter().zip(ne).collect(),
    })
}

/// What the score is: the cosine (no negatives) or LERF's relevancy.
pub fn quantity(q: &ResolvedQuery) -> &'static str {
    if q.negatives.is_empty() {
        "cosine"
    } else {
        "relevancy"
    }
}

/// The score of every row of `features` (`[n, k]`, the field's output
/// space): the highest over positives of the cosine, or with negatives of
/// `min_j exp(c_p) / (exp(c_p) + exp(c_j))`.
pub fn scores(
    features: &[f32],
    q: &ResolvedQuery,
    pca: Option<&PcaBasis>,
) -> Result<Vec<f64>, ViewerError> {
    let cos = |e: &[f32]| cosine_scores(features, e, pca).map_err(ViewerError::from);
    let negatives: Vec<Vec<f64>> = q
        .negatives
        .iter()
        .map(|(_, e)| cos(e))
        .collect::<Result<_, _>>()?;
    let mut best: Option<Vec<f64>> = None;
    for (_, e) in &q.positives {
        let p = cos(e)?;
        let s: Vec<f64> = if negatives.is_empty() {
            p
        } else {
            p.iter()
                .enumerate()
                .map(|(i, &cp)| {
                    negatives
                        .iter()
                        .map(|n| 1.0 / (1.0 + (n[i] - cp).exp()))
                        .fold(f64::INFINITY, f64::min)
                })
                .collect()
        };
        best = Some(match best {
            None => s,
            Some(b) => b.iter().zip(&s).map(|(a, b)| a.max(*b)).collect(),
        });
    }
    Ok(best.unwrap_or_default())
}

/// A query's answer on the points.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct QueryResult {
    /// The positives as understood.
    pub positives: Vec<String>,
    /// The negatives as understood.
    pub negatives: Vec<String>,
    /// `cosine` or `relevancy`.
    pub quantity: &'static str,
    /// The score at the colour bar's bottom (normalised 0).
    pub lo: f64,
    /// The score at the top (normalised 1).
    pub hi: f64,
    /// The score at the default threshold.
    pub cut: f64,
    /// The default threshold, normalised.
    pub threshold: f32,
    /// Normalised score of every point, `[0, 1]`.
    pub values: Vec<f32>,
}

/// Scores the viewer's points for `req` under the current field.
pub fn query_points(viewer: &Viewer, req: &QueryRequest) -> Result<QueryResult, ViewerError> {
    score_points(viewer, &resolve(viewer, req)?)
}

/// Scores the viewer's points for the embedded query `q` under the current
/// field.
pub fn score_points(viewer: &Viewer, q: &ResolvedQuery) -> Result<QueryResult, ViewerError> {
    let f = viewer.point_features();
    let s = scores(&f.features, q, viewer.data.meta.pca.as_ref())?;
    let scale = RelevancyScale::spanning([s.as_slice()]);
    Ok(QueryResult {
        positives: q.positives.iter().map(|p| p.0.clone()).collect(),
        negatives: q.negatives.iter().map(|p| p.0.clone()).collect(),
        quantity: quantity(q),
        lo: scale.lo,
        hi: scale.hi,
        cut: scale.lo + RELEVANCY_THRESHOLD as f64 * (scale.hi - scale.lo),
        threshold: RELEVANCY_THRESHOLD,
        values: scale.apply(&s),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(pos: &[&[f32]], neg: &[&[f32]]) -> ResolvedQuery {
        let named = |v: &[&[f32]]| v.iter().map(|e| (String::new(), e.to_vec())).collect();
        ResolvedQuery {
            positives: named(pos),
            negatives: named(neg),
        }
    }

    #[test]
    fn relevancy_is_the_pairwise_softmax_against_the_closest_negative() {
        // Two unit features: along x and along y.
        let features = [1.0, 0.0, 0.0, 1.0];
        let s = scores(
            &features,
            &q(&[&[1.0, 0.0]], &[&[0.0, 1.0], &[0.6, 0.8]]),
            None,
        )
        .expect("scores");
        // Point 0: c_p = 1, c_n = 0 and 0.6 -> min(sigmoid(1), sigmoid(0.4)).
        let sig = |x: f64| 1.0 / (1.0 + (-x).exp());
        assert!((s[0] - sig(0.4)).abs() < 1e-6, "{s:?}");
        // Point 1: c_p = 0, c_n = 1 and 0.8 -> sigmoid(-1).
        assert!((s[1] - sig(-1.0)).abs() < 1e-6, "{s:?}");
    }

    #[test]
    fn several_positives_take_the_highest_cosine() {
        let features = [1.0, 0.0, 0.0, 1.0];
        let s = scores(&features, &q(&[&[1.0, 0.0], &[0.0, 1.0]], &[]), None).expect("scores");
        assert_eq!(s, vec![1.0, 1.0]);
        let s = scores(&features, &q(&[&[1.0, 1.0]], &[]), None).expect("scores");
        assert!((s[0] - 0.5f64.sqrt()).abs() < 1e-6, "{s:?}");
    }

    #[test]
    fn lists_are_split_trimmed_and_bounded() {
        assert_eq!(
            split_list(" chair ; ;sofa", "positives").expect("list"),
            vec!["chair".to_string(), "sofa".to_string()]
        );
        let many = vec!["x"; MAX_ITEMS + 1].join(";");
        assert!(split_list(&many, "negatives").is_err());
        assert!(split_list(&"y".repeat(MAX_ITEM_CHARS + 1), "positives").is_err());
    }
}
