//! Learning-rate schedule: Mip-NeRF's warm-up followed by a log-linear decay.

use serde::{Deserialize, Serialize};

/// Warm-up + log-linear decay (Mip-NeRF `learning_rate_decay`).
///
/// `lr(i) = delay(i) * exp((1 - t) ln(lr_init) + t ln(lr_final))` with
/// `t = clamp(i / iterations, 0, 1)` and, during the first `warmup_iters`
/// iterations, `delay(i) = m + (1 - m) sin(pi/2 * i / warmup_iters)` rising
/// from `m = warmup_factor` to 1 (a smooth warm-up that avoids the early
/// collapse of the density to zero).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScheduleConfig {
    /// Total training iterations.
    pub iterations: usize,
    /// Learning rate at iteration 0 (before the warm-up factor).
    pub lr_init: f64,
    /// Learning rate at the last iteration.
    pub lr_final: f64,
    /// Length of the warm-up in iterations (0 = none).
    pub warmup_iters: usize,
    /// Multiplier of the learning rate at iteration 0 (rises to 1 over the warm-up).
    pub warmup_factor: f64,
}

impl Default for ScheduleConfig {
    fn default() -> Self {
        Self {
            iterations: 2000,
            lr_init: 5e-3,
            lr_final: 5e-5,
            warmup_iters: 100,
            warmup_factor: 0.01,
        }
    }
}

impl ScheduleConfig {
    /// Checks that the rates are positive and finite.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [("lr_init", self.lr_init), ("lr_final", self.lr_final)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "schedule.{name} must be positive and finite, got {v}"
                ));
            }
        }
        if !(self.warmup_factor.is_finite()
            && self.warmup_factor > 0.0
            && self.warmup_factor <= 1.0)
        {
            return Err(format!(
                "schedule.warmup_factor must be in (0, 1], got {}",
                self.warmup_factor
            ));
        }
        Ok(())
    }

    /// The fraction of the schedule done before `iteration` (0-based), in
    /// `[0, 1]` (1 for an empty schedule).
    pub fn progress(&self, iteration: usize) -> f32 {
        if self.iterations == 0 {
            return 1.0;
        }
        (iteration as f64 / self.iterations as f64).clamp(0.0, 1.0) as f32
    }

    /// The learning rate at `iteration` (0-based). Pure: a resumed run gets
    /// exactly the rate the uninterrupted run would have used.
    pub fn lr(&self, iteration: usize) -> f64 {
        let t = if self.iterations == 0 {
            1.0
        } else {
            (iteration as f64 / self.iterations as f64).clamp(0.0, 1.0)
        };
        let log_lerp = ((1.0 - t) * self.lr_init.ln() + t * self.lr_final.ln()).exp();
        let delay = if self.warmup_iters > 0 {
            let s = (iteration as f64 / self.warmup_iters as f64).clamp(0.0, 1.0);
            let m = self.warmup_factor;
            m + (1.0 - m) * (0.5 * std::f64::consts::PI * s).sin()
        } else {
            1.0
        };
        delay * log_lerp
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> ScheduleConfig {
        ScheduleConfig {
            iterations: 1000,
            lr_init: 1e-2,
            lr_final: 1e-4,
            warmup_iters: 100,
            warmup_factor: 0.1,
        }
    }

    #[test]
    fn endpoints_match_closed_form() {
        let c = cfg();
        assert!((c.lr(0) - 1e-3).abs() < 1e-15, "{}", c.lr(0));
        assert!((c.lr(1000) - 1e-4).abs() < 1e-15);
        // Past the end the rate stays at lr_final.
        assert!((c.lr(5000) - 1e-4).abs() < 1e-15);
        // Half-way (after the warm-up) the rate is the geometric mean.
        assert!((c.lr(500) - 1e-3).abs() < 1e-12);
    }

    #[test]
    fn warmup_follows_the_sine_ramp_then_decay_is_log_linear() {
        let c = cfg();
        let decay =
            |i: usize| (1e-2f64.ln() + (1e-4f64.ln() - 1e-2f64.ln()) * i as f64 / 1000.0).exp();
        for i in [0, 10, 50, 99, 100, 101] {
            let s = (i as f64 / 100.0).min(1.0);
            let delay = 0.1 + 0.9 * (0.5 * std::f64::consts::PI * s).sin();
            assert!((c.lr(i) - delay * decay(i)).abs() < 1e-15, "{i}");
        }
        // After the warm-up, ln(lr) drops by the same amount per iteration.
        let step = |i: usize| c.lr(i + 1).ln() - c.lr(i).ln();
        let expected = (1e-4f64.ln() - 1e-2f64.ln()) / 1000.0;
        for i in [150, 400, 900] {
            assert!((step(i) - expected).abs() < 1e-12);
        }
    }

    #[test]
    fn no_warmup_starts_at_lr_init_and_validation_rejects_bad_rates() {
        let mut c = cfg();
        c.warmup_iters = 0;
        assert!((c.lr(0) - 1e-2).abs() < 1e-15);
        c.lr_final = 0.0;
        assert!(c.validate().is_err());
        c.lr_final = f64::NAN;
        assert!(c.validate().is_err());
        assert!(cfg().validate().is_ok());
    }
}
