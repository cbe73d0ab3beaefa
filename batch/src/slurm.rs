//! The batch as Slurm job arrays: one array task per run, one array per
//! distinct resource request (tasks listed by index, `--array=0,2,5`).
//!
//! Each task runs `batch --out DIR --task I` under a script that survives
//! preemption: Slurm signals the task (SIGTERM: preemption, `scontrol
//! requeue`, or `--signal` before the time limit), `train` writes a
//! checkpoint and exits with 75, and the script requeues the task, which
//! resumes from that checkpoint when it runs again. Output is appended to
//! `DIR/<run>/batch.log` (Slurm's own messages to `DIR/slurm/`).

use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::Deserialize;
use train::interrupt::EXIT_INTERRUPTED;

use crate::error::BatchError;

/// What one task asks of the cluster; an unset field takes the defaults'
/// value, then Slurm's own default.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlurmRequest {
    /// `--cpus-per-task`.
    pub cpus: Option<u32>,
    /// `--mem`: a size with an optional K, M, G or T suffix.
    pub mem: Option<String>,
    /// `--time`: minutes, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS.
    pub time: Option<String>,
    /// GPUs (`--gres=gpu:N`).
    pub gpus: Option<u32>,
    /// `--partition`.
    pub partition: Option<String>,
    /// Further `#SBATCH` options, each as `--option=value`.
    pub extra: Option<Vec<String>>,
}

impl SlurmRequest {
    /// This request with `defaults` filling its unset fields.
    pub fn over(&self, defaults: &Self) -> Self {
        Self {
            cpus: self.cpus.or(defaults.cpus),
            mem: self.mem.clone().or_else(|| defaults.mem.clone()),
            time: self.time.clone().or_else(|| defaults.time.clone()),
            gpus: self.gpus.or(defaults.gpus),
            partition: self
                .partition
                .clone()
                .or_else(|| defaults.partition.clone()),
            extra: self.extra.clone().or_else(|| defaults.extra.clone()),
        }
    }

    /// Values Slurm would refuse, refused here before anything is written.
    pub fn check(&self) -> Result<(), String> {
        if self.cpus == Some(0) {
            return Err("slurm.cpus must be at least 1".into());
        }
        if let Some(m) = &self.mem {
            let digits = m.trim_end_matches(['K', 'M', 'G', 'T']);
            if digits.is_empty() || !digits.chars().all(|c| c.is_ascii_digit()) {
                return Err(format!(
                    "slurm.mem {m:?}: expected a size such as 4000, 16G or 512M"
                ));
            }
        }
        if let Some(t) = &self.time
            && !valid_time(t)
        {
            return Err(format!(
                "slurm.time {t:?}: expected minutes, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS"
            ));
        }
        if let Some(p) = &self.partition
            && (p.is_empty() || p.contains(char::is_whitespace))
        {
            return Err(format!("slurm.partition {p:?}: not a partition name"));
        }
        for e in self.extra.iter().flatten() {
            if !e.starts_with("--") || e.contains('\n') {
                return Err(format!(
                    "slurm.extra {e:?}: each entry is one sbatch option, as --option=value"
                ));
            }
        }
        Ok(())
    }

    /// The `#SBATCH` lines of the request.
    fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(c) = self.cpus {
            out.push(format!("--cpus-per-task={c}"));
        }
        if let Some(m) = &self.mem {
            out.push(format!("--mem={m}"));
        }
        if let Some(t) = &self.time {
            out.push(format!("--time={t}"));
        }
        if let Some(g) = self.gpus.filter(|&g| g > 0) {
            out.push(format!("--gres=gpu:{g}"));
        }
        if let Some(p) = &self.partition {
            out.push(format!("--partition={p}"));
        }
        out.extend(self.extra.iter().flatten().cloned());
        out
    }
}

