//! The scene list (`scenes.toml`) and the runs it expands to.
//!
//! ```toml
//! [defaults]                      # applies to every scene (each may override)
//! train = ["--iters", "2000"]     # flags of `train`
//! eval = [["segment"], ["render", "--cameras", "heldout"]]   # `eval` commands
//! seeds = [0, 1, 2]               # one run per seed (`--seed`)
//! [defaults.slurm]
//! cpus = 8
//! mem = "16G"
//! time = "02:00:00"
//! gpus = 0
//!
//! [[scene]]
//! name = "room0"
//! data = "replica/room0"          # any `--data` format, relative to this file
//! train = ["--stride", "10"]      # added after the defaults' flags
//!
//! [[scene]]
//! name = "synthetic-7"
//! synthetic = 7                   # the built-in synthetic room, this seed
//! ```
//!
//! Everything is checked before anything runs or is submitted: unknown
//! keys, missing capture directories, duplicate names, flags `train` or
//! `eval` would refuse.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use clap::Parser;
use field_ops::batch_dir::{BatchManifest, BatchTask};
use serde::Deserialize;

use crate::error::BatchError;
use crate::slurm::SlurmRequest;

/// Settings shared by the scenes.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Defaults {
    train: Option<Vec<String>>,
    eval: Option<Vec<Vec<String>>>,
    seeds: Option<Vec<u64>>,
    #[serde(default)]
    slurm: SlurmRequest,
}

/// One `[[scene]]` entry.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneEntry {
    name: String,
    data: Option<PathBuf>,
    synthetic: Option<u64>,
    train: Option<Vec<String>>,
    eval: Option<Vec<Vec<String>>>,
    seeds: Option<Vec<u64>>,
    #[serde(default)]
    slurm: SlurmRequest,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenesFile {
    #[serde(default)]
    defaults: Defaults,
    #[serde(default)]
    scene: Vec<SceneEntry>,
}

/// A checked scene list: its runs and what each asks of a cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// `batch.json`'s content.
    pub manifest: BatchManifest,
    /// The cluster request of each task, in task order.
    pub requests: Vec<SlurmRequest>,
}

/// `eval` commands a batch may run after training (`view` serves until
/// stopped, `extract` and `gather` do not take a run).
const EVAL_COMMANDS: [&str; 4] = ["segment", "query", "render", "uncertainty"];

/// `train` flags that `batch` sets itself.
const SET_BY_BATCH: [&str; 3] = ["--out", "--resume", "--data"];

/// Reads and checks the scene list at `path`.
pub fn read(path: &Path) -> Result<Batch, BatchError> {
    let text = std::fs::read_to_string(path).map_err(|e| BatchError::scenes(path, e))?;
    let file: ScenesFile = toml::from_str(&text).map_err(|e| BatchError::scenes(path, e))?;
    if file.scene.is_empty() {
        return Err(BatchError::scenes(path, "no [[scene]] entry"));
    }
    let base = path.parent().unwrap_or(Path::new("."));
    let scenes_file = std::path::absolute(path).map_err(|e| BatchError::scenes(path, e))?;
    let mut tasks = Vec::new();
    let mut requests = Vec::new();
    let mut names = BTreeSet::new();
    for entry in &file.scene {
        let err = |m: String| BatchError::scenes(path, format!("scene {:?}: {m}", entry.name));
        check_name(&entry.name).map_err(err)?;
        let capture = capture_flags(entry, base).map_err(err)?;
        let request = entry.slurm.over(&file.defaults.slurm);
        request.check().map_err(err)?;
        let eval = entry
            .eval
            .clone()
            .or_else(|| file.defaults.eval.clone())
            .unwrap_or_default();
        for step in &eval {
            check_eval(step).map_err(err)?;
        }
        let seeds = entry.seeds.clone().or_else(|| file.defaults.seeds.clone());
        if seeds.as_ref().is_some_and(|s| s.is_empty()) {
            return Err(err(
                "`seeds` is empty: give at least one seed, or leave it out".into(),
            ));
        }
        let runs: Vec<(String, Option<u64>)> = match seeds {
            None => vec![(entry.name.clone(), None)],
            Some(s) => s
                .iter()
                .map(|&k| (format!("{}-seed{k}", entry.name), Some(k)))
                .collect(),
        };
        for (run, seed) in runs {
            if !names.insert(run.clone()) {
                return Err(err(format!(
                    "the run name {run:?} is used twice: scene names must be unique"
                )));
            }
            let mut train: Vec<String> = file.defaults.train.clone().unwrap_or_default();
            train.extend(entry.train.clone().unwrap_or_default());
            check_not_set_by_batch(&train).map_err(err)?;
            train.extend(capture.iter().cloned());
            if let Some(k) = seed {
                train.extend(["--seed".to_string(), k.to_string()]);
            }
            check_train(&train).map_err(err)?;
            tasks.push(BatchTask {
                index: tasks.len(),
                run,
                scene: entry.name.clone(),
                seed,
                train,
                eval: eval.clone(),
            });
            requests.push(request.clone());
        }
    }
    Ok(Batch {
        manifest: BatchManifest { scenes_file, tasks },
        requests,
    })
}

