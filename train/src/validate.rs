//! Checks that run before anything is loaded, trained or written: the
//! command line, the keys of a `--config` file, the held-out split and the
//! output directory. Every refusal names the flag or the file and says how
//! to proceed, so a mistyped option never trains something other than what
//! was asked for and never overwrites a finished run.

use std::path::Path;

use field_ops::run_dir::{RunDir, Split};

use crate::checkpoint::list_checkpoints;
use crate::cli::{Cli, DatasetKind};
use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::settings::args::{AppearanceArg, FieldArg, FieldModelArg, SamplerArg};

/// The largest `--box-margin`: a box 21 times the region the capture sees
/// leaves the field too coarse to resolve it.
const MAX_BOX_MARGIN: f64 = 10.0;

fn flag_error(message: String) -> TrainError {
    TrainError::Config(message)
}

/// The words of `--extractor-command`, split as a POSIX shell splits them
/// (quotes and backslashes keep spaces in a path), so that a program or
/// argument path with spaces survives; unbalanced quotes and an empty
/// command are refused.
pub fn extractor_words(command: &str) -> Result<Vec<String>, TrainError> {
    let words = shlex::split(command).ok_or_else(|| {
        flag_error(format!(
            "--extractor-command {command:?}: unbalanced quotes or a trailing backslash \
             (it is split into words as a shell would)"
        ))
    })?;
    if words.is_empty() {
        return Err(flag_error(
            "--extractor-command is empty: give the program (and its leading arguments)".into(),
        ));
    }
    Ok(words)
}

/// Checks the options of `cli` against each other, before any file is read.
pub fn cli(cli: &Cli) -> Result<(), TrainError> {
    value_flags(cli)?;
    novel_and_grid_flags(cli)?;
    if cli.resume.is_some() {
        return resume_flags(cli);
    }
    new_run_flags(cli)
}

/// `--viewer-host` and `--viewer-every`.
fn viewer_flags(cli: &Cli) -> Result<(), TrainError> {
    if cli.viewer_host.parse::<std::net::IpAddr>().is_err() {
        return Err(flag_error(format!(
            "--viewer-host {:?}: not an IP address (127.0.0.1 for this machine only, 0.0.0.0 \
             for every interface)",
            cli.viewer_host
        )));
    }
    if !(cli.viewer_every.is_finite() && cli.viewer_every > 0.0) {
        return Err(flag_error(format!(
            "--viewer-every {}: must be a positive number of seconds",
            cli.viewer_every
        )));
    }
    Ok(())
}

/// Numbers out of their range, and the device.
fn value_flags(cli: &Cli) -> Result<(), TrainError> {
    for (flag, value) in [
        ("iters", cli.iters),
        ("stop-at", cli.stop_at),
        ("rays", cli.rays),
        ("samples", cli.samples),
        ("width", cli.width),
        ("depth", cli.depth),
    ] {
        if value == Some(0) {
            return Err(flag_error(format!("--{flag} 0: must be at least 1")));
        }
    }
    if cli.viewer {
        viewer_flags(cli)?;
    }
    if let Some(b) = cli.time_budget
        && !(b.is_finite() && b > 0.0)
    {
        return Err(flag_error(format!(
            "--time-budget {b}: must be a positive number of seconds"
        )));
    }
    if let Some(m) = cli.max_depth
        && !(m.is_finite() && m > 0.0)
    {
        return Err(flag_error(format!(
            "--max-depth {m}: must be a positive number of metres"
        )));
    }
    if let Some(m) = cli.box_margin
        && !(m.is_finite() && (0.0..=MAX_BOX_MARGIN).contains(&m))
    {
        return Err(flag_error(format!(
            "--box-margin {m}: must be a fraction from 0 to {MAX_BOX_MARGIN} of the box's \
             largest side"
        )));
    }
    if let Some(lr) = cli.lr
        && !(lr.is_finite() && lr > 0.0)
    {
        return Err(flag_error(format!(
            "--lr {lr}: must be a positive learning rate"
        )));
    }
    for (flag, value) in [
        ("lambda-open", cli.lambda_open),
        ("lambda-depth", cli.lambda_depth),
        ("unseen-depth", cli.unseen_depth),
    ] {
        if let Some(v) = value
            && !(v.is_finite() && v >= 0.0)
        {
            return Err(flag_error(format!(
                "--{flag} {v}: must be a finite, non-negative weight"
            )));
        }
    }
    cli.compute.check().map_err(flag_error)
}

