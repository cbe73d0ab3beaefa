//! Bad scene lists and flags through the real `batch` binary: each is
//! refused with a message naming the file and the problem, and nothing is
//! written or submitted.

mod common;

use common::{TINY, batch, text, write};

/// Runs `batch --scenes <list> --out <dir>/out` (plus `extra`) on a list
/// with `body`; returns stderr after checking the failure and that
/// nothing was written.
fn refused(body: &str, extra: &[&str]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let scenes = write(dir.path(), "scenes.toml", body);
    let out = dir.path().join("out");
    let mut args = vec![
        "--scenes",
        scenes.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = batch(&args);
    assert!(!o.status.success(), "accepted:\n{}", text(&o));
    assert!(!out.exists(), "wrote {} although refused", out.display());
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        err.contains("scenes.toml") || extra.contains(&"--submit"),
        "{err}"
    );
    err
}

fn scene(extra: &str) -> String {
    format!("[defaults]\ntrain = {TINY}\n\n[[scene]]\nname = \"a\"\nsynthetic = 0\n{extra}")
}

#[test]
fn a_missing_capture_directory_is_named() {
    let err = refused(
        "[[scene]]\nname = \"room0\"\ndata = \"no/such/capture\"\n",
        &[],
    );
    assert!(err.contains("scene \"room0\""), "{err}");
    assert!(err.contains("no/such/capture: no such directory"), "{err}");
}

#[test]
fn a_duplicate_name_is_refused() {
    let body = format!("{}\n[[scene]]\nname = \"a\"\nsynthetic = 1\n", scene(""));
    let err = refused(&body, &[]);
    assert!(err.contains("\"a\" is used twice"), "{err}");
    // A seed's run name clashing with another scene is a duplicate too.
    let body = format!(
        "{}seeds = [1]\n\n[[scene]]\nname = \"a-seed1\"\nsynthetic = 1\n",
        scene("")
    );
    let err = refused(&body, &[]);
    assert!(err.contains("\"a-seed1\" is used twice"), "{err}");
}

#[test]
fn an_unknown_flag_inside_an_entry_is_refused() {
    let err = refused(&scene("train = [\"--iterations\", \"5\"]\n"), &[]);
    assert!(err.contains("scene \"a\""), "{err}");
    assert!(err.contains("--iterations"), "{err}");
    // A value train would refuse, caught before anything runs.
    let err = refused(&scene("train = [\"--time-budget\", \"-3\"]\n"), &[]);
    assert!(err.contains("--time-budget -3"), "{err}");
    // Flags batch sets itself.
    let err = refused(&scene("train = [\"--out\", \"x\"]\n"), &[]);
    assert!(err.contains("--out is set by batch"), "{err}");
    let err = refused(&scene("train = [\"--resume=x\"]\n"), &[]);
    assert!(err.contains("--resume is set by batch"), "{err}");
}

#[test]
fn bad_eval_steps_are_refused() {
    let err = refused(&scene("eval = [[\"view\"]]\n"), &[]);
    assert!(err.contains("must be one of"), "{err}");
    let err = refused(&scene("eval = [[\"segment\", \"--no-such-flag\"]]\n"), &[]);
    assert!(err.contains("--no-such-flag"), "{err}");
    let err = refused(&scene("eval = [[\"render\", \"--run\", \"x\"]]\n"), &[]);
    assert!(err.contains("--run is set by batch"), "{err}");
}

#[test]
fn malformed_lists_are_refused() {
    let err = refused("[[scene]]\nname = \"a\"\nsynthetic = 0\ncolour = 1\n", &[]);
    assert!(err.contains("colour"), "{err}");
    let err = refused("[defaults]\ntrain = []\n", &[]);
    assert!(err.contains("no [[scene]] entry"), "{err}");
    let err = refused("[[scene]]\nname = \"a b\"\nsynthetic = 0\n", &[]);
    assert!(err.contains("a name is 1 to 100"), "{err}");
    let err = refused("[[scene]]\nname = \"a\"\n", &[]);
    assert!(err.contains("give `data`"), "{err}");
    let err = refused(&scene("seeds = []\n"), &[]);
    assert!(err.contains("`seeds` is empty"), "{err}");
    let err = refused(&scene("[scene.slurm]\ntime = \"2 hours\"\n"), &[]);
    assert!(err.contains("slurm.time \"2 hours\""), "{err}");
    let err = refused(&scene("[scene.slurm]\nmem = \"lots\"\n"), &[]);
    assert!(err.contains("slurm.mem \"lots\""), "{err}");
    let err = refused("this is not toml", &[]);
    assert!(err.contains("scenes.toml"), "{err}");
}

