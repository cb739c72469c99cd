//! Online calibration of the odometry's systematic heading errors, from the
//! filter's own corrections.
//!
//! A differential-drive robot's odometry turns its heading wrongly in two
//! systematic ways (Borenstein's UMBmark): unequal wheel radii turn it by a
//! fixed amount per metre driven, and a wrong wheelbase scales every turn.
//! A range-only filter sees heading worst (a transducer's lever on the ring is
//! a few tenths of a metre), so each turn's error lingers for many cycles and
//! a long stretch without beacons drifts by the per-metre error. Both errors
//! are the robot's, constant over a run, and can be learned.
//!
//! While the filter is sure of its heading, the difference between its
//! heading and the raw odometry's, `c`, grows as
//! `c ≈ b_turn · T + b_drive · D + const`, with `T` the odometry's turn and
//! `D` its forward distance, both summed since the start. Once a ring cycle
//! the three sums are a sample; an exponentially weighted least-squares fit of
//! `c` on `T` and `D` (centred, so an intercept is implicit and the sums'
//! size does not cost precision in `f32`) gives the two biases, and every
//! odometry step is then corrected by them before the filter predicts with it:
//! `dφ' = dφ · (1 + b_turn) + b_drive · dx`.
//!
//! The fit runs on the cumulative sums, not on each cycle's increments, because
//! the filter corrects a turn's error over the cycles *after* the turn: only
//! the sums carry that correction back to the turn that caused it.
//!
//! Samples are taken only while the filter is neither lost nor on its way
//! to being lost, and its heading σ is small; a lost cycle throws the
//! statistics away (the pose may jump, and what the filter said while wrong is
//! not evidence), keeping the estimate in use until a new one is ready. The
//! estimate is clamped to what a calibrated robot's odometry can be.
//!
//! Fixed memory (18 floats and a counter: 84 bytes), no
//! allocation, `f32`.
//!
//! ```
//! use echoloc::referencing::calibration::{CalibrationConfig, OdometryCalibration, Standing};
//! use echoloc::referencing::Motion;
//! let (cfg, mut cal) = (CalibrationConfig::DEFAULT, OdometryCalibration::new());
//! // The odometry turns 2 % short and drifts 0.1°/m left; the filter, sure
//! // of itself, follows the truth.
//! let (mut truth, mut heading) = (0.0f32, 0.0f32);
//! for k in 0..400 {
//!     // Left and right turns (turning one way only, the turn and the
//!     // distance would grow together and could not be told apart).
//!     let turn = match k % 40 { 0 => 1.5, 20 => -1.0, _ => 0.0 };
//!     let u = Motion { dx: 0.2, dy: 0.0, dphi: turn * 0.98 + 0.2 * 0.1f32.to_radians() };
//!     let _step = cal.corrected(&u); // what the filter would predict with
//!     cal.take(&cfg, &u, heading);
//!     truth += turn;
//!     heading = echoloc::referencing::wrap(truth);
//!     cal.end_cycle(&cfg, heading, 0.001, Standing::Sure);
//! }
//! let b = cal.estimate().unwrap();
//! assert!((b.per_rad - (1.0 / 0.98 - 1.0)).abs() < 1e-3);
//! assert!((b.per_m + 0.1f32.to_radians()).abs() < 1e-4);
//! ```

use super::model::{wrap, Motion};

/// Calibration settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationConfig {
    /// Whether the odometry is corrected at all.
    pub enabled: bool,
    /// Memory of the fit, in samples (ring cycles): a sample's weight is
    /// `1/n` for the first `memory` samples (the plain fit), then
    /// `1/memory` (older samples fade).
    pub memory: f32,
    /// Samples since the statistics were last thrown away before a fit is
    /// used.
    pub min_samples: u16,
    /// Samples are taken only while the filter's heading σ is below this, rad.
    pub max_sigma_rad: f32,
    /// Largest |turn error| taken, rad per rad turned.
    pub max_per_rad: f32,
    /// Largest |drift| taken, rad per metre driven.
    pub max_per_m: f32,
    /// A fit is used only if the turn and the distance sums' correlation
    /// leaves at least this fraction of their variances' product in the
    /// determinant (they are apart enough to be told apart).
    pub min_independence: f32,
}

