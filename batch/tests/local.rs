//! A batch on this machine through the real binaries: it runs every scene,
//! a SIGTERM stops it with a checkpoint (exit 75) and the same command
//! continues it bit-identically; finished runs are skipped; `eval gather`
//! writes the table and lists failed and unstarted runs.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{TINY, batch, gather, logged_iteration, non_timing_summary, text, write};
use field_ops::batch_dir::{TaskRecord, TaskState};

fn list(dir: &Path) -> std::path::PathBuf {
    write(
        dir,
        "scenes.toml",
        &format!(
            r#"[defaults]
train = {TINY}
eval = [["segment", "--max-views", "2", "--render-scale", "0.25"]]

[[scene]]
name = "long"
synthetic = 0
train = ["--iters", "400"]

[[scene]]
name = "short"
synthetic = 1
train = ["--iters", "30"]
"#
        ),
    )
}

fn record(run: &Path) -> TaskRecord {
    TaskRecord::read(run).unwrap().expect("batch_task.json")
}

#[test]
fn a_signalled_batch_resumes_bit_identically_and_gathers() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = list(dir.path());
    let out = dir.path().join("out");
    let args = [
        "--scenes",
        scenes.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];

    let mut child = Command::new(common::batch_exe())
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while logged_iteration(&out.join("long")) < 50 {
        assert!(start.elapsed() < Duration::from_secs(300), "no progress");
        assert!(child.try_wait().unwrap().is_none(), "batch ended early");
        std::thread::sleep(Duration::from_millis(50));
    }
    let kill = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(75), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("interrupted by a signal at iteration"),
        "{err}"
    );
    let long = out.join("long");
    assert_eq!(record(&long).state, TaskState::Running);
    assert!(!long.join("summary.json").exists());
    assert!(
        !out.join("short").exists(),
        "the batch went on after the signal"
    );

    let o = batch(&args);
    assert!(o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("long: resuming from its checkpoint at iteration"),
        "{err}"
    );
    for run in ["long", "short"] {
        let r = record(&out.join(run));
        assert_eq!(r.state, TaskState::Done, "{run}");
        assert_eq!(r.eval_done, vec![0], "{run}");
        assert!(out.join(run).join("segmentation.json").exists());
    }
    assert_eq!(record(&long).attempts, 2);
    assert_eq!(record(&out.join("short")).attempts, 1);

    // The same list uninterrupted, in another directory.
    let reference = dir.path().join("reference");
    let o = batch(&[
        "--scenes",
        scenes.to_str().unwrap(),
        "--out",
        reference.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    for run in ["long", "short"] {
        assert_eq!(
            non_timing_summary(&out.join(run)),
            non_timing_summary(&reference.join(run)),
            "{run}"
        );
    }

    // Done runs are skipped.
    let o = batch(&args);
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("long: done before, skipped"), "{err}");
    assert_eq!(record(&long).attempts, 2);

    let md = gather(&out);
    assert!(md.contains("2 of 2 runs finished."), "{md}");
    assert!(md.contains("| long | 1/1 |"), "{md}");
    assert!(md.contains("| **mean** | 2/2 |"), "{md}");
    let csv = std::fs::read_to_string(out.join("benchmark_runs.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    assert!(out.join("benchmark.csv").exists());
    assert!(out.join("benchmark.png").exists());
}

#[test]
fn gather_lists_failed_and_unstarted_runs() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = write(
        dir.path(),
        "scenes.toml",
        &format!(
            r#"[defaults]
train = {TINY}

[[scene]]
name = "broken"
synthetic = 0
train = ["--iters", "10"]
eval = [["render", "--cameras", "/no/such/transforms.json"]]

[[scene]]
name = "waiting"
synthetic = 1
"#
        ),
    );
    let out = dir.path().join("out");
    let o = batch(&[
        "--scenes",
        scenes.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--emit",
        "slurm",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = batch(&["--out", out.to_str().unwrap(), "--task", "0"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let r = record(&out.join("broken"));
    assert_eq!(r.state, TaskState::Failed);
    assert!(
        r.error
            .as_deref()
            .unwrap_or_default()
            .contains("/no/such/transforms.json"),
        "{r:?}"
    );

    let md = gather(&out);
    assert!(md.contains("0 of 2 runs finished."), "{md}");
    assert!(
        md.contains("- broken (broken): failed: eval render"),
        "{md}"
    );
    assert!(md.contains("- waiting (waiting): not started"), "{md}");
    // Trained, so its PSNR counts; no run is segmented, so no chart.
    assert!(md.contains("| broken | 1/1 |"), "{md}");
    assert!(!out.join("benchmark.png").exists());
    let csv = std::fs::read_to_string(out.join("benchmark_runs.csv")).unwrap();
    assert!(csv.contains("waiting,waiting,,not started,"), "{csv}");
}
