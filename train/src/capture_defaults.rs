//! Sampling defaults that depend on the kind of capture, where they were
//! measured to help: on an LLFF capture (a forward-facing scene filling
//! the frame, every ray ending on a surface inside its box) the default
//! run's field is short of iterations, not of samples: 16 samples per ray
//! and level and 128 rays a batch give it about six times the iterations
//! of 48 and 256 in the same seconds, and a higher held-out PSNR
//! (docs/measurements/fern.md). On a COLMAP capture (the unbounded field with the hash
//! encoding) 64 rays a batch instead of 256 give four times the updates in
//! the same seconds and lift the held-out views (docs/measurements/unbounded.md). Other
//! captures keep the built-in settings. A `--preset`, a `--config` file
//! and `--samples` / `--rays` still win.

use datasets::detect::Format;
use datasets::{Scene, SceneSource};

use crate::config::TrainConfig;

/// The samples and rays a kind of capture trains with by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SamplingDefault {
    /// Samples per ray and level (`None`: the built-in number).
    pub samples: Option<usize>,
    /// Rays per batch.
    pub rays: usize,
    /// The capture, in words.
    pub capture: &'static str,
    /// The page that measures it.
    pub doc: &'static str,
}

/// LLFF captures: more iterations of fewer samples (docs/measurements/fern.md).
const LLFF: SamplingDefault = SamplingDefault {
    samples: Some(16),
    rays: 128,
    capture: "an LLFF capture",
    doc: "docs/measurements/fern.md",
};

/// COLMAP captures: more updates of fewer rays (docs/measurements/unbounded.md).
const COLMAP: SamplingDefault = SamplingDefault {
    samples: None,
    rays: 64,
    capture: "a COLMAP capture",
    doc: "docs/measurements/unbounded.md",
};

/// The default for `scene`'s kind of capture, if it has its own.
pub fn for_scene(scene: &Scene) -> Option<SamplingDefault> {
    if crate::appearance::is_colmap(scene) {
        return Some(COLMAP);
    }
    match scene.source.base() {
        SceneSource::Disk { loader, .. } if loader.format() == Format::Llff => Some(LLFF),
        _ => None,
    }
}

impl SamplingDefault {
    /// Sets the samples and rays on `config`, and the schedule's length so
    /// that the run draws about as many samples as before (a run without
    /// `--iters` or `--time-budget` then takes about as long).
    pub fn apply(&self, config: &mut TrainConfig) {
        let samples = self.samples.unwrap_or(config.model.num_samples);
        let before = config.model.num_samples * config.sampler.rays_per_batch;
        let after = (samples * self.rays).max(1);
        let iterations = config.schedule.iterations * before;
        config.schedule.iterations = iterations.div_ceil(after).max(1);
        config.model.num_samples = samples;
        config.sampler.rays_per_batch = self.rays;
    }

    /// Whether `config` (the default applied, then a `--config` file and
    /// the flags) still trains with these sizes.
    pub fn kept_by(&self, config: &TrainConfig) -> bool {
        config.sampler.rays_per_batch == self.rays
            && self.samples.is_none_or(|n| config.model.num_samples == n)
    }

    /// The line `train` prints.
    pub fn message(&self) -> String {
        let samples = self
            .samples
            .map(|n| format!("{n} samples per ray and level, "))
            .unwrap_or_default();
        format!(
            "sampling: {samples}{} rays a batch (auto: {}: more iterations in the same \
             seconds fit it better, {}; --samples and --rays set others)",
            self.rays, self.capture, self.doc
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A default named "test", measured on "docs/test.md".
    fn test_default(samples: Option<usize>, rays: usize) -> SamplingDefault {
        SamplingDefault {
            samples,
            rays,
            capture: "test",
            doc: "docs/test.md",
        }
    }

    #[test]
    fn apply_keeps_the_samples_drawn_and_sets_the_sizes() {
        let mut c = TrainConfig::default_run(0);
        let drawn = |c: &TrainConfig| {
            c.schedule.iterations * c.model.num_samples * c.sampler.rays_per_batch
        };
        let before = drawn(&c);
        let d = test_default(Some(16), 128);
        d.apply(&mut c);
        assert_eq!(c.model.num_samples, 16);
        assert_eq!(c.sampler.rays_per_batch, 128);
        // 1000 iterations of 48 x 256 samples are 6000 of 16 x 128.
        assert_eq!(c.schedule.iterations, 6000);
        assert_eq!(drawn(&c), before);
    }

    #[test]
    fn apply_without_samples_keeps_the_built_in_samples() {
        let mut c = TrainConfig::default_run(0);
        let d = test_default(None, 128);
        d.apply(&mut c);
        assert_eq!(c.model.num_samples, 48);
        assert_eq!(c.sampler.rays_per_batch, 128);
        // 1000 iterations of 256 rays are 2000 of 128.
        assert_eq!(c.schedule.iterations, 2000);
        assert!(
            d.message()
                .starts_with("sampling: 128 rays a batch (auto: test:"),
            "{}",
            d.message()
        );
        assert!(d.message().contains("docs/test.md"), "{}", d.message());
    }

    #[test]
    fn kept_by_asks_for_every_size_the_default_sets() {
        let llff = test_default(Some(16), 128);
        let colmap = test_default(None, 128);
        let mut c = TrainConfig::default_run(0);
        llff.apply(&mut c);
        assert!(llff.kept_by(&c));
        c.model.num_samples = 20;
        assert!(!llff.kept_by(&c));
        assert!(colmap.kept_by(&c));
        c.sampler.rays_per_batch = 64;
        assert!(!colmap.kept_by(&c));
    }
}
