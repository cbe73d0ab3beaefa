//! The schedule's fit to a time budget: the length of the schedule set
//! from the measured pace of the steps, so that the learning rate decays
//! over the whole budget.

use super::session::SessionOptions;

/// Fits the schedule's length to a time budget from the measured time of
/// the steps (evaluations and checkpoints included, as they happen).
///
/// The first fit comes after a few timed steps; the fit is then repeated
/// every tenth of the planned run from the step time since the last fit,
/// so that a run that slows down (a busier machine, a longer step later in
/// training) still reaches the end of its learning-rate decay
/// inside the budget instead of being cut off half-way.
#[derive(Debug, Clone, Copy)]
struct BudgetFit {
    budget: f64,
    /// `(iteration, elapsed seconds)` when timing started or last fitted.
    start: Option<(usize, f64)>,
    /// Iteration of the next fit.
    next: usize,
}

impl BudgetFit {
    /// Steps before timing starts (the first ones pay for allocation and
    /// warm-up) and steps timed.
    const SKIP: usize = 3;
    const TIMED: usize = 20;
    /// Fraction of the remaining budget planned for, leaving room for the
    /// periodic evaluations and checkpoints the timed steps did not include.
    const SAFETY: f64 = 0.95;
    /// Refits per planned run.
    const REFITS: usize = 10;

    fn new(budget: f64) -> Self {
        Self {
            budget,
            start: None,
            next: Self::SKIP + Self::TIMED,
        }
    }

    /// Called before iteration `it`; returns the (re)fitted number of
    /// iterations when a fit is due and changes the plan.
    fn observe(&mut self, it: usize, elapsed: f64) -> Option<usize> {
        match self.start {
            None if it >= Self::SKIP => {
                self.start = Some((it, elapsed));
                None
            }
            Some((i0, t0)) if it >= self.next && it > i0 => {
                // The pace since the last fit: what the next steps will cost.
                let per_step = (elapsed - t0) / (it - i0) as f64;
                let left = (self.budget - elapsed).max(0.0) * Self::SAFETY;
                let planned = it + (left / per_step.max(1e-9)).floor() as usize;
                self.start = Some((it, elapsed));
                self.next = it + (planned / Self::REFITS).max(Self::TIMED);
                Some(planned)
            }
            _ => None,
        }
    }
}

/// A session's fit and what it has said about it: the first fit is news,
/// later ones only when the plan moves by more than a few per cent.
#[derive(Debug, Clone, Copy)]
pub(super) struct ScheduleFit {
    fit: BudgetFit,
    fitted_once: bool,
    reported: usize,
}

/// A new length of the schedule.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Refit {
    /// Iterations of the schedule.
    pub iterations: usize,
    /// What to tell the user, if anything.
    pub announce: Option<String>,
}

impl ScheduleFit {
    /// The fit of a session that starts at `iteration`: only a new run
    /// asked to fit its schedule to a time budget has one.
    pub(super) fn for_session(session: &SessionOptions, iteration: usize) -> Option<Self> {
        match session.time_budget {
            Some(budget) if session.fit_schedule_to_budget && iteration == 0 => Some(Self {
                fit: BudgetFit::new(budget),
                fitted_once: false,
                reported: 0,
            }),
            _ => None,
        }
    }