/// Slurm's time formats.
fn valid_time(t: &str) -> bool {
    let number = |s: &str| !s.is_empty() && s.len() <= 4 && s.chars().all(|c| c.is_ascii_digit());
    let (days, rest) = match t.split_once('-') {
        Some((d, r)) => (Some(d), r),
        None => (None, t),
    };
    if days.is_some_and(|d| !number(d)) {
        return false;
    }
    let parts: Vec<&str> = rest.split(':').collect();
    parts.len() <= 3 && parts.iter().all(|p| number(p))
}

/// Seconds of warning before the time limit: the task checkpoints and
/// requeues itself in them.
pub const SIGNAL_BEFORE_LIMIT_S: u32 = 120;

/// One array: its request and the task indices that share it.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrayScript {
    /// Where the script is written.
    pub path: PathBuf,
    /// The task indices.
    pub tasks: Vec<usize>,
    /// The script's text.
    pub text: String,
}

/// The scripts for the batch in `dir` (absolute), running `exe`.
pub fn scripts(
    dir: &Path,
    exe: &Path,
    runs: &[String],
    requests: &[SlurmRequest],
    max_parallel: Option<usize>,
) -> Vec<ArrayScript> {
    let mut groups: Vec<(SlurmRequest, Vec<usize>)> = Vec::new();
    for (i, r) in requests.iter().enumerate() {
        match groups.iter_mut().find(|g| g.0 == *r) {
            Some(g) => g.1.push(i),
            None => groups.push((r.clone(), vec![i])),
        }
    }
    let single = groups.len() == 1;
    groups
        .into_iter()
        .enumerate()
        .map(|(k, (request, tasks))| {
            let name = if single {
                "batch.sbatch".to_string()
            } else {
                format!("batch-{k}.sbatch")
            };
            let path = dir.join(name);
            let text = script(&path, dir, exe, runs, &request, &tasks, max_parallel);
            ArrayScript { path, tasks, text }
        })
        .collect()
}

/// Single-quotes `s` for bash.
fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

fn script(
    path: &Path,
    dir: &Path,
    exe: &Path,
    runs: &[String],
    request: &SlurmRequest,
    tasks: &[usize],
    max_parallel: Option<usize>,
) -> String {
    let dir_s = dir.to_string_lossy();
    let list: Vec<String> = tasks.iter().map(|t| t.to_string()).collect();
    let mut array = list.join(",");
    if let Some(k) = max_parallel {
        let _ = write!(array, "%{k}");
    }
    let mut s = String::from("#!/bin/bash\n");
    let _ = writeln!(
        s,
        "# Written by `batch --emit slurm`: one array task per run of {dir_s}/batch.json.\n\
         # Submit with `sbatch {}`; gather with `eval gather {dir_s}`.",
        path.to_string_lossy()
    );
    let mut options = vec![
        format!(
            "--job-name=opennerf-{}",
            dir.file_name()
                .map_or("batch".into(), |n| n.to_string_lossy())
        ),
        format!("--array={array}"),
    ];
    options.extend(request.lines());
    options.extend([
        "--requeue".to_string(),
        "--open-mode=append".to_string(),
        format!("--signal=B:TERM@{SIGNAL_BEFORE_LIMIT_S}"),
        format!("--output={dir_s}/slurm/%A_%a.out"),
    ]);
    for o in options {
        let _ = writeln!(s, "#SBATCH {o}");
    }
    let names: Vec<String> = runs.iter().map(|r| quote(r)).collect();
    let _ = write!(
        s,
        r#"
set -u
runs=({names})
run={dir}/"${{runs[$SLURM_ARRAY_TASK_ID]}}"
mkdir -p "$run"
log="$run/batch.log"
echo "== task $SLURM_ARRAY_TASK_ID, job ${{SLURM_ARRAY_JOB_ID}}_${{SLURM_ARRAY_TASK_ID}}, start $(( ${{SLURM_RESTART_COUNT:-0}} + 1 )), on $(hostname), $(date -Is)" >> "$log"
# Run in the background so that the TERM Slurm sends this script before the
# time limit reaches the task at once (a foreground child would delay it).
{exe} --out {dir} --task "$SLURM_ARRAY_TASK_ID" >> "$log" 2>&1 &
child=$!
trap 'kill -TERM "$child" 2>/dev/null' TERM
wait "$child"
status=$?
# A trapped signal ends `wait` early: wait for the checkpoint to be written.
while [ "$status" -gt 128 ] && kill -0 "$child" 2>/dev/null; do
  wait "$child"
  status=$?
done
# A child that ended between the signal and the check above has an exit
# status the interrupted `wait` did not return: the shell keeps it.
if [ "$status" -gt 128 ]; then
  wait "$child"
  status=$?
fi
if [ "$status" -eq {code} ]; then
  echo "== checkpoint written; requeueing ${{SLURM_ARRAY_JOB_ID}}_${{SLURM_ARRAY_TASK_ID}}" >> "$log"
  # Preemption and `scontrol requeue` requeue the task themselves; the time
  # limit does not.
  scontrol requeue "${{SLURM_ARRAY_JOB_ID}}_${{SLURM_ARRAY_TASK_ID}}" >> "$log" 2>&1 || true
fi
echo "== exit $status, $(date -Is)" >> "$log"
exit "$status"
"#,
        names = names.join(" "),
        dir = quote(&dir_s),
        exe = quote(&exe.to_string_lossy()),
        code = EXIT_INTERRUPTED,
    );
    s
}