#[test]
fn submit_without_sbatch_submits_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = write(dir.path(), "scenes.toml", &scene(""));
    let out = dir.path().join("out");
    let empty = dir.path().join("empty-path");
    std::fs::create_dir(&empty).unwrap();
    let o = std::process::Command::new(common::batch_exe())
        .args([
            "--scenes",
            scenes.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--submit",
        ])
        .env("PATH", &empty)
        .output()
        .unwrap();
    assert!(!o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("sbatch is not on PATH"), "{err}");
    assert!(err.contains("nothing was submitted"), "{err}");
    assert!(!out.exists());
}

#[test]
fn emit_writes_one_array_per_request_and_keeps_its_list() {
    let dir = tempfile::tempdir().unwrap();
    let body = format!(
        "{}seeds = [0, 1]\n\n[[scene]]\nname = \"big\"\nsynthetic = 3\n[scene.slurm]\ncpus = 4\ngpus = 1\n",
        scene("")
    );
    let scenes = write(dir.path(), "scenes.toml", &body);
    let out = dir.path().join("out");
    let args = [
        "--scenes",
        scenes.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--emit",
        "slurm",
    ];
    let o = batch(&args);
    assert!(o.status.success(), "{}", text(&o));
    let small = std::fs::read_to_string(out.join("batch-0.sbatch")).unwrap();
    let big = std::fs::read_to_string(out.join("batch-1.sbatch")).unwrap();
    assert!(small.contains("#SBATCH --array=0,1\n"), "{small}");
    assert!(big.contains("#SBATCH --array=2\n"), "{big}");
    assert!(
        big.contains("#SBATCH --cpus-per-task=4\n#SBATCH --gres=gpu:1\n"),
        "{big}"
    );
    for s in [&small, &big] {
        assert!(s.contains("#SBATCH --requeue\n"));
        assert!(s.contains("runs=('a-seed0' 'a-seed1' 'big')"), "{s}");
    }
    let manifest = field_ops::batch_dir::BatchManifest::read(&out).unwrap();
    let runs: Vec<&str> = manifest.tasks.iter().map(|t| t.run.as_str()).collect();
    assert_eq!(runs, ["a-seed0", "a-seed1", "big"]);
    assert_eq!(manifest.tasks[1].seed, Some(1));
    assert!(
        manifest.tasks[1]
            .train
            .ends_with(&["--seed".to_string(), "1".to_string()])
    );
    // The same list again is fine; another list for the same directory is
    // refused (its array tasks would run other scenes).
    assert!(batch(&args).status.success());
    let other = write(
        dir.path(),
        "scenes.toml",
        &scene("synthetic = 9\n").replace("synthetic = 0\n", ""),
    );
    let o = batch(&[
        "--scenes",
        other.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--emit",
        "slurm",
    ]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("holds a batch written from"));
    // A task index past the list.
    let o = batch(&["--out", out.to_str().unwrap(), "--task", "3"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no task 3: the batch has 3"));
}

#[test]
fn bad_flags_and_directories_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = write(dir.path(), "scenes.toml", &scene(""));
    let s = scenes.to_str().unwrap();
    let file = write(dir.path(), "a-file", "");
    let f = file.to_str().unwrap();
    let o = batch(&["--scenes", s, "--out", f]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("a-file"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let out = dir.path().join("out");
    let o = batch(&[
        "--scenes",
        s,
        "--out",
        out.to_str().unwrap(),
        "--max-parallel",
        "0",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--max-parallel"));
    let o = batch(&[
        "--scenes",
        s,
        "--out",
        out.to_str().unwrap(),
        "--emit",
        "pbs",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("possible values: slurm"));
    let o = batch(&["--scenes", s, "--out", out.to_str().unwrap(), "--task", "0"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot be used with"));
    let o = batch(&["--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--scenes"));
    assert!(!out.exists());
    // A task of a directory no batch was written to names the missing list.
    let o = batch(&["--out", dir.path().to_str().unwrap(), "--task", "0"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("batch.json: missing"), "{err}");
}
