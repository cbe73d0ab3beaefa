//! Free-text queries and class lists embedded by a CLIP text model
//! (`--text-model DIR`), with the embeddings cached in the run directory.

use std::path::Path;

use burn::tensor::Device;
use datasets::SceneMeta;
use datasets::text::TextEmbeddings;

use crate::OpsError;

/// The class names of `--classes "a, b, c"`: comma-separated, trimmed, each
/// non-empty and given once.
pub fn parse_classes(list: &str) -> Result<Vec<String>, OpsError> {
    let names: Vec<String> = list.split(',').map(|s| s.trim().to_string()).collect();
    if let Some(i) = names.iter().position(String::is_empty) {
        return Err(OpsError::Invalid(format!(
            "--classes {list:?}: class {} is empty (give names separated by commas, e.g. \
             --classes \"chair, wooden table, something to sit on\")",
            i + 1
        )));
    }
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(OpsError::Invalid(format!(
                "--classes {list:?}: {n:?} is given twice"
            )));
        }
    }
    Ok(names)
}

/// Checks `--text` / `--classes` and `--text-model` before anything is
/// loaded: the text is not blank and the model directory exists.
pub fn check_flags(
    text: Option<&str>,
    classes: Option<&str>,
    text_model: Option<&Path>,
) -> Result<(), OpsError> {
    if let Some(t) = text
        && t.trim().is_empty()
    {
        return Err(OpsError::Invalid(
            "--text: empty text; give some words to query, e.g. --text \"something to sit on\""
                .into(),
        ));
    }
    if let Some(list) = classes {
        parse_classes(list)?;
    }
    if let Some(dir) = text_model
        && !dir.is_dir()
    {
        return Err(OpsError::Invalid(format!(
            "--text-model {}: not a directory (a CLIP text model: model.safetensors, \
             config.json, vocab.json, merges.txt)",
            dir.display()
        )));
    }
    Ok(())
}

/// The text model of a run: `--text-model` when given, else the CLIP model
/// a `--vlm` run made its maps with.
pub fn default_text_model(
    text_model: Option<&Path>,
    meta: &SceneMeta,
) -> Option<std::path::PathBuf> {
    text_model
        .map(Path::to_path_buf)
        .or_else(|| meta.source.vlm().map(|v| v.model.clone()))
}

/// [`default_text_model`], refusing (for `flag`'s texts) a run that has none.
pub fn model_for(
    text_model: Option<&Path>,
    meta: &SceneMeta,
    flag: &str,
) -> Result<std::path::PathBuf, OpsError> {
    default_text_model(text_model, meta).ok_or_else(|| {
        OpsError::Invalid(format!(
            "{flag} needs --text-model DIR (the CLIP model whose image features the field \
             was trained on); a run trained with --vlm uses its own"
        ))
    })
}

/// Unit-length embeddings of `texts` by the model in `model_dir`, as
/// class embeddings named by the texts. Cached in `run`; checked against the
/// run's feature dimension.
pub fn embed(
    model_dir: &Path,
    texts: &[String],
    run: &Path,
    meta: &SceneMeta,
    device: &Device,
) -> Result<TextEmbeddings, OpsError> {
    let flag = format!("--text-model {}", model_dir.display());
    let e = clip::embed_texts(model_dir, texts, Some(run), device)
        .map_err(|e| OpsError::Invalid(format!("{flag}: {e}")))?;
    for note in &e.notes {
        eprintln!("note: {note}");
    }
    match meta.feature_dim {
        None => {
            return Err(OpsError::Invalid(format!(
                "{}: the run was trained without feature maps, so it cannot be queried \
                 (train with --features)",
                run.display()
            )));
        }
        Some(d) if d != e.dim => {
            return Err(OpsError::Invalid(format!(
                "{flag}: the text model embeds in {} dimensions but the run's features have {d}; \
                 use the CLIP model whose image features the field was trained on",
                e.dim
            )));
        }
        Some(_) => {}
    }
    if e.cached < texts.len() {
        eprintln!(
            "embedded {} text(s) with {} ({} from the cache)",
            texts.len(),
            model_dir.display(),
            e.cached
        );
    }
    Ok(TextEmbeddings {
        names: texts.to_vec(),
        dim: e.dim,
        data: e.rows.concat(),
    })
}

/// Tells (on stderr) which `--classes` name no class of the point labels:
/// they are embedded but cannot be scored.
pub fn note_unscored(asked: &[String], scored: &[String]) {
    let unscored: Vec<&String> = asked.iter().filter(|n| !scored.contains(n)).collect();
    if !unscored.is_empty() {
        eprintln!(
            "note: {} of --classes name no class of the point labels and are not scored: \
             {unscored:?}",
            unscored.len()
        );
    }
}

/// A file-name-safe label for a query text (at most 48 characters).
pub fn label(text: &str) -> String {
    let s: String = text
        .trim()
        .chars()
        .map(|c| if c.is_alphanumeric() { c } else { '_' })
        .take(48)
        .collect();
    if s.is_empty() { "query".into() } else { s }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes_are_split_trimmed_and_checked() {
        assert_eq!(
            parse_classes(" chair, wooden table ,soft").unwrap(),
            vec!["chair", "wooden table", "soft"]
        );
        let e = parse_classes("a,,b").unwrap_err().to_string();
        assert!(
            e.contains("--classes") && e.contains("class 2 is empty"),
            "{e}"
        );
        assert!(parse_classes("").is_err());
        assert!(
            parse_classes("a, a")
                .unwrap_err()
                .to_string()
                .contains("twice")
        );
        assert_eq!(label("something to sit on!"), "something_to_sit_on_");
        assert_eq!(label("  "), "query");
    }
}
