//! The batch on a real one-node Slurm cluster (Debian's slurm-wlm and munge,
//! started on this machine by `scripts/slurm-local.sh`): an array of three
//! tiny scenes runs to completion, one task is requeued mid-training with
//! `scontrol requeue`, comes back, resumes from its checkpoint and ends
//! with the summary of an uninterrupted run; `eval gather` gives the table.
//!
//! Ignored in a plain `cargo test` (it needs the packages and takes a few
//! minutes, about three of them Slurm's hold on a requeued job); `.ci/run` installs
//! the packages and runs it.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use common::{TINY, batch_exe, gather, logged_iteration, non_timing_summary, text, write};
use field_ops::batch_dir::{TaskRecord, TaskState};

/// The cluster, stopped when dropped.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/slurm-local.sh")
}

impl Cluster {
    fn start(dir: &Path) -> Self {
        let o = Command::new("bash")
            .arg(script())
            .args(["start", dir.to_str().unwrap(), "2"])
            .output()
            .expect("running scripts/slurm-local.sh");
        assert!(
            o.status.success(),
            "the local Slurm cluster did not start (apt-get install slurm-wlm munge):\n{}",
            text(&o)
        );
        Self {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
        }
    }

    /// A Slurm client command.
    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// The task ids of `job` still queued or running.
    fn queued(&self, job: &str) -> Vec<String> {
        let o = self
            .command("squeue")
            .args(["-h", "-r", "-j", job, "-o", "%i %T %r"])
            .output()
            .unwrap();
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .map(str::to_string)
            .collect()
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(script())
            .args(["stop", self.dir.to_str().unwrap()])
            .status();
    }
}

fn wait_for(what: &str, limit: Duration, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < limit, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
#[ignore = "needs Slurm (slurm-wlm, munge); .ci/run installs it and runs this"]
fn a_requeued_array_task_resumes_and_the_batch_gathers() {
    let tmp = tempfile::tempdir().unwrap();
    let cluster = Cluster::start(&tmp.path().join("cluster"));
    let body = format!(
        r#"[defaults]
train = {TINY}
eval = [["segment", "--max-views", "2", "--render-scale", "0.25"]]
[defaults.slurm]
cpus = 1
mem = "1G"
time = "00:30:00"

[[scene]]
name = "requeued"
synthetic = 0
train = ["--iters", "900"]

[[scene]]
name = "room"
synthetic = 1
train = ["--iters", "150"]
seeds = [0, 1]
"#
    );
    let scenes = write(tmp.path(), "scenes.toml", &body);
    let out = tmp.path().join("out");
    let o = cluster
        .command(batch_exe().to_str().unwrap())
        .args([
            "--scenes",
            scenes.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--submit",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let job = stdout
        .lines()
        .find_map(|l| l.strip_prefix("submitted job "))
        .and_then(|l| l.split_whitespace().next())
        .expect("a job id")
        .to_string();

    let requeued = out.join("requeued");
    wait_for(
        "iteration 100 of the first task",
        Duration::from_secs(300),
        || logged_iteration(&requeued) >= 100,
    );
    assert!(
        !requeued.join("summary.json").exists(),
        "trained before the requeue"
    );
    let o = cluster
        .command("scontrol")
        .args(["requeue", &format!("{job}_0")])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    // Slurm holds a requeued job for about two minutes before it runs again.
    wait_for("every task to finish", Duration::from_secs(900), || {
        cluster.queued(&job).is_empty()
    });

    let log = std::fs::read_to_string(requeued.join("batch.log")).unwrap();
    println!("== requeued/batch.log (training lines left out)");
    for line in log.lines().filter(|l| !l.starts_with("iteration ")) {
        println!("{line}");
    }
    assert!(
        log.contains("interrupted by a signal at iteration"),
        "{log}"
    );
    assert!(log.contains("== checkpoint written; requeueing"), "{log}");
    assert!(
        log.contains("requeued: resuming from its checkpoint at iteration"),
        "{log}"
    );
    assert!(log.contains(", start 2, "), "{log}");
    for run in ["requeued", "room-seed0", "room-seed1"] {
        let r = TaskRecord::read(&out.join(run)).unwrap().expect(run);
        assert_eq!(r.state, TaskState::Done, "{run}: {r:?}");
        assert_eq!(r.attempts, if run == "requeued" { 2 } else { 1 }, "{run}");
    }

    // The requeued run ends as an uninterrupted one does.
    let reference = tmp.path().join("reference");
    // The same list written to another directory, its task 0 run here.
    let o = Command::new(batch_exe())
        .args([
            "--scenes",
            scenes.to_str().unwrap(),
            "--out",
            reference.to_str().unwrap(),
            "--emit",
            "slurm",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let o = Command::new(batch_exe())
        .args(["--out", reference.to_str().unwrap(), "--task", "0"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        non_timing_summary(&requeued),
        non_timing_summary(&reference.join("requeued"))
    );

    let md = gather(&out);
    println!("== eval gather\n{md}");
    assert!(md.contains("3 of 3 runs finished."), "{md}");
    assert!(md.contains("| room | 2/2 |"), "{md}");
    assert!(md.contains("| requeued | 1/1 |"), "{md}");
    assert!(out.join("benchmark.png").exists());
}