impl CalibrationConfig {
    /// Settings for the simulator's calibrated Pioneer-class robot
    /// (docs/self-referencing.md): a fit over all samples up to 5 000 cycles
    /// (about 50 min), used after 100 (a minute), sampled while the heading σ
    /// is under 3° (1° kept a filter with few readings from ever sampling:
    /// docs/self-referencing.md); clamped to 3 % of a turn and 0.57°/m (a UMBmark-
    /// calibrated robot's wheel-diameter error of 0.2 % over a 0.33 m
    /// wheelbase drifts 0.35°/m).
    pub const DEFAULT: Self = Self {
        enabled: true,
        memory: 5000.0,
        min_samples: 100,
        max_sigma_rad: 0.052_359_88,
        max_per_rad: 0.03,
        max_per_m: 0.01,
        min_independence: 0.05,
    };

    /// No calibration: the odometry is used as it comes.
    pub const OFF: Self = Self { enabled: false, ..Self::DEFAULT };
}

/// The odometry's systematic heading errors, as corrections.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingBias {
    /// Added to each turn, per radian the odometry turned.
    pub per_rad: f32,
    /// Added per metre the odometry drove forward, rad.
    pub per_m: f32,
}

/// How the filter stood at the end of a cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Standing {
    /// Neither lost nor on its way.
    Sure,
    /// Bad cycles in a row, not yet lost.
    Doubtful,
    /// Lost.
    Lost,
}

/// The calibrator: the running sums and the weighted statistics of the
/// samples. Its settings are passed to each call, as the filter holds them
/// (`EkfConfig::calibration`), the way [`super::recovery::Recent`] takes its own.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OdometryCalibration {
    /// Running sums: odometry turn T, forward distance D, and filter heading
    /// minus odometry heading c.
    sums: [f32; 3],
    /// The filter's heading when `sums[2]` was last brought up to date.
    heading: Option<f32>,
    /// Weighted means and covariances of the samples (T, D, c), since the
    /// last reset.
    mean: [f32; 3],
    cov: [[f32; 3]; 3],
    samples: u32,
    estimate: Option<HeadingBias>,
}

/// Sums beyond this are shifted back (the statistics are centred, so only
/// differences matter, and small numbers keep `f32`'s precision).
const REBASE: f32 = 1024.0;

impl OdometryCalibration {
    /// A calibrator with nothing learned.
    pub const fn new() -> Self {
        Self { sums: [0.0; 3], heading: None, mean: [0.0; 3], cov: [[0.0; 3]; 3], samples: 0, estimate: None }
    }

    /// The correction in use, if any (never one while the settings say off:
    /// nothing is then fitted).
    pub fn estimate(&self) -> Option<HeadingBias> {
        self.estimate
    }

    /// Samples in the statistics now.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The step the filter should predict with for the odometry's step `u`.
    pub fn corrected(&self, u: &Motion) -> Motion {
        match self.estimate() {
            Some(b) => Motion { dphi: u.dphi + b.per_rad * u.dphi + b.per_m * u.dx, ..*u },
            None => *u,
        }
    }

    /// The filter, at `heading`, has taken the odometry's step `u` (as
    /// [`Self::corrected`] gave it): the sums take the raw step. Called only
    /// once the filter has accepted the step, so a refused one counts for
    /// neither.
    pub fn take(&mut self, cfg: &CalibrationConfig, u: &Motion, heading: f32) {
        if !cfg.enabled {
            return;
        }
        self.follow(heading);
        self.sums[0] += u.dphi;
        self.sums[1] += u.dx;
        self.sums[2] -= u.dphi;
    }