    /// Called before iteration `it`, `elapsed` seconds into the session,
    /// with a schedule of `iterations`: the new length when it changes.
    pub(super) fn observe(&mut self, it: usize, elapsed: f64, iterations: usize) -> Option<Refit> {
        let fitted = self.fit.observe(it, elapsed)?;
        if fitted == iterations {
            return None;
        }
        let first = !self.fitted_once;
        self.fitted_once = true;
        let announce = (first || fitted.abs_diff(self.reported) * 20 > self.reported).then(|| {
            self.reported = fitted;
            format!(
                "schedule {} to the time budget: {fitted} iterations",
                if first { "fitted" } else { "refitted" }
            )
        });
        Some(Refit {
            iterations: fitted,
            announce,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::{BudgetFit, ScheduleFit, SessionOptions};

    /// Steps of 0.5 s after a slow first one: the fit skips the first steps,
    /// times 20, and plans 95% of what is left of the budget.
    #[test]
    fn the_schedule_is_fitted_to_the_remaining_budget() {
        let mut fit = BudgetFit::new(100.0);
        let elapsed = |it: usize| if it == 0 { 0.0 } else { 4.0 + 0.5 * it as f64 };
        let mut fitted = None;
        for it in 0..100 {
            if let Some(n) = fit.observe(it, elapsed(it)) {
                fitted = Some((it, n));
                break;
            }
        }
        let (at, n) = fitted.expect("fitted after the timed steps");
        assert_eq!(at, BudgetFit::SKIP + BudgetFit::TIMED);
        // At iteration 23, 15.5 s have passed: 0.95 * 84.5 / 0.5 = 160.55 more.
        assert_eq!(n, 23 + 160);
        // A budget already spent plans no further iteration.
        let mut late = BudgetFit::new(1.0);
        assert_eq!(late.observe(3, 2.0), None);
        assert_eq!(late.observe(23, 12.0), Some(23));
    }

    /// Steps that become twice as slow half-way: the refits shorten the
    /// plan so that the run ends inside the budget, near its fitted end.
    #[test]
    fn a_run_that_slows_down_is_refitted_to_end_inside_the_budget() {
        let budget = 100.0;
        let mut fit = BudgetFit::new(budget);
        let step = |it: usize| if it < 100 { 0.25 } else { 0.5 };
        let (mut t, mut planned, mut refits) = (0.0, usize::MAX, 0);
        let mut it = 0;
        while it < planned && t < budget {
            if let Some(n) = fit.observe(it, t) {
                planned = n;
                refits += 1;
            }
            t += step(it);
            it += 1;
        }
        assert!(refits >= 3, "{refits} fits");
        // The plan was met before the budget ran out...
        assert_eq!(it, planned, "stopped at {it} of {planned} after {t} s");
        assert!(t <= budget);
        // ...and little of the budget is left unused.
        assert!(t > 0.85 * budget, "ended at {t} s");
        // Fitted once at 0.25 s a step, the plan would have been ~380
        // iterations, which take ~140 s at the slower pace.
        assert!(planned < 300, "{planned}");
    }

    /// Only a new run asked to fit its schedule has a fit; the first fit is
    /// announced, a later one only when it moves the plan by over 5%.
    #[test]
    fn fits_are_announced_when_they_are_news() {
        let budget = SessionOptions {
            time_budget: Some(100.0),
            fit_schedule_to_budget: true,
            ..SessionOptions::default()
        };
        assert!(ScheduleFit::for_session(&budget, 10).is_none());
        let fixed = SessionOptions {
            fit_schedule_to_budget: false,
            ..budget.clone()
        };
        assert!(ScheduleFit::for_session(&fixed, 0).is_none());
        let mut fit = ScheduleFit::for_session(&budget, 0).unwrap();
        // 0.5 s a step from iteration 3 on.
        let elapsed = |it: usize| 0.5 * it as f64;
        let mut refits = Vec::new();
        let mut iterations = 1000;
        for it in 0..200 {
            if let Some(r) = fit.observe(it, elapsed(it), iterations) {
                iterations = r.iterations;
                refits.push((it, r));
            }
        }
        let (at, first) = &refits[0];
        assert_eq!(*at, 23);
        // 0.95 * (100 - 11.5) / 0.5 = 168.15 more.
        assert_eq!(first.iterations, 23 + 168);
        assert_eq!(
            first.announce.as_deref(),
            Some("schedule fitted to the time budget: 191 iterations")
        );
        // At a steady pace later fits move the plan by a step or two: no news.
        assert!(refits[1..].iter().all(|(_, r)| r.announce.is_none()));
        // A fit that matches the schedule changes nothing.
        let mut same = ScheduleFit::for_session(&budget, 0).unwrap();
        assert_eq!(same.observe(3, 1.5, 191), None);
        assert_eq!(same.observe(23, 11.5, 191), None);
    }
}
