//! The fit monitor: the readings' mean log-likelihood at the EKF's pose,
//! against its own long-term average (augmented MCL's test, on the EKF's one
//! hypothesis). It notices a kidnap in a few cycles, where the gate's counts
//! need many.

use super::super::expect::FieldLookup;
use super::super::measure::{Measure, Sensed};
use super::{compose, CycleReport, Localizer};
use crate::f32math::sin_cos;

impl<const N: usize> Localizer<N> {
    /// The fit monitor: the readings' mean log-likelihood at the EKF's pose
    /// (at the cycle's start), its short- and long-term averages (augmented
    /// MCL's, on the EKF's one hypothesis); true when the short one has
    /// been `fit_drop` below the long one for `fit_cycles` cycles in a row:
    /// the readings no longer fit the pose, as after a kidnap, well before
    /// the gate's counts say so.
    pub(super) fn monitor(&mut self, lookup: &FieldLookup<'_, '_>, report: &mut CycleReport) -> bool {
        let c = &self.cfg;
        let k = Sensed::usable(&self.sensed);
        if N == 0 || lookup.field().is_empty() || k < usize::from(c.handoff_min_readings) {
            return false;
        }
        let start = self.ekf_at_cycle_start();
        let fit = Measure::new(lookup, &c.mcl.beam, 0.0).log_likelihood(&start, &self.sensed) / k as f32;
        let (fast, slow) = self.fit;
        let (fast, slow) = if self.fit_seen == 0 { (fit, fit) } else { (fast + c.fit_fast * (fit - fast), slow) };
        let bad = fast < slow - c.fit_drop;
        // The long-term average learns from every cycle, slowly: a lasting
        // drop shows against it for many cycles, while leaving out the bad
        // ones would bias it to the best the place ever gave.
        let slow = if self.fit_seen == 0 {
            slow
        } else {
            slow + c.fit_slow.max(1.0 / (self.fit_seen as f32 + 1.0)) * (fit - slow)
        };
        self.fit = (fast, slow);
        self.fit_seen = self.fit_seen.saturating_add(1);
        self.misfit = if bad { self.misfit.saturating_add(1) } else { 0 };
        report.fit = [fit, fast, slow];
        // `fit_cycles` 0 is off (it said so, yet fired on every cycle).
        c.fit_cycles > 0 && self.fit_seen > u16::from(c.fit_cycles) * 4 && self.misfit >= c.fit_cycles
    }

    /// The EKF's estimate carried back to the cycle's start (where the
    /// particles stand and the readings are expressed): now ⊕ offset⁻¹.
    pub(super) fn ekf_at_cycle_start(&self) -> [f32; 3] {
        back_to_start(&self.referencer.ekf.state(), &self.offset)
    }
}

/// `now` carried back by the odometry `offset` since the cycle's start:
/// now ⊕ offset⁻¹.
pub(super) fn back_to_start(now: &[f32; 3], offset: &[f32; 3]) -> [f32; 3] {
    let (s, co) = sin_cos(offset[2]);
    let (ox, oy) = (-(co * offset[0] + s * offset[1]), s * offset[0] - co * offset[1]);
    compose(now, &[ox, oy, -offset[2]])
}
