//! An extended Kalman filter over the robot's pose (x, y, φ): odometry
//! prediction, sequential range updates on plane and point targets, a χ²
//! validation gate, κ-weighted measurement variance, the Joseph-form
//! covariance update, and a *lost* state (DESIGN §4.6).
//!
//! Fixed memory (a 3-vector and a 3×3 matrix), no allocation, `f32`.
//!
//! ```
//! use echoloc::referencing::{Ekf, EkfConfig, Motion, MountM, Target, Update};
//! let mut ekf = Ekf::new([0.0, 0.0, 0.0], [0.05, 0.05, 0.02], EkfConfig::DEFAULT).unwrap();
//! ekf.predict(&Motion { dx: 1.0, dy: 0.0, dphi: 0.0 }).unwrap();
//! // A wall 3 m ahead of the start; the forward transducer reads 2.02 m.
//! let wall = Target::Plane { point: [3.0, 0.0], normal: [-1.0, 0.0] };
//! let u = ekf.update(2.02, 1.0, MountM { x: 0.0, y: 0.0 }, &wall);
//! assert!(matches!(u, Update::Accepted { .. }));
//! assert!(ekf.state()[0] < 1.0); // the reading says the robot is short of 1 m
//! ```

use super::calibration::{CalibrationConfig, OdometryCalibration, Standing};
use super::gaussian::{in_range, Correction, PoseGaussian};
pub use super::gaussian::{EkfError, MAX_POSITION_M};
use super::model::{range_model, wrap, Motion, MountM, Target};
use super::recovery::{Found, Recent, RecoveryConfig};
use crate::f32math::sqrt;

/// Filter settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EkfConfig {
    /// Variance of the distance travelled, m² per metre.
    pub var_per_m: f32,
    /// Variance of the sideways slip, m² per metre.
    pub var_side_per_m: f32,
    /// Variance of the heading, rad² per radian turned.
    pub var_heading_per_rad: f32,
    /// Variance of the heading, rad² per metre travelled (wheelbase and
    /// wheel-radius errors turn the robot as it drives).
    pub var_heading_per_m: f32,
    /// Range standard deviation of a reading with κ = 1, m.
    pub sigma_range_m: f32,
    /// σ² = σ₀² / max(κ, κ_floor).
    pub kappa_floor: f32,
    /// A point target's variance is this many times a plane's: the echo of
    /// a corner or a clipped edge end comes from near the point, not from it.
    pub point_variance_scale: f32,
    /// χ² gate for one degree of freedom (6.63: 99 %).
    pub gate: f32,
    /// Huber's threshold on the normalised innovation ν²/S (2.5: 1.6 σ;
    /// `INFINITY` turns it off). A reading the gate passes beyond it is
    /// weighted down: its variance grows until ν²/S is this, so it moves the
    /// state by `robust_nis / (ν²/S)` of a full update and shrinks the
    /// covariance less. One clutter reading just inside the gate then cannot
    /// pull the pose far and collapse the covariance around the wrong place
    /// (docs/self-referencing.md measures it).
    pub robust_nis: f32,
    /// A reading the verdict does not confirm at the estimate (its echo
    /// outside the prediction's tolerance, a few centimetres) enters with
    /// its variance this many times larger ([`Ekf::update_unconfirmed`];
    /// 1: as a confirmed one). The gate widens with the covariance and the
    /// tolerance does not: after a turn or a stretch of few echoes the gate
    /// passes clutter by the metre, and such an echo at full weight moved
    /// the estimate onto the wrong surface and shrank the covariance there
    /// (a dense lab: a third of the accepted readings, the filter worse
    /// than the odometry on 6 of 10 runs; docs/real-buildings.md). Weighted
    /// down, not refused: a filter a little off confirms nothing, and must
    /// still be pulled back. Default 16 (σ × 4; 4 and 8 were too little,
    /// 64 sent a depot run 0.5 m off); 1 turns it off. The lost monitor judges
    /// cycles at the plain variance ([`CycleUpdates::weak`]), so the weak
    /// readings cannot keep a wrong filter found (issue #49).
    pub unconfirmed_variance_scale: f32,
    /// The smallest variance kept on the diagonal, so the covariance stays
    /// positive definite in `f32`.
    pub min_var: [f32; 3],
    /// The largest variance on the diagonal: beyond it the filter knows
    /// nothing and stops growing.
    pub max_var: [f32; 3],
    /// Lost: a cycle is *bad* when at least this many readings were tested
    /// by the gate ...
    pub lost_min_tested: u16,
    /// ... and no more than this fraction of them passed ...
    pub lost_max_accepted: f32,
    /// ... while the position standard deviation is below this, m ...
    pub lost_max_sigma_m: f32,
    /// ... for this many consecutive cycles. A cycle is bad too when the
    /// gate's recent acceptance rate (a fast average, weight
    /// `lost_rate_fast` per cycle) falls below `lost_rate_drop` times its
    /// long-run rate (a slow average, weight `lost_rate_slow`, frozen while
    /// cycles are bad): a kidnapped robot whose wrong pose still agrees with
    /// a few readings, in a place where most used to validate. (Augmented
    /// MCL's short- and long-term likelihood averages, on the gate's counts.)
    pub lost_cycles: u16,
    /// Weight of a cycle in the long-run acceptance rate.
    pub lost_rate_slow: f32,
    /// Weight of a cycle in the recent acceptance rate.
    pub lost_rate_fast: f32,
    /// The recent rate below this fraction of the long-run rate makes a bad
    /// cycle (0: off) ...
    pub lost_rate_drop: f32,
    /// ... when it is also this much below it (clutter that comes and goes
    /// moves a low long-run rate by less).
    pub lost_rate_margin: f32,
    /// A lost filter's covariance grows by this factor each cycle, so the
    /// gate widens until readings validate again (1: off; odometry alone
    /// still grows it as the robot moves).
    pub lost_inflation: f32,
    /// While lost, the pose correction the last readings agree on is
    /// looked for and taken ([`super::recovery`]; `RecoveryConfig::OFF`:
    /// never).
    pub recovery: RecoveryConfig,
    /// The odometry's systematic heading errors learned from the filter's
    /// corrections and taken out of each step ([`super::calibration`];
    /// `CalibrationConfig::OFF`: never).
    pub calibration: CalibrationConfig,
}

