//! The training loop reads its steps' values back once a log window (the
//! steps run on the device in between), and where a step of the window was
//! not finite it goes back and takes the window's steps again, each
//! checked: the run is the one that checking every step gives.

use model::host_work::{ReadReason, read_backs};
use tests::{ci_scene, run_weights as weights, scratch_dir, serial, tiny_config};
use train::metrics_log::MetricsEvent;
use train::{BackendKind, SessionOptions, TrainConfig};

fn session() -> SessionOptions {
    SessionOptions {
        backend: BackendKind::Flex,
        final_render: false,
        ..Default::default()
    }
}

/// A short run's configuration: 32 rays a batch, logging every
/// `log_every` steps, no periodic evaluation or checkpoint.
fn config(scene: &datasets::Scene, iterations: usize, log_every: usize) -> TrainConfig {
    let mut c = tiny_config(scene, iterations);
    c.sampler.rays_per_batch = 32;
    c.logging.eval_pixels = 32;
    c.logging.log_every = log_every;
    c.logging.eval_every = 0;
    c.logging.checkpoint_every = 0;
    c.logging.max_nonfinite_steps = iterations;
    c
}

/// Trains `config` on `scene`; returns the run's weights, the iterations of
/// its skipped steps, and the reads of step values it made.
fn train(scene: &datasets::Scene, config: TrainConfig) -> (Vec<f32>, Vec<usize>, u64) {
    let dir = scratch_dir();
    let before = read_backs();
    let out = train::train_new(scene, config, 4, dir.path(), &session()).expect("trains");
    let reads = read_backs().since(&before).of(ReadReason::StepValues);
    let skipped: Vec<usize> = train::metrics_log::read(&dir.path().join("metrics.jsonl"))
        .expect("metrics.jsonl")
        .iter()
        .filter_map(|e| match e {
            MetricsEvent::Nonfinite(n) => Some(n.iteration),
            _ => None,
        })
        .collect();
    assert_eq!(out.summary.skipped_steps, skipped.len());
    (weights(dir.path()), skipped, reads)
}

#[test]
fn logging_reads_the_steps_back_once_every_log_every_steps() {
    let _guard = serial();
    let scene = ci_scene();
    for (iterations, log_every, reads) in [(30, 10, 3), (25, 10, 3), (6, 1, 6)] {
        let (_, skipped, got) = train(scene, config(scene, iterations, log_every));
        assert!(skipped.is_empty());
        assert_eq!(
            got, reads,
            "{iterations} iterations logged every {log_every}: step values read {got} times"
        );
    }
}

#[test]
fn a_window_with_a_non_finite_step_trains_as_checking_every_step_does() {
    let _guard = serial();
    // Not-a-number in every 150th pixel of each frame but the first: a step
    // whose batch draws one has a non-finite loss.
    let mut scene = ci_scene().clone();
    for frame in scene.frames.iter_mut().skip(1) {
        let datasets::RgbData::F32(values) = &mut frame.rgb.data else {
            panic!("the synthetic scene's colours are floats");
        };
        for (i, v) in values.iter_mut().enumerate() {
            if (i / 3) % 150 == 7 {
                *v = f32::NAN;
            }
        }
    }
    let iterations = 40;
    let (every_step, skipped, reads_every_step) = train(&scene, config(&scene, iterations, 1));
    assert!(
        !skipped.is_empty() && skipped.len() < iterations / 2,
        "some steps, not most, are skipped: {skipped:?}"
    );
    assert_eq!(reads_every_step, iterations as u64, "one read a step");
    let (windowed, skipped_windowed, reads) = train(&scene, config(&scene, iterations, 10));
    assert_eq!(skipped_windowed, skipped, "the same steps are skipped");
    assert!(
        weights_equal(&windowed, &every_step),
        "the same weights, bit for bit"
    );
    // One read a window, and one a step taken again.
    assert!(
        reads > 4 && reads < reads_every_step,
        "{reads} reads against {reads_every_step} checking every step"
    );
}

fn weights_equal(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}