/// The novel-view and occupancy-grid options.
fn novel_and_grid_flags(cli: &Cli) -> Result<(), TrainError> {
    if let Some(w) = cli.novel_depth_weight
        && !(w.is_finite() && (0.0..=1.0).contains(&w))
    {
        return Err(flag_error(format!(
            "--novel-depth-weight {w}: must be a weight in [0, 1] (sensor depth weighs 1)"
        )));
    }
    if let Some(w) = cli.novel_color_weight
        && !(w.is_finite() && (0.0..=1.0).contains(&w))
    {
        return Err(flag_error(format!(
            "--novel-color-weight {w}: must be a weight in [0, 1] (captured colour weighs 1)"
        )));
    }
    if let Some(v) = cli.novel_scale
        && !(v.is_finite() && v > 0.0 && v <= 1.0)
    {
        return Err(flag_error(format!(
            "--novel-scale {v}: must be in (0, 1] (a fraction of the capture resolution)"
        )));
    }
    if let Some(e) = cli.novel_max_color_error
        && (e.is_nan() || e < 0.0)
    {
        return Err(flag_error(format!(
            "--novel-max-color-error {e}: must be a colour difference >= 0 (inf turns the check off)"
        )));
    }
    if let Some(r) = cli.grid_resolution {
        if !(2..=256).contains(&r) {
            return Err(flag_error(format!(
                "--grid-resolution {r}: must be in 2..=256 cells per axis"
            )));
        }
        if !cli.occupancy_grid && cli.resume.is_none() {
            return Err(flag_error(format!(
                "--grid-resolution {r} has no effect without --occupancy-grid"
            )));
        }
    }
    if cli.novel_after == Some(0) {
        return Err(flag_error(
            "--novel-after 0: the field must be trained before it can render views; give an iteration >= 1"
                .into(),
        ));
    }
    if let Some(c) = &cli.extractor_command {
        extractor_words(c)?;
    }
    let novel_given = cli.novel_after.is_some()
        || cli.novel_views_mode.is_some()
        || cli.novel_depth_weight.is_some()
        || cli.novel_max_color_error.is_some()
        || cli.novel_oracle.is_some()
        || cli.novel_normalisation.is_some()
        || cli.novel_color_weight.is_some()
        || cli.novel_keep_fog
        || cli.extractor_command.is_some();
    if novel_given && cli.novel_views.is_none() && cli.resume.is_none() {
        return Err(flag_error(
            "novel-view options are given without --novel-views N (how many views to add)".into(),
        ));
    }
    Ok(())
}

