//! What the `train` binary tells the user around a run: the warning when a
//! run cannot be segmented or queried, and the exact commands to run next.

use std::path::Path;

use datasets::{LoaderOptions, SceneMeta, SceneSource};
use field_ops::run_dir::RunDir;

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
/// held-out renders next to their ground truth in any case, and the web
/// viewer of a run whose scene file is there.
pub fn next_commands(dir: &Path) -> Vec<String> {
    let run = shell_word(dir);
    let eval = "cargo run -p eval --release --";
    let meta: Option<SceneMeta> = std::fs::read_to_string(RunDir::new(dir).scene())
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok());
    let features = meta.as_ref().is_some_and(|m| m.feature_dim.is_some());
    let synthetic = meta
        .as_ref()
        .is_some_and(|m| matches!(m.source.base(), SceneSource::Synthetic { .. }));
    // A --vlm run embeds free text with its own model.
    let vlm = meta.as_ref().is_some_and(|m| m.source.vlm().is_some());
    let mut out = Vec::new();
    if features && synthetic {
        out.push(format!("{eval} segment --run {run}"));
        out.push(format!("{eval} query --run {run} --query sofa"));
    } else if features && vlm {
        out.push(format!(
            "{eval} query --run {run} --text \"something to sit on\""
        ));
        let points = match meta.as_ref().map(|m| m.source.base()) {
            Some(SceneSource::Disk { loader, .. }) if has_own_points(loader) => "",
            _ => " --points CLOUD.ply",
        };
        out.push(format!(
            "{eval} segment --run {run}{points} --classes \"wall, floor, chair, table\""
        ));
    } else if features {
        out.push(format!(
            "{eval} query --run {run} --query NAME --embeddings EMBEDDINGS.npy --names NAMES.txt"
        ));
        // COLMAP's sparse points and a phone scan's mesh are the scene's
        // cloud; others need one.
        let points = match meta.as_ref().map(|m| &m.source) {
            Some(SceneSource::Disk { loader, .. }) if has_own_points(loader) => "",
            _ => " --points CLOUD.ply",
        };
        out.push(format!(
            "{eval} segment --run {run}{points} --embeddings EMBEDDINGS.npy --names NAMES.txt"
        ));
    }
    out.push(format!("{eval} render --run {run}"));
    if meta.is_some() {
        out.push(format!("{eval} view --run {run}"));
    }
    out
}

/// Whether scenes of `loader`'s format carry their own point cloud.
fn has_own_points(loader: &LoaderOptions) -> bool {
    matches!(
        loader,
        LoaderOptions::Colmap(_)
            | LoaderOptions::ScannerApp(_)
            | LoaderOptions::Record3d(_)
            | LoaderOptions::Polycam(_)
    )
}

/// The run's result files that exist in `dir`, in the order a reader wants
/// them (the novel views with their count).
pub fn result_files(dir: &Path) -> Vec<String> {
    let run = RunDir::new(dir);
    let mut out: Vec<String> = [
        (run.summary(), "summary.json"),
        (run.metrics(), "metrics.jsonl"),
        (dir.join("training_curve.png"), "training_curve.png"),
        (run.renders(), "renders/"),
        (
            run.renders().join(crate::view_eval::CONTACT_SHEET),
            "renders/heldout.png",
        ),
        (run.weights(), "model.bpk"),
        (run.occupancy(), "occupancy.bin"),
    ]
    .into_iter()
    .filter(|(p, _)| p.exists())
    .map(|(_, name)| name.to_string())
    .collect();
    if let Ok(Some(record)) = datasets::novel_record::read_record(&run.novel()) {
        out.push(format!(
            "novel/ ({} {} views added at iteration {})",
            record.views.len(),
            record.mode,
            record.added_at
        ));
    }
    out
}

/// The command that continues the run in `dir` when it stopped before the
/// end of its schedule (`--stop-at`, a time budget), else `None`.
pub fn resume_command(dir: &Path, iterations: usize) -> Option<String> {
    let text = std::fs::read_to_string(RunDir::new(dir).config()).ok()?;
    let config: serde_json::Value = serde_json::from_str(&text).ok()?;
    let planned = config["schedule"]["iterations"].as_u64()? as usize;
    (iterations < planned).then(|| {
        format!(
            "cargo run -p train --release -- --resume {}   # iteration {iterations} of {planned}",
            shell_word(dir)
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_files_listed_are_those_written_and_a_short_run_gets_a_resume_command() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        assert!(result_files(d).is_empty());
        std::fs::write(d.join("summary.json"), "{}").unwrap();
        std::fs::write(d.join("model.bpk"), "").unwrap();
        assert_eq!(result_files(d), ["summary.json", "model.bpk"]);
        assert_eq!(resume_command(d, 5), None, "no config.json");
        std::fs::write(d.join("config.json"), r#"{"schedule":{"iterations":100}}"#).unwrap();
        assert_eq!(resume_command(d, 100), None);
        let cmd = resume_command(d, 40).unwrap();
        assert!(
            cmd.contains(&format!("--resume {}", shell_word(d))),
            "{cmd}"
        );
        assert!(cmd.contains("iteration 40 of 100"), "{cmd}");
    }

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
    fn a_vlm_capture_is_queried_with_free_text() {
        let dir = tempfile::tempdir().unwrap();
        let base = SceneSource::Disk {
            loader: LoaderOptions::Llff(Default::default()),
            path: "/fern".into(),
        };
        let mut meta = SceneMeta {
            source: SceneSource::WithFeatures {
                base: Box::new(base.clone()),
                features: "/maps".into(),
                pca: datasets::features::PcaSetting::Auto,
                vlm: Some(datasets::VlmSource {
                    model: "/clip".into(),
                    dense: clip::DenseVariant::Naclip,
                    short_side: 336,
                }),
            },
            scene_box: model::geometry::SceneBox {
                min: [0.0; 3],
                max: [1.0; 3],
            },
            background: None,
            pca: None,
            feature_dim: Some(512),
            world: None,
        };
        let write = |m: &SceneMeta| {
            std::fs::write(
                dir.path().join("scene.json"),
                serde_json::to_string(m).unwrap(),
            )
            .unwrap();
        };
        write(&meta);
        let cmds = next_commands(dir.path()).join("\n");
        assert!(
            cmds.contains("query --run") && cmds.contains("--text"),
            "{cmds}"
        );
        assert!(
            cmds.contains("--classes") && cmds.contains("--points CLOUD.ply"),
            "{cmds}"
        );
        assert!(!cmds.contains("--embeddings"), "{cmds}");
        // Without the model: embeddings must be given.
        meta.source = base;
        write(&meta);
        let cmds = next_commands(dir.path()).join("\n");
        assert!(
            cmds.contains("--embeddings") && !cmds.contains("--text"),
            "{cmds}"
        );
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
