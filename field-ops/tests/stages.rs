//! The stage log's memory figures are the OS's: a stage that touches 200 MB
//! records a peak of at least that, and a later small stage (after the
//! reset) records much less. One test in its own binary, so no other test
//! allocates in the process meanwhile.

use field_ops::stages::{STAGES_FILE, StageLog, read_records};

const BIG: usize = 200 * 1024 * 1024;

#[test]
fn peak_is_per_stage_and_nested_stages_are_apart() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut log = StageLog::for_run(dir.path());
    log.begin("big");
    let mut block = vec![0u8; BIG];
    // Touch every page so it is resident.
    for (i, page) in block.chunks_mut(4096).enumerate() {
        page[0] = (i % 251) as u8 + 1;
    }
    let sum: u64 = block.iter().step_by(4096).map(|&b| b as u64).sum();
    assert!(std::hint::black_box(sum) > 0);
    drop(block);
    log.end().expect("end big");
    log.begin("outer");
    log.begin("small");
    let small = std::hint::black_box(vec![1u8; 1 << 20]);
    drop(small);
    log.end().expect("end small");
    log.end().expect("end outer");
    let records = read_records(&dir.path().join(STAGES_FILE)).expect("stages.json");
    let names: Vec<&str> = records.iter().map(|r| r.stage.as_str()).collect();
    assert_eq!(names, ["big", "small", "outer"], "in the order they ended");
    if !std::path::Path::new("/proc/self/clear_refs").exists() {
        assert!(records.iter().all(|r| r.peak_mb.is_none()));
        return;
    }
    let peak = |i: usize| records[i].peak_mb.expect("peak recorded");
    assert!(peak(0) >= 200.0, "big stage peak {} MiB", peak(0));
    assert!(
        peak(1) < peak(0) - 150.0 && peak(2) < peak(0) - 150.0,
        "after the reset: {} and {} MiB against {} MiB",
        peak(1),
        peak(2),
        peak(0)
    );
}