impl EkfConfig {
    /// Settings for a Pioneer-class robot and a Polaroid ring, checked in
    /// the simulator (docs/self-referencing.md): distance 2 cm/√m, sideways
    /// 1 cm/√m, heading 0.57°/√rad turned and 0.57°/√m driven; 15 mm range
    /// noise at κ = 1, point targets at twice that; the gate at 99 %; lost
    /// after 5 cycles in which at least 6 readings were tested and at most
    /// 10 % passed, or the recent acceptance rate (weight 0.3) fell below
    /// half the long-run rate (weight 0.02), while σ < 0.5 m; no inflation
    /// while lost (it let clutter through the widened gate in the simulator).
    pub const DEFAULT: Self = Self {
        var_per_m: 4e-4,
        var_side_per_m: 1e-4,
        var_heading_per_rad: 1e-4,
        var_heading_per_m: 1e-4,
        sigma_range_m: 0.015,
        kappa_floor: 0.1,
        point_variance_scale: 4.0,
        gate: 6.63,
        robust_nis: 2.5,
        unconfirmed_variance_scale: 16.0,
        min_var: [1e-8, 1e-8, 1e-9],
        max_var: [100.0, 100.0, 10.0],
        lost_min_tested: 6,
        lost_max_accepted: 0.1,
        lost_max_sigma_m: 0.5,
        lost_cycles: 5,
        lost_rate_slow: 0.005,
        lost_rate_fast: 0.1,
        lost_rate_drop: 0.5,
        lost_rate_margin: 0.25,
        lost_inflation: 1.0,
        recovery: RecoveryConfig::DEFAULT,
        calibration: CalibrationConfig::DEFAULT,
    };

    /// The motion noise of `u` (forward m², sideways m², heading rad², in
    /// the robot's frame): the variances per metre driven and per radian
    /// turned.
    pub fn motion_noise(&self, u: &Motion) -> [f32; 3] {
        let d = sqrt(u.dx * u.dx + u.dy * u.dy);
        let turn = libm::fabsf(u.dphi);
        [self.var_per_m * d, self.var_side_per_m * d, self.var_heading_per_rad * turn + self.var_heading_per_m * d]
    }
}

/// What one range update did.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Update {
    /// It passed the gate and corrected the state.
    Accepted {
        /// Innovation z − h, m.
        innovation: f32,
        /// Its normalised square ν²/S.
        nis: f32,
    },
    /// The gate rejected it: the state is unchanged.
    Gated {
        /// Innovation z − h, m.
        innovation: f32,
        /// Its normalised square ν²/S.
        nis: f32,
    },
    /// Not usable: a non-finite range or κ, or a degenerate model.
    Unusable,
}

