//! Speed/accuracy presets (`train --preset`), chosen from the measured
//! sweep (README, "Speed against accuracy"): each sets the samples per ray,
//! the occupancy grid and the schedule's length of a point of the front;
//! `--config` keys and explicit flags (`--iters`, `--time-budget`, ...)
//! still win.

use crate::config::TrainConfig;

/// A named trade of speed for accuracy: the settings and the length of a
/// point of the lego sweep's Pareto front.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// 16 samples per ray and level, the occupancy grid, 1600 iterations
    /// (lego 100x100: 25.3 dB in 60 s of training).
    Fast,
    /// 24 samples per ray and level, the occupancy grid, 2300 iterations
    /// (lego: 27.0 dB in 120 s).
    Balanced,
    /// 24 samples per ray and level, the occupancy grid, 5000 iterations
    /// (lego: 29.4 dB in 240 s).
    Best,
}

impl Preset {
    /// Sets this preset's knobs and schedule length on `config`.
    pub fn apply(self, config: &mut TrainConfig) {
        let (samples, iterations) = match self {
            Preset::Fast => (16, 1600),
            Preset::Balanced => (24, 2300),
            Preset::Best => (24, 5000),
        };
        config.model.num_samples = samples;
        config.occupancy.enabled = true;
        config.schedule.iterations = iterations;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_grow_in_cost_and_turn_the_grid_on() {
        let cost = |p: Preset| {
            let mut c = TrainConfig::default_run(0);
            p.apply(&mut c);
            assert!(c.occupancy.enabled);
            assert!(c.validate().is_ok());
            c.model.num_samples * c.schedule.iterations
        };
        assert!(cost(Preset::Fast) < cost(Preset::Balanced));
        assert!(cost(Preset::Balanced) < cost(Preset::Best));
    }
}