    /// Ends a ring cycle: the filter's heading now, its σ (rad), and how it
    /// stands. A sure cycle with a small σ is a sample; a doubtful one is
    /// not; a lost one throws the statistics away.
    pub fn end_cycle(&mut self, cfg: &CalibrationConfig, heading: f32, sigma_rad: f32, standing: Standing) {
        if !cfg.enabled {
            return;
        }
        self.follow(heading);
        match standing {
            Standing::Lost => {
                self.samples = 0;
                return;
            }
            Standing::Doubtful => return,
            Standing::Sure => {}
        }
        if sigma_rad.is_nan() || sigma_rad > cfg.max_sigma_rad {
            return;
        }
        self.add(cfg.memory);
        if self.samples >= u32::from(cfg.min_samples) {
            if let Some(b) = self.fit(cfg) {
                self.estimate = Some(b);
            }
        }
    }

    /// Brings `c` up to the filter's heading (its change since the last
    /// call, wrapped: the filter's heading is reduced to (−π, π]).
    fn follow(&mut self, heading: f32) {
        if let Some(h) = self.heading {
            self.sums[2] += wrap(heading - h);
        }
        self.heading = Some(heading);
    }

    fn add(&mut self, memory: f32) {
        if self.samples == 0 {
            self.mean = self.sums;
            self.cov = [[0.0; 3]; 3];
        }
        self.samples = self.samples.saturating_add(1);
        let w = (1.0 / self.samples as f32).max(1.0 / memory.max(1.0));
        let d = [self.sums[0] - self.mean[0], self.sums[1] - self.mean[1], self.sums[2] - self.mean[2]];
        for i in 0..3 {
            self.mean[i] += w * d[i];
            for j in 0..3 {
                self.cov[i][j] = (1.0 - w) * (self.cov[i][j] + w * d[i] * d[j]);
            }
        }
        if self.sums.iter().any(|s| libm::fabsf(*s) > REBASE) {
            for i in 0..3 {
                self.sums[i] -= self.mean[i];
                self.mean[i] = 0.0;
            }
        }
    }

