//! Speed/accuracy presets (`train --preset`), chosen from the measured
//! sweeps (docs/measurements/sweep-and-presets.md): each sets the samples per ray,
//! the occupancy grid, the rays per batch and the schedule's length of a
//! measured point; `--config` keys and explicit flags (`--iters`,
//! `--rays`, `--time-budget`, ...) still win.
//!
//! The settings depend on the kind of scene. An object seen from outside
//! (lego) was swept with 256 rays a batch. On a room, where every ray
//! starts inside the scene and ends on a wall, the same samples and grid
//! with 128 rays a batch and as many iterations as fill the same seconds
//! gave a higher PSNR at every preset's budget and the same segmentation
//! on average (docs/measurements/sweep-and-presets.md, "The presets on the room").

use crate::config::TrainConfig;

/// A named trade of speed for accuracy: the settings and the length of a
/// point of the sweeps' Pareto fronts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// 16 samples per ray and level, the occupancy grid, 1600 iterations
    /// (lego 100x100: 25.3 dB in 60 s of training); on a room 128 rays a
    /// batch and 2600 iterations.
    Fast,
    /// 24 samples per ray and level, the occupancy grid, 2300 iterations
    /// (lego: 27.0 dB in 120 s); on a room 128 rays a batch and 4150
    /// iterations.
    Balanced,
    /// 24 samples per ray and level, the occupancy grid, 5000 iterations
    /// (lego: 29.4 dB in 240 s); on a room 128 rays a batch and 9000
    /// iterations.
    Best,
}

/// What the presets tell apart: a scene seen from outside, whose rays can
/// miss it, and a scene the cameras stand in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneKind {
    /// The cameras stand outside the scene box and look in (an object).
    Object,
    /// Most cameras stand inside the scene box (a room or a walk-through
    /// capture: every ray starts inside and ends on a surface).
    Room,
}

impl SceneKind {
    /// Lower-case name for messages.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Object => "object",
            SceneKind::Room => "room",
        }
    }
}

/// What a preset sets (besides turning the occupancy grid on).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PresetSettings {
    /// Samples per ray and level.
    pub samples: usize,
    /// Rays per batch.
    pub rays: usize,
    /// The schedule's length.
    pub iterations: usize,
}

impl Preset {
    /// The preset's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Fast => "fast",
            Preset::Balanced => "balanced",
            Preset::Best => "best",
        }
    }

    /// This preset's settings on a scene of `kind`.
    pub fn settings(self, kind: SceneKind) -> PresetSettings {
        let (samples, rays, iterations) = match (self, kind) {
            (Preset::Fast, SceneKind::Object) => (16, 256, 1600),
            (Preset::Balanced, SceneKind::Object) => (24, 256, 2300),
            (Preset::Best, SceneKind::Object) => (24, 256, 5000),
            (Preset::Fast, SceneKind::Room) => (16, 128, 2600),
            (Preset::Balanced, SceneKind::Room) => (24, 128, 4150),
            (Preset::Best, SceneKind::Room) => (24, 128, 9000),
        };
        PresetSettings {
            samples,
            rays,
            iterations,
        }
    }

    /// Sets this preset's knobs and schedule length for a scene of `kind`
    /// on `config`, with the occupancy grid when `grid` (a field that can
    /// use one), and returns them.
    pub fn apply(self, config: &mut TrainConfig, kind: SceneKind, grid: bool) -> PresetSettings {
        let s = self.settings(kind);
        config.model.num_samples = s.samples;
        config.sampler.rays_per_batch = s.rays;
        config.occupancy.enabled = grid;
        config.schedule.iterations = s.iterations;
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_grow_in_cost_and_turn_the_grid_on() {
        for kind in [SceneKind::Object, SceneKind::Room] {
            let cost = |p: Preset| {
                let mut c = TrainConfig::default_run(0);
                p.apply(&mut c, kind, true);
                assert!(c.occupancy.enabled);
                assert!(c.validate().is_ok());
                c.model.num_samples * c.sampler.rays_per_batch * c.schedule.iterations
            };
            assert!(cost(Preset::Fast) < cost(Preset::Balanced));
            assert!(cost(Preset::Balanced) < cost(Preset::Best));
        }
    }

    #[test]
    fn a_room_halves_the_batch_and_runs_more_iterations() {
        for p in [Preset::Fast, Preset::Balanced, Preset::Best] {
            let (obj, room) = (p.settings(SceneKind::Object), p.settings(SceneKind::Room));
            assert_eq!(obj.samples, room.samples);
            assert_eq!((obj.rays, room.rays), (256, 128));
            // The same seconds: more iterations, fewer rays in all.
            assert!(
                room.iterations > obj.iterations
                    && room.iterations * room.rays < obj.iterations * obj.rays
            );
        }
    }
}
