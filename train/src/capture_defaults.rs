//! Sampling defaults that depend on the kind of capture, where they were
//! measured to help (docs/fern.md): on an LLFF capture (a
//! forward-facing scene filling the frame, every ray ending on a surface
//! inside its box) the default run's field is short of iterations, not of
//! samples: 16 samples per ray and level and 128 rays a batch give it
//! about six times the iterations of 48 and 256 in the same seconds, and
//! a higher held-out PSNR. Other captures keep the built-in settings. A
//! `--preset`, a `--config` file and `--samples` / `--rays` still win.

use datasets::{Scene, SceneSource};

use crate::config::TrainConfig;

/// The samples and rays a kind of capture trains with by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SamplingDefault {
    /// Samples per ray and level.
    pub samples: usize,
    /// Rays per batch.
    pub rays: usize,
    /// The capture, in words.
    pub capture: &'static str,
}

/// The default for `scene`'s kind of capture, if it has its own.
pub fn for_scene(scene: &Scene) -> Option<SamplingDefault> {
    match scene.source.base() {
        SceneSource::Disk { loader, .. } if loader.format() == "llff" => Some(SamplingDefault {
            samples: 16,
            rays: 128,
            capture: "an LLFF capture",
        }),
        _ => None,
    }
}

impl SamplingDefault {
    /// Sets the samples and rays on `config`, and the schedule's length so
    /// that the run draws about as many samples as before (a run without
    /// `--iters` or `--time-budget` then takes about as long).
    pub fn apply(&self, config: &mut TrainConfig) {
        let before = config.model.num_samples * config.sampler.rays_per_batch;
        let after = (self.samples * self.rays).max(1);
        let iterations = config.schedule.iterations * before;
        config.schedule.iterations = iterations.div_ceil(after).max(1);
        config.model.num_samples = self.samples;
        config.sampler.rays_per_batch = self.rays;
    }

    /// The line `train` prints.
    pub fn message(&self) -> String {
        format!(
            "sampling: {} samples per ray and level, {} rays a batch (auto: {}: more \
             iterations in the same seconds fit it better, docs/fern.md; \
             --samples and --rays set others)",
            self.samples, self.rays, self.capture
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn apply_keeps_the_samples_drawn_and_sets_the_sizes() {
        let mut c = TrainConfig::default_run(0);
        let drawn = |c: &TrainConfig| {
            c.schedule.iterations * c.model.num_samples * c.sampler.rays_per_batch
        };
        let before = drawn(&c);
        let d = SamplingDefault {
            samples: 16,
            rays: 128,
            capture: "test",
        };
        d.apply(&mut c);
        assert_eq!(c.model.num_samples, 16);
        assert_eq!(c.sampler.rays_per_batch, 128);
        // 1000 iterations of 48 x 256 samples are 6000 of 16 x 128.
        assert_eq!(c.schedule.iterations, 6000);
        assert_eq!(drawn(&c), before);
    }
}