/// The options of a new run: the held-out split and the scene.
fn new_run_flags(cli: &Cli) -> Result<(), TrainError> {
    match cli.holdout_every {
        0 => {
            return Err(flag_error(
                "--holdout-every 0 holds out no frame, so no held-out figures could be \
                 measured; use --holdout-every N with N >= 2 (frames 0, N, 2N, ... are held out)"
                    .into(),
            ));
        }
        1 => {
            return Err(flag_error(
                "--holdout-every 1 holds out every frame and leaves none to train on; \
                 use --holdout-every N with N >= 2"
                    .into(),
            ));
        }
        _ => {}
    }
    if let Some(o) = cli.novel_oracle
        && cli.dataset_kind() != DatasetKind::Synthetic
    {
        return Err(flag_error(format!(
            "--novel-oracle {}: the oracle takes novel views from a synthetic scene's ground truth; a scene on disk has none (leave --novel-oracle out)",
            o.name()
        )));
    }
    if cli.dataset_kind() == DatasetKind::Synthetic {
        if let Some(data) = &cli.data {
            return Err(flag_error(format!(
                "--data {} is given with --dataset synthetic (the built-in scene, which \
                 reads no files); leave --dataset out to detect the format of the directory",
                data.display()
            )));
        }
        for (flag, given) in [
            ("features", cli.features.is_some()),
            ("stride", cli.stride.is_some()),
            ("max-frames", cli.max_frames.is_some()),
            ("resolution", cli.resolution.is_some()),
            ("downscale", cli.downscale.is_some()),
            ("colmap-depth", cli.colmap_depth),
            ("sparse-depth", cli.sparse_depth.is_some()),
            ("min-depth-confidence", cli.min_depth_confidence.is_some()),
            ("max-depth", cli.max_depth.is_some()),
            ("box-margin", cli.box_margin.is_some()),
        ] {
            if given {
                return Err(flag_error(format!(
                    "--{flag} applies to a scene on disk, not to the synthetic scene (which \
                     makes its own images and feature maps); add --data PATH (the format is \
                     detected, or give --dataset), or leave --{flag} out"
                )));
            }
        }
    }
    Ok(())
}

/// With `--resume`, the run's own configuration and scene are used: options
/// that would change them are refused instead of being silently ignored.
fn resume_flags(cli: &Cli) -> Result<(), TrainError> {
    let ignored = [
        ("dataset", cli.dataset.is_some()),
        ("colmap-depth", cli.colmap_depth),
        ("sparse-depth", cli.sparse_depth.is_some()),
        ("min-depth-confidence", cli.min_depth_confidence.is_some()),
        ("max-depth", cli.max_depth.is_some()),
        ("box-margin", cli.box_margin.is_some()),
        ("features", cli.features.is_some()),
        ("vlm", cli.vlm.is_some()),
        ("stride", cli.stride.is_some()),
        ("max-frames", cli.max_frames.is_some()),
        ("resolution", cli.resolution.is_some()),
        ("downscale", cli.downscale.is_some()),
        ("rays", cli.rays.is_some()),
        ("samples", cli.samples.is_some()),
        ("width", cli.width.is_some()),
        ("depth", cli.depth.is_some()),
        ("lambda-open", cli.lambda_open.is_some()),
        ("lambda-depth", cli.lambda_depth.is_some()),
        ("lr", cli.lr.is_some()),
        ("unseen-depth", cli.unseen_depth.is_some()),
        ("pose-refine", cli.pose_refine.is_some()),
        ("hash-grid", cli.hash_grid.is_some()),
        ("field-model", cli.field_model != FieldModelArg::Auto),
        ("field", cli.field != FieldArg::Auto),
        ("sampler", cli.sampler != SamplerArg::Auto),
        ("appearance", cli.appearance != AppearanceArg::Auto),
        ("seed", cli.seed.is_some()),
        ("log-every", cli.log_every.is_some()),
        ("novel-views", cli.novel_views.is_some()),
        ("novel-after", cli.novel_after.is_some()),
        ("novel-views-mode", cli.novel_views_mode.is_some()),
        ("novel-depth-weight", cli.novel_depth_weight.is_some()),
        ("novel-scale", cli.novel_scale.is_some()),
        ("novel-max-color-error", cli.novel_max_color_error.is_some()),
        ("novel-oracle", cli.novel_oracle.is_some()),
        ("novel-normalisation", cli.novel_normalisation.is_some()),
        ("novel-color-weight", cli.novel_color_weight.is_some()),
        ("novel-keep-fog", cli.novel_keep_fog),
        ("extractor-command", cli.extractor_command.is_some()),
        ("occupancy-grid", cli.occupancy_grid),
        ("head-top-k", cli.head_top_k.is_some()),
        ("preset", cli.preset.is_some()),
        ("grid-resolution", cli.grid_resolution.is_some()),
        ("grid-early-samples", cli.grid_early_samples.is_some()),
        ("grid-early-updates", cli.grid_early_updates.is_some()),
        ("grid-dilation", cli.grid_dilation.is_some()),
        ("grid-keep-dropped", cli.grid_keep_dropped.is_some()),
    ];
    if let Some((flag, _)) = ignored.iter().find(|(_, given)| *given) {
        return Err(flag_error(format!(
            "--{flag} cannot be combined with --resume: a resumed run keeps the scene and \
             configuration in its config.json (only --iters, --time-budget and --stop-at apply)"
        )));
    }
    Ok(())
}

