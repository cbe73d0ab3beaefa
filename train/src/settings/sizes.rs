//! The samples and rays a capture kind's row sets, with the schedule's
//! length scaled so that a run draws about as many samples as with the
//! built-in sizes (a run without `--iters` or `--time-budget` then takes
//! about as long).

use super::table::{FieldModel, Row, Sampler};
use crate::config::TrainConfig;

/// The sizes a row sets (at least one of them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sizes {
    /// Samples per ray and level (`None`: the built-in number).
    pub samples: Option<usize>,
    /// Rays per batch (`None`: the built-in number).
    pub rays: Option<usize>,
}

impl Sizes {
    /// The sizes `row` sets for a field `model` sampled by `sampler`, if
    /// it sets any.
    pub fn of_row(row: &Row, model: FieldModel, sampler: Sampler) -> Option<Self> {
        let samples = row.samples_for(model, sampler);
        (samples.is_some() || row.rays.is_some()).then_some(Self {
            samples,
            rays: row.rays,
        })
    }

    /// Sets the sizes on `config`, and the schedule's length so that the
    /// run draws about as many samples as before.
    pub fn apply(&self, config: &mut TrainConfig) {
        let samples = self.samples.unwrap_or(config.model.num_samples);
        let rays = self.rays.unwrap_or(config.sampler.rays_per_batch);
        let before = config.model.num_samples * config.sampler.rays_per_batch;
        let after = (samples * rays).max(1);
        let iterations = config.schedule.iterations * before;
        config.schedule.iterations = iterations.div_ceil(after).max(1);
        config.model.num_samples = samples;
        config.sampler.rays_per_batch = rays;
    }

    /// Whether a run trains with these sizes when the samples and the
    /// rays are set again later (`samples_set`, `rays_set`: by the file or
    /// a flag): only those this row sets matter.
    pub fn kept(&self, samples_set: bool, rays_set: bool) -> bool {
        !(self.samples.is_some() && samples_set || self.rays.is_some() && rays_set)
    }

    /// The line `train` prints, with the row's reason.
    pub fn line(&self, reason: &str) -> String {
        let samples = self
            .samples
            .map(|n| format!("{n} samples per ray and level, "))
            .unwrap_or_default();
        let rays = self
            .rays
            .map(|n| format!("{n} rays a batch"))
            .unwrap_or_else(|| "the built-in rays a batch".into());
        format!("sampling: {samples}{rays} ({reason}; --samples and --rays set others)")
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
        let d = Sizes {
            samples: Some(16),
            rays: Some(128),
        };
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
        let d = Sizes {
            samples: None,
            rays: Some(128),
        };
        d.apply(&mut c);
        assert_eq!(c.model.num_samples, 48);
        assert_eq!(c.sampler.rays_per_batch, 128);
        // 1000 iterations of 256 rays are 2000 of 128.
        assert_eq!(c.schedule.iterations, 2000);
        let line = d.line("auto: test: docs/test.md");
        assert!(
            line.starts_with("sampling: 128 rays a batch (auto: test:"),
            "{line}"
        );
        assert!(line.contains("docs/test.md"), "{line}");
    }

    #[test]
    fn the_fast_field_takes_its_own_samples_where_a_row_sets_them() {
        use super::super::table::row;
        use datasets::capture_kind::CaptureKind;
        let object = row(CaptureKind::PhotographedObject);
        for sampler in [Sampler::CoarseFine, Sampler::Proposal] {
            assert_eq!(Sizes::of_row(&object, FieldModel::Mip, sampler), None);
        }
        let fast = Sizes::of_row(&object, FieldModel::Fast, Sampler::Proposal)
            .expect("the fast field's samples");
        assert_eq!((fast.samples, fast.rays), (Some(24), None));
        assert!(
            object
                .sizes_why_for(FieldModel::Fast, Sampler::Proposal)
                .contains("24 samples")
        );
        // The fast field's own samples are for its proposal networks: on
        // the coarse and fine levels it samples as the Mip-NeRF field does.
        assert_eq!(
            Sizes::of_row(&object, FieldModel::Fast, Sampler::CoarseFine),
            None
        );
        assert_eq!(
            object.sizes_why_for(FieldModel::Fast, Sampler::CoarseFine),
            object.sizes_why
        );
        // Elsewhere the fast field samples as the row says for both fields.
        let forward = row(CaptureKind::ForwardFacing);
        for model in [FieldModel::Mip, FieldModel::Fast] {
            for sampler in [Sampler::CoarseFine, Sampler::Proposal] {
                let s = Sizes::of_row(&forward, model, sampler).expect("the row's samples");
                assert_eq!(s.samples, Some(16), "{model:?}");
                assert_eq!(
                    forward.sizes_why_for(model, sampler),
                    forward.sizes_why,
                    "{model:?}"
                );
                assert_eq!(
                    Sizes::of_row(&row(CaptureKind::Room), model, sampler),
                    None,
                    "{model:?}"
                );
            }
        }
    }

    #[test]
    fn kept_asks_for_every_size_the_row_sets() {
        let llff = Sizes {
            samples: Some(16),
            rays: Some(128),
        };
        let colmap = Sizes {
            samples: None,
            rays: Some(128),
        };
        assert!(llff.kept(false, false));
        // Samples set again break the LLFF default but not the COLMAP one.
        assert!(!llff.kept(true, false));
        assert!(colmap.kept(true, false));
        // Rays set again break both.
        assert!(!colmap.kept(false, true));
        assert!(!llff.kept(false, true));
    }
}