/// Counts of one ring cycle's updates and what the lost monitor made of them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleUpdates {
    /// Readings the gate tested.
    pub tested: u16,
    /// Readings it accepted.
    pub accepted: u16,
    /// Of those accepted, the ones only their scaled variance let in
    /// ([`Ekf::update_unconfirmed`]): the plain gate would have refused
    /// them, so the lost monitor does not count them as validating.
    pub weak: u16,
}

impl CycleUpdates {
    /// The readings the plain gate would have accepted: what the lost
    /// monitor judges the cycle by.
    pub fn validated(&self) -> u16 {
        self.accepted.saturating_sub(self.weak)
    }
}

/// The filter.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ekf {
    g: PoseGaussian,
    cfg: EkfConfig,
    cycle: CycleUpdates,
    bad_run: u16,
    /// Acceptance rates of tested cycles: long-run and recent.
    rates: (f32, f32),
    /// Tested cycles the rates have seen (saturating): until a rate's
    /// weight is reached it is the plain mean, so neither starts biased.
    rated: u16,
    lost: bool,
    lost_count: u32,
    cycles_lost: u32,
    /// The last readings, for recovery.
    recent: Recent,
    recoveries: u32,
    last_recovery: Option<Found>,
    calibration: OdometryCalibration,
}

impl Ekf {
    /// A filter at pose `x` (m, m, rad) with standard deviations `sigma`.
    // Inlined so the caller builds the filter where it keeps it: out of
    // line, the returned `Result` was unpacked through two stack
    // temporaries of the filter's size (the board's loop: 8 632 → 5 984 B
    // of stack, for 520 B of flash; docs/benchmarks.md).
    #[inline]
    pub fn new(x: [f32; 3], sigma: [f32; 3], cfg: EkfConfig) -> Result<Self, EkfError> {
        if !x.iter().chain(sigma.iter()).all(|v| v.is_finite()) || sigma.iter().any(|&s| s < 0.0) {
            return Err(EkfError::NotFinite);
        }
        if !in_range(&x) {
            return Err(EkfError::OutOfRange);
        }
        let mut e = Self::origin(cfg);
        for (i, (row, s)) in e.g.p.iter_mut().zip(sigma).enumerate() {
            row[i] = crate::f32math::clamp(s * s, cfg.min_var[i], cfg.max_var[i]);
        }
        e.g.x = [x[0], x[1], wrap(x[2])];
        Ok(e)
    }

    /// Restarts the filter at `x` with covariance `p` (a relocalisation:
    /// the particles' hand-off, or a pose the robot's computer sent). Its
    /// settings, its odometry calibration (a constant of the robot) and its
    /// counts stay; the lost state, the bad-cycle run, the cycle's counts
    /// and the recovery's readings (taken about the old estimate) go.
    /// Refused, the filter left as it was, for a non-finite or out-of-range
    /// pose or a non-finite covariance.
    pub fn relocate(&mut self, x: [f32; 3], p: [[f32; 3]; 3]) -> Result<(), EkfError> {
        if !x.iter().chain(p.iter().flatten()).all(|v| v.is_finite()) {
            return Err(EkfError::NotFinite);
        }
        if !in_range(&x) {
            return Err(EkfError::OutOfRange);
        }
        self.g.x = [x[0], x[1], wrap(x[2])];
        self.g.p = p;
        self.cycle = CycleUpdates::default();
        self.bad_run = 0;
        self.lost = false;
        self.recent.clear();
        self.condition();
        Ok(())
    }