/// Every key path of `patch` that `base` does not have (`model.mlp.widht`).
/// Below a `null` in `base` (an unset optional section) nothing is checked:
/// the section's own deserialisation does that.
pub fn unknown_keys(patch: &serde_json::Value, base: &serde_json::Value) -> Vec<String> {
    let mut found = Vec::new();
    walk(patch, base, "", &mut found);
    found
}

fn walk(patch: &serde_json::Value, base: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
    let (serde_json::Value::Object(p), serde_json::Value::Object(b)) = (patch, base) else {
        return;
    };
    for (key, value) in p {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match b.get(key) {
            Some(inner) => walk(value, inner, &path, out),
            None => out.push(path),
        }
    }
}

/// Refuses a `--config` file with keys the configuration does not have (a
/// typo would otherwise leave the default in place without a word).
pub fn config_keys(path: &Path, base: &TrainConfig) -> Result<(), TrainError> {
    let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e))?;
    let patch: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| TrainError::json(path, e))?;
    let base = serde_json::to_value(base).map_err(|e| TrainError::json(path, e))?;
    let unknown = unknown_keys(&patch, &base);
    if unknown.is_empty() {
        return Ok(());
    }
    let known = |v: &serde_json::Value| match v {
        serde_json::Value::Object(m) => m.keys().cloned().collect::<Vec<_>>().join(", "),
        _ => String::new(),
    };
    Err(TrainError::json(
        path,
        format!(
            "unknown key{} {} (top-level keys are: {})",
            if unknown.len() > 1 { "s" } else { "" },
            unknown.join(", "),
            known(&base)
        ),
    ))
}

/// Frames `0, n, 2n, ...` are held out (none when `n` is 0 or there are
/// fewer than two frames); the rest are trained on.
pub fn split_frames(frames: usize, holdout_every: usize) -> Split {
    let mut split = Split::default();
    for i in 0..frames {
        if holdout_every > 0 && frames > 1 && i.is_multiple_of(holdout_every) {
            split.heldout.push(i);
        } else {
            split.train.push(i);
        }
    }
    split
}

/// The train / held-out split of `frames` frames holding out every
/// `holdout_every`-th one; refused when either side would be empty, since
/// the "held-out" figures would then be measured on training frames.
pub fn holdout_split(frames: usize, holdout_every: usize) -> Result<Split, TrainError> {
    let split = split_frames(frames, holdout_every);
    if split.heldout.is_empty() {
        let plural = if frames == 1 { "" } else { "s" };
        return Err(flag_error(format!(
            "--holdout-every {holdout_every}: the scene has {frames} frame{plural} and none of \
             them would be held out (held-out figures would be measured on training frames); \
             a run needs at least 2 frames (keep more with a smaller --stride)"
        )));
    }
    if split.train.is_empty() {
        return Err(flag_error(format!(
            "--holdout-every {holdout_every} holds out all {frames} frames and leaves none to \
             train on; use a larger N"
        )));
    }
    Ok(split)
}