    /// The least-squares biases of the statistics, clamped; `None` when the
    /// turn and the distance cannot be told apart.
    fn fit(&self, cfg: &CalibrationConfig) -> Option<HeadingBias> {
        let c = &self.cov;
        let (tt, dd, td) = (c[0][0], c[1][1], c[0][1]);
        let det = tt * dd - td * td;
        if !(tt > 0.0 && dd > 0.0 && det > cfg.min_independence * tt * dd) {
            return None;
        }
        let per_rad = (dd * c[0][2] - td * c[1][2]) / det;
        let per_m = (tt * c[1][2] - td * c[0][2]) / det;
        if !(per_rad.is_finite() && per_m.is_finite()) {
            return None;
        }
        let (r, m) = (cfg.max_per_rad, cfg.max_per_m);
        Some(HeadingBias { per_rad: crate::f32math::clamp(per_rad, -r, r), per_m: crate::f32math::clamp(per_m, -m, m) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drive of straight legs and turns; the filter's heading is the truth
    /// plus `noise(k)`. Returns the calibrator.
    fn drive(per_rad: f64, per_m: f64, noise: impl Fn(usize) -> f64, cycles: usize) -> OdometryCalibration {
        let (cfg, mut cal) = (CalibrationConfig::DEFAULT, OdometryCalibration::new());
        let mut truth = 0.0f64;
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        for k in 0..cycles {
            // Turns of ±0.3–2.5 rad every 10–30 cycles; 0.23 m a cycle otherwise.
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let r = (rng >> 11) as f64 / (1u64 << 53) as f64;
            let (turn, dx) = if k % 17 == 0 { ((r - 0.5) * 5.0, 0.0) } else { (0.0, 0.23) };
            // The odometry: true turn over (1 + per_rad), and drift the other way.
            let odo = Motion { dx: dx as f32, dy: 0.0, dphi: (turn / (1.0 + per_rad) - per_m * dx) as f32 };
            let heading = wrap((truth + noise(k)) as f32);
            cal.take(&cfg, &odo, heading);
            truth += turn;
            cal.end_cycle(&cfg, wrap((truth + noise(k)) as f32), 0.005, Standing::Sure);
        }
        cal
    }

    #[test]
    fn learns_the_biases_of_a_filter_that_follows_the_truth() {
        for (r, m) in [(0.01, 0.006), (-0.02, -0.003), (0.0, 0.0), (0.025, -0.008)] {
            let cal = drive(r, m, |_| 0.0, 3000);
            let b = cal.estimate().unwrap();
            assert!((f64::from(b.per_rad) - r).abs() < 2e-4, "{r}: {b:?}");
            // The odometry's drift is also in its turn sum: the fit's per-metre
            // term is m·(1 + r) (see `drive`).
            assert!((f64::from(b.per_m) - m * (1.0 + r)).abs() < 2e-5, "{m}: {b:?}");
        }
    }

    #[test]
    fn learns_them_through_a_noisy_lagging_filter() {
        // The filter's heading error: 1° of noise, and each turn's error
        // corrected only slowly (a bounded error does not bias the fit on the sums).
        let noise = |k: usize| 0.5f64.to_radians() * ((k as f64 * 0.7).sin() + (k as f64 * 0.13).cos());
        let cal = drive(0.012, 0.004, noise, 3000);
        let b = cal.estimate().unwrap();
        assert!((f64::from(b.per_rad) - 0.012).abs() < 1e-3, "{b:?}");
        assert!((f64::from(b.per_m) - 0.004 * 1.012).abs() < 2e-4, "{b:?}");
    }

    #[test]
    fn corrects_nothing_before_enough_samples_and_when_off() {
        let cal = drive(0.02, 0.005, |_| 0.0, 99);
        assert_eq!(cal.estimate(), None);
        let u = Motion { dx: 0.3, dy: 0.01, dphi: 0.2 };
        assert_eq!(cal.corrected(&u), u);
        let mut off = OdometryCalibration::new();
        for _ in 0..200 {
            off.take(&CalibrationConfig::OFF, &u, 0.0);
            off.end_cycle(&CalibrationConfig::OFF, 1.0, 0.0, Standing::Sure);
        }
        assert_eq!(off.samples(), 0);
        assert_eq!(off.corrected(&u), u);
    }

    #[test]
    fn corrects_each_step_by_the_estimate() {
        let cal = drive(0.02, 0.005, |_| 0.0, 1000);
        let b = cal.estimate().unwrap();
        let u = Motion { dx: 0.3, dy: 0.01, dphi: 0.2 };
        let v = cal.corrected(&u);
        assert_eq!((v.dx, v.dy), (u.dx, u.dy));
        assert!((v.dphi - (0.2 * (1.0 + b.per_rad) + 0.3 * b.per_m)).abs() < 1e-7);
    }

    #[test]
    fn clamps_and_forgets_what_a_lost_filter_said() {
        // 10 % turn error is beyond a calibrated robot: clamped to 3 %.
        let mut cal = drive(0.1, 0.0, |_| 0.0, 1000);
        assert_eq!(cal.estimate().unwrap().per_rad, CalibrationConfig::DEFAULT.max_per_rad);
        let kept = cal.estimate();
        let n = cal.samples();
        let cfg = CalibrationConfig::DEFAULT;
        cal.end_cycle(&cfg, 0.5, 0.001, Standing::Doubtful);
        assert_eq!(cal.samples(), n);
        cal.end_cycle(&cfg, 0.5, 0.001, Standing::Lost);
        assert_eq!(cal.samples(), 0);
        assert_eq!(cal.estimate(), kept);
    }

    #[test]
    fn a_straight_drive_cannot_tell_turn_from_drift() {
        // Only driving: no turn to fit, no estimate.
        let (cfg, mut cal) = (CalibrationConfig::DEFAULT, OdometryCalibration::new());
        for _ in 0..500 {
            cal.take(&cfg, &Motion { dx: 0.2, dy: 0.0, dphi: 0.001 }, 0.0);
            cal.end_cycle(&cfg, 0.0, 0.001, Standing::Sure);
        }
        assert_eq!(cal.estimate(), None);
    }
}
