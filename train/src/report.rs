//! What the `train` binary tells the user around a run: the warning when a
//! run cannot be segmented or queried, and the exact commands to run next.

use std::path::Path;

use datasets::{SceneMeta, SceneSource};
use eval::run::RunDir;

/// Printed when the scene has no feature maps.
pub const NO_FEATURES_WARNING: &str = "warning: training without --features: the field learns \
colour and depth only, so `eval segment` and `eval query` will not work on this run \
(`eval render` will)";

/// `path` as one shell word (quoted when it holds anything but plain
/// characters), so a printed command can be pasted as it is.
pub fn shell_word(path: &Path) -> String {
    let s = path.display().to_string();
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+:=@,".contains(c));
    if plain {
        s
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// The commands to run next on the run in `dir`, from the repository root:
/// segmentation when the scene carries labelled points and classes (the
/// synthetic scene), a relevancy query when it only has features, and the
/// held-out renders next to their ground truth in any case.
pub fn next_commands(dir: &Path) -> Vec<String> {
    let run = shell_word(dir);
    let eval = "cargo run -p eval --release --";
    let meta: Option<SceneMeta> = std::fs::read_to_string(RunDir::new(dir).scene())
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok());
    let features = meta.as_ref().is_some_and(|m| m.feature_dim.is_some());
    let synthetic = meta
        .as_ref()
        .is_some_and(|m| matches!(m.source, SceneSource::Synthetic { .. }));
    let mut out = Vec::new();
    if features && synthetic {
        out.push(format!("{eval} segment --run {run}"));
        out.push(format!("{eval} query --run {run} --query sofa"));
    } else if features {
        out.push(format!(
            "{eval} query --run {run} --query NAME --embeddings EMBEDDINGS.npy --names NAMES.txt"
        ));
        out.push(format!(
            "{eval} segment --run {run} --points CLOUD.ply --embeddings EMBEDDINGS.npy --names NAMES.txt"
        ));
    }
    out.push(format!("{eval} render --run {run}"));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_quoted_only_when_needed() {
        assert_eq!(
            shell_word(Path::new("runs/synthetic-17")),
            "runs/synthetic-17"
        );
        assert_eq!(shell_word(Path::new("my runs/a")), "'my runs/a'");
        assert_eq!(shell_word(Path::new("it's")), r"'it'\''s'");
    }

    #[test]
    fn without_a_run_directory_only_render_is_suggested() {
        let cmds = next_commands(Path::new("/nonexistent/run"));
        assert_eq!(
            cmds,
            ["cargo run -p eval --release -- render --run /nonexistent/run"]
        );
    }
}