/// Refuses to start a new run in a directory that already holds one (its
/// weights and metrics would be replaced), with or without checkpoints.
pub fn fresh_out_dir(dir: &Path) -> Result<(), TrainError> {
    if dir.exists() && !dir.is_dir() {
        return Err(flag_error(format!(
            "--out {}: exists and is not a directory",
            dir.display()
        )));
    }
    let run = RunDir::new(dir);
    let has_checkpoints = !list_checkpoints(&run.checkpoints())?.is_empty();
    let present: Vec<String> = [run.weights(), run.summary(), run.metrics(), run.config()]
        .iter()
        .filter(|p| p.exists())
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .chain(has_checkpoints.then(|| "checkpoints/".to_string()))
        .collect();
    if present.is_empty() {
        return Ok(());
    }
    let next = if has_checkpoints {
        format!(
            "continue it with --resume {}, or choose another --out",
            dir.display()
        )
    } else {
        "choose another --out".to_string()
    };
    Err(flag_error(format!(
        "--out {} already holds a run ({}); {next} (or delete that directory to start over)",
        dir.display(),
        present.join(", ")
    )))
}

/// With `--resume --iters N`: the schedule cannot end before the iterations
/// the run has already done.
pub fn resume_iterations(requested: usize, done: usize, dir: &Path) -> Result<(), TrainError> {
    if requested < done {
        return Err(flag_error(format!(
            "--iters {requested} is below the {done} iterations {} has already trained; \
             give --iters {done} or more",
            dir.display()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[test]
    fn split_holds_out_every_nth_frame() {
        let s = split_frames(10, 4);
        assert_eq!(s.heldout, vec![0, 4, 8]);
        assert_eq!(s.train, vec![1, 2, 3, 5, 6, 7, 9]);
        assert!(split_frames(10, 0).heldout.is_empty());
        assert_eq!(split_frames(1, 1).train, vec![0]);
    }

    #[test]
    fn unknown_keys_are_reported_with_their_path() {
        let base =
            serde_json::json!({"model": {"mlp": {"width": 1, "depth": 2}}, "seed": 0, "opt": null});
        let patch = serde_json::json!({"model": {"mlp": {"widht": 3, "depth": 4}, "x": 1}, "seed": 2, "opt": {"a": 1}, "sed": 1});
        let mut keys = unknown_keys(&patch, &base);
        keys.sort();
        assert_eq!(keys, ["model.mlp.widht", "model.x", "sed"]);
    }

    #[test]
    fn split_refuses_empty_sides() {
        assert!(holdout_split(1, 8).is_err());
        assert!(holdout_split(5, 1).is_err());
        assert!(holdout_split(5, 0).is_err());
        let s = holdout_split(10, 4).unwrap();
        assert_eq!(s.heldout, vec![0, 4, 8]);
    }

    #[test]
    fn the_extractor_command_is_split_as_a_shell_splits_it() {
        let words =
            extractor_words(r#"python3 '/my models/extract.py' --out "a b" c\ d"#).expect("split");
        assert_eq!(
            words,
            ["python3", "/my models/extract.py", "--out", "a b", "c d"]
        );
        for bad in ["", "  ", "python3 'unclosed", "trailing\\"] {
            let e = extractor_words(bad).unwrap_err().to_string();
            assert!(e.contains("--extractor-command"), "{bad:?}: {e}");
        }
    }

    #[test]
    fn flag_checks() {
        let parse = |args: &[&str]| {
            let mut v = vec!["train"];
            v.extend_from_slice(args);
            cli(&Cli::try_parse_from(v).unwrap())
        };
        assert!(parse(&[]).is_ok());
        for bad in [
            &["--iters", "0"][..],
            &["--time-budget", "0"],
            &["--time-budget", "NaN"],
            &["--time-budget", "-3"],
            &["--holdout-every", "0"],
            &["--data", "/x", "--dataset", "synthetic"],
            &["--features", "/x"],
            &["--colmap-depth"],
            &["--device", "0"],
        ] {
            let err = parse(bad).unwrap_err().to_string();
            assert!(err.contains(bad[0]), "{bad:?}: {err}");
        }
    }
}