    /// [`Ekf::relocate`] with standard deviations `sigma` (m, m, rad) and
    /// no correlation.
    pub fn relocate_diagonal(&mut self, x: [f32; 3], sigma: [f32; 3]) -> Result<(), EkfError> {
        if !sigma.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(EkfError::NotFinite);
        }
        let mut p = [[0.0; 3]; 3];
        for (i, row) in p.iter_mut().enumerate() {
            row[i] = sigma[i] * sigma[i];
        }
        self.relocate(x, p)
    }

    /// A filter at the origin with unit standard deviations, to be
    /// [relocated](Ekf::relocate) where the robot is: infallible, so a
    /// holder of one (the localizer) is built in place.
    #[inline]
    pub fn origin(cfg: EkfConfig) -> Self {
        let mut p = [[0.0; 3]; 3];
        for (i, row) in p.iter_mut().enumerate() {
            row[i] = crate::f32math::clamp(1.0, cfg.min_var[i], cfg.max_var[i]);
        }
        Self {
            g: PoseGaussian::new([0.0; 3], p),
            cfg,
            cycle: CycleUpdates::default(),
            bad_run: 0,
            rates: (0.0, 0.0),
            rated: 0,
            lost: false,
            lost_count: 0,
            cycles_lost: 0,
            recent: Recent::new(),
            recoveries: 0,
            last_recovery: None,
            calibration: OdometryCalibration::new(),
        }
    }

    /// The state (x m, y m, φ rad).
    pub fn state(&self) -> [f32; 3] {
        self.g.x
    }

    /// The covariance.
    pub fn covariance(&self) -> [[f32; 3]; 3] {
        self.g.p
    }

    /// The settings.
    pub fn config(&self) -> &EkfConfig {
        &self.cfg
    }

    /// Odometry prediction: `x ← x ⊕ u`, `P ← F P Fᵀ + G Q Gᵀ` with Q from
    /// the distance travelled and the angle turned.
    pub fn predict(&mut self, u: &Motion) -> Result<(), EkfError> {
        if !u.is_finite() {
            return Err(EkfError::NotFinite);
        }
        let raw = u;
        let u = &self.calibration.corrected(raw);
        let q = self.cfg.motion_noise(u);
        let heading = self.g.x[2];
        let (a, b) = self.g.propagate(u, q)?;
        self.calibration.take(&self.cfg.calibration, raw, heading);
        self.recent.carry(a, b);
        self.condition();
        Ok(())
    }

    /// One range reading `z` (m) with credence `kappa` of `target`, seen by
    /// the transducer at `mount`: gated, then a sequential scalar update.
    pub fn update(&mut self, z: f32, kappa: f32, mount: MountM, target: &Target) -> Update {
        self.update_scaled(z, kappa, 1.0, mount, target)
    }

    /// [`Ekf::update`] for a reading the verdict did not confirm: its
    /// variance times [`EkfConfig::unconfirmed_variance_scale`], in the
    /// gate as in the correction (gated at the plain variance instead, the
    /// dense lab and the depot both did worse, docs/real-buildings.md): an
    /// echo a decimetre or two off is weak evidence, not none.
    pub fn update_unconfirmed(&mut self, z: f32, kappa: f32, mount: MountM, target: &Target) -> Update {
        self.update_scaled(z, kappa, self.cfg.unconfirmed_variance_scale, mount, target)
    }

    fn update_scaled(&mut self, z: f32, kappa: f32, scale: f32, mount: MountM, target: &Target) -> Update {
        if !(z.is_finite() && kappa.is_finite()) {
            return Update::Unusable;
        }
        let Some((h, hj)) = range_model(&self.g.x, mount, target) else { return Update::Unusable };
        let mut s2 = self.cfg.sigma_range_m * self.cfg.sigma_range_m / kappa.max(self.cfg.kappa_floor);
        if let Target::Point { .. } = target {
            s2 *= self.cfg.point_variance_scale;
        }
        // The recovery's record takes the reading at the variance it entered with.
        s2 *= scale;
        let nu = z - h;
        let c = self.g.correct(nu, hj, s2, self.cfg.gate, self.cfg.robust_nis);
        if c == Correction::Unusable {
            return Update::Unusable;
        }
        self.cycle.tested = self.cycle.tested.saturating_add(1);
        self.recent.push(hj, nu, s2);
        match c {
            Correction::Accepted { nis, dx, spread } => {
                self.cycle.accepted = self.cycle.accepted.saturating_add(1);
                // The plain gate's verdict, for the lost monitor: S at the
                // plain variance. NaN (S not positive) counts as weak.
                if scale > 1.0 {
                    let plain_nis = nu * nu / (spread + s2 / scale);
                    if plain_nis.is_nan() || plain_nis > self.cfg.gate {
                        self.cycle.weak = self.cycle.weak.saturating_add(1);
                    }
                }
                self.recent.shift(dx);
                self.condition();
                Update::Accepted { innovation: nu, nis }
            }
            Correction::Gated { nis } => Update::Gated { innovation: nu, nis },
            // Overflow on absurd inputs: the reading refused, the filter kept.
            Correction::Refused { .. } | Correction::Unusable => Update::Unusable,
        }
    }

    /// Ends a ring cycle: the lost monitor looks at the cycle's gate counts.
    /// Returns them.
    pub fn end_cycle(&mut self) -> CycleUpdates {
        self.recent.rebase();
        let c = self.cycle;
        self.cycle = CycleUpdates::default();
        let sigma = sqrt(self.g.p[0][0] + self.g.p[1][1]);
        let tested = c.tested >= self.cfg.lost_min_tested;
        let validated = c.validated();
        let frac = if c.tested == 0 { 0.0 } else { validated as f32 / c.tested as f32 };
        let mut dropped = false;
        if tested {
            let (slow, fast) = self.rates;
            self.rated = self.rated.saturating_add(1);
            let mean = 1.0 / self.rated as f32;
            let fast = fast + self.cfg.lost_rate_fast.max(mean) * (frac - fast);
            dropped = fast < self.cfg.lost_rate_drop * slow && slow - fast >= self.cfg.lost_rate_margin;
            // The long-run rate learns only from good cycles, so a lasting
            // fault cannot become the new normal.
            let slow = if dropped || self.bad_run > 0 || self.lost {
                slow
            } else {
                slow + self.cfg.lost_rate_slow.max(mean) * (frac - slow)
            };
            self.rates = (slow, fast);
        }
        let bad = frac <= self.cfg.lost_max_accepted || dropped;
        if tested && bad && (self.lost || sigma < self.cfg.lost_max_sigma_m) {
            self.bad_run = self.bad_run.saturating_add(1);
        } else if tested || validated > 0 {
            // Readings validate again (or the filter is unsure enough that
            // rejections are expected): not lost.
            self.bad_run = 0;
            if self.lost && validated >= 2 {
                self.lost = false;
            }
        }
        if !self.lost && self.bad_run >= self.cfg.lost_cycles {
            self.lost = true;
            self.lost_count = self.lost_count.saturating_add(1);
        }
        if self.lost {
            self.recover();
        }
        if self.lost {
            self.cycles_lost = self.cycles_lost.saturating_add(1);
            let f = self.cfg.lost_inflation;
            for row in self.g.p.iter_mut() {
                for v in row.iter_mut() {
                    *v *= f;
                }
            }
            self.condition();
        }
        let standing = match (self.lost, self.bad_run) {
            (true, _) => Standing::Lost,
            (false, 0) => Standing::Sure,
            (false, _) => Standing::Doubtful,
        };
        self.calibration.end_cycle(&self.cfg.calibration, self.g.x[2], sqrt(self.g.p[2][2]), standing);
        c
    }

    /// The odometry calibration ([`super::calibration`]).
    pub fn calibration(&self) -> &OdometryCalibration {
        &self.calibration
    }

    /// Looks for the correction the last readings agree on and takes it:
    /// the state moves, the covariance becomes what those readings fix
    /// (but no tighter than the search's grid), and the readings follow.
    /// Not inlined: its search's frame is on the stack only while lost.
    #[inline(never)]
    fn recover(&mut self) {
        let Some(found) = self.recent.search(&self.cfg.recovery) else { return };
        let mut next = self.g.x;
        for (xi, d) in next.iter_mut().zip(found.dx) {
            *xi += d;
        }
        next[2] = wrap(next[2]);
        if !in_range(&next) {
            return;
        }
        let g = &self.cfg.recovery;
        let floor = [g.step_m * g.step_m, g.step_m * g.step_m, g.step_rad * g.step_rad];
        let mut p = [[0.0f32; 3]; 3];
        for i in 0..3 {
            p[i][i] = found.covariance[i][i].max(floor[i]);
        }
        self.g.x = next;
        self.g.p = p;
        self.recent.shift(found.dx);
        self.recoveries = self.recoveries.saturating_add(1);
        self.last_recovery = Some(found);
        self.bad_run = 0;
        self.condition();
    }

    /// How many times a lost filter took a recovered pose.
    pub fn recoveries(&self) -> u32 {
        self.recoveries
    }

    /// The last correction a recovery took.
    pub fn last_recovery(&self) -> Option<Found> {
        self.last_recovery
    }

    /// Whether the filter is lost now.
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    /// How many times it became lost.
    pub fn lost_count(&self) -> u32 {
        self.lost_count
    }

    /// How many cycles it ended lost.
    pub fn cycles_lost(&self) -> u32 {
        self.cycles_lost
    }

    /// Symmetric, diagonal within its bounds, and every correlation below 1,
    /// so P stays positive definite in `f32`.
    fn condition(&mut self) {
        self.g.condition(&self.cfg.min_var, &self.cfg.max_var);
    }
}