/// A name that is one directory name on every file system.
fn check_name(name: &str) -> Result<(), String> {
    let ok = !name.is_empty()
        && name.len() <= 100
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
    if ok {
        Ok(())
    } else {
        Err(
            "a name is 1 to 100 of the characters A-Z a-z 0-9 - _ . (not starting with a dot)"
                .into(),
        )
    }
}

/// `--data DIR` (checked to exist) or `--scene-seed N`.
fn capture_flags(entry: &SceneEntry, base: &Path) -> Result<Vec<String>, String> {
    match (&entry.data, entry.synthetic) {
        (Some(_), Some(_)) => Err("give `data` or `synthetic`, not both".into()),
        (None, None) => Err("give `data` (a capture directory) or `synthetic` (a seed)".into()),
        (None, Some(seed)) => Ok(vec!["--scene-seed".into(), seed.to_string()]),
        (Some(data), None) => {
            let dir = base.join(data);
            if !dir.is_dir() {
                return Err(format!("data {}: no such directory", dir.display()));
            }
            let dir = std::path::absolute(&dir).map_err(|e| e.to_string())?;
            Ok(vec!["--data".into(), dir.to_string_lossy().into_owned()])
        }
    }
}

/// The scene's own flags leave the run directory and capture to `batch`.
fn check_not_set_by_batch(args: &[String]) -> Result<(), String> {
    let set = |a: &String| {
        SET_BY_BATCH
            .iter()
            .find(|f| a == *f || a.starts_with(&format!("{f}=")))
    };
    match args.iter().find_map(set) {
        Some(flag) => Err(format!(
            "train flag {flag} is set by batch (the run directory is <out>/<name>, the capture \
             is the scene's `data`)"
        )),
        None => Ok(()),
    }
}

/// The flags parse as `train`'s, with their values in range.
fn check_train(args: &[String]) -> Result<(), String> {
    let cli = train_cli(args, Path::new("batch-check"))?;
    train::validate::cli(&cli).map_err(|e| format!("train flags: {e}"))
}

/// `train`'s command line for `args` writing into `out`.
pub fn train_cli(args: &[String], out: &Path) -> Result<train::cli::Cli, String> {
    let argv = ["train".to_string()]
        .into_iter()
        .chain(args.iter().cloned())
        .chain(["--out".to_string(), out.to_string_lossy().into_owned()]);
    train::cli::Cli::try_parse_from(argv)
        .map_err(|e| format!("train flags {args:?}: {}", first_line(&e)))
}

/// An `eval` command batch can run, with flags `eval` accepts.
fn check_eval(step: &[String]) -> Result<(), String> {
    match step.first() {
        Some(c) if EVAL_COMMANDS.contains(&c.as_str()) => {}
        other => {
            return Err(format!(
                "eval step {step:?}: the command must be one of {EVAL_COMMANDS:?}, not {other:?}"
            ));
        }
    }
    if step.iter().any(|a| a == "--run") {
        return Err(format!("eval step {step:?}: --run is set by batch"));
    }
    eval_cli(step, Path::new("batch-check")).map(|_| ())
}

/// `eval`'s command line for `step` on run `run`.
pub fn eval_cli(step: &[String], run: &Path) -> Result<eval::cli::Cli, String> {
    let argv = ["eval".to_string()]
        .into_iter()
        .chain(step.iter().cloned())
        .chain(["--run".to_string(), run.to_string_lossy().into_owned()]);
    eval::cli::Cli::try_parse_from(argv)
        .map_err(|e| format!("eval step {step:?}: {}", first_line(&e)))
}

/// The first line of a clap error (the rest is usage help).
fn first_line(e: &clap::Error) -> String {
    let text = e.to_string();
    text.lines()
        .next()
        .unwrap_or_default()
        .trim_start_matches("error: ")
        .to_string()
}