/// `sbatch` on PATH, or an error saying nothing was submitted.
pub fn find_sbatch() -> Result<PathBuf, BatchError> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .map(|d| d.join("sbatch"))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            BatchError::Slurm(
                "--submit: sbatch is not on PATH (Slurm's client commands are needed to submit); \
                 nothing was submitted"
                    .into(),
            )
        })
}

/// Submits `script` with `sbatch --parsable`; returns the job id.
pub fn submit(sbatch: &Path, script: &Path) -> Result<String, BatchError> {
    let out = Command::new(sbatch)
        .arg("--parsable")
        .arg(script)
        .output()
        .map_err(|e| BatchError::Slurm(format!("running {}: {e}", sbatch.display())))?;
    if !out.status.success() {
        return Err(BatchError::Slurm(format!(
            "sbatch {} failed ({}): {}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    // `--parsable` prints `jobid` or `jobid;cluster`.
    let id = text
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        return Err(BatchError::Slurm(format!(
            "sbatch {}: unexpected answer {text:?}",
            script.display()
        )));
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_in_slurm_formats_are_accepted_and_others_refused() {
        for t in ["30", "30:00", "02:00:00", "1-0", "1-02:00", "1-02:00:00"] {
            assert!(valid_time(t), "{t}");
        }
        for t in ["", "1h", "1:2:3:4", "-1", "1-", "a-02", "02::00"] {
            assert!(!valid_time(t), "{t}");
        }
    }

    #[test]
    fn requests_group_tasks_into_arrays() {
        let big = SlurmRequest {
            cpus: Some(8),
            ..Default::default()
        };
        let small = SlurmRequest::default();
        let runs: Vec<String> = (0..4).map(|i| format!("r{i}")).collect();
        let s = scripts(
            Path::new("/b"),
            Path::new("/bin/batch"),
            &runs,
            &[small.clone(), big.clone(), small, big],
            Some(2),
        );
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].tasks, vec![0, 2]);
        assert!(s[0].text.contains("#SBATCH --array=0,2%2\n"));
        assert!(s[1].text.contains("#SBATCH --array=1,3%2\n"));
        assert!(s[1].text.contains("#SBATCH --cpus-per-task=8\n"));
        assert!(!s[0].text.contains("cpus-per-task"));
        assert_eq!(s[1].path, Path::new("/b/batch-1.sbatch"));
    }

    #[test]
    fn quoting_survives_quotes_and_spaces() {
        assert_eq!(quote("a b"), "'a b'");
        assert_eq!(quote("it's"), r"'it'\''s'");
    }
}
