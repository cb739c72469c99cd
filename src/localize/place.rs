//! A place that tracks itself (DESIGN §4.8, issue #48): one hypothesis of
//! where the robot is, with its own Kalman filter corrected by every ring
//! cycle, and the evidence for it since it was born.
//!
//! The tracker's EKF predicts each reading with the exact predictor and
//! judges it by the paper's verdicts: too dear to run for every place (the
//! M4's tracking cycle is 380 k instructions). A place instead asks the
//! compiled map's field ([`super::expect`]) what a transducer there should
//! hear and, where the four nodes around it see one plane, how that range
//! changes as the transducer moves: a plane's range and its gradient, which
//! is all a range update needs. Each reading, in turn:
//!
//! 1. is scored at the place's pose before it corrects it, by the shared
//!    measurement model, *hit or null*: where the field expects an echo,
//!    the reading is that echo with probability `hit_share` (a Gaussian
//!    about the expected range, its σ the beam model's widened by the
//!    pose's own uncertainty along the gradient) and otherwise whatever
//!    the null hypothesis ([`super::null`]) says a reading is; where the
//!    field expects nothing, it is scored as the null scores it; off the
//!    field, by the beam model's off-field term. A place gains only on the
//!    echoes it predicted, and loses at most `ln(1 − hit_share)` on any
//!    other reading, so clutter costs every place and the null alike
//!    (docs/localization.md measures why: scored by the beam model's
//!    short, random and miss terms, the clutter made the null beat the
//!    truth on every run);
//! 2. adds its log-ratio over the null, clipped to `±clip` (readings of one
//!    ring are not independent), to the place's evidence;
//! 3. corrects the pose, if it is an echo the field predicts surely on a
//!    plane and more likely the hit than not: the same gated,
//!    Huber-weighted Joseph update as the tracker's
//!    ([`crate::referencing::gaussian`]), with the beam model's σ divided by
//!    the reading's responsibility (the hit's share of its likelihood).
//!
//! The cycle's odometry then carries the place, with the tracker's motion
//! noise. Two places' evidence differ by the log-ratio of the readings
//! under them (each reading's share bounded by twice the clip), and a
//! place's evidence is its log-ratio over the null: what the sequential
//! test ([`super::sprt`]) decides on.
//!
//! ```
//! use echoloc::localize::place::{Place, Tracking};
//! use echoloc::localize::{BeamModel, FieldLookup, Sensed};
//! use echoloc::map::FieldView;
//! use echoloc::referencing::{EkfConfig, Motion, Reading};
//!
//! let field = FieldView::EMPTY;
//! let lookup = FieldLookup::new(&field);
//! let cfg = EkfConfig::DEFAULT;
//! let t = Tracking { lookup: &lookup, beam: &BeamModel::DEFAULT, ekf: &cfg, clip: 2.0, hit_share: 0.5 };
//! let mut place = Place::new([1.0, 2.0, 0.0], [0.1, 0.1, 0.05], &cfg).unwrap();
//! // No field: the place stands nowhere the map allows, every reading says
//! // so (clipped), and nothing corrects it; the odometry carries it.
//! let sensed = [Sensed { pose: [0.2, 0.0, 0.0], reading: Reading::Echo { range_mm: 1500 } }];
//! let c = place.cycle(&sensed, &[-1.0], &Motion { dx: 0.5, dy: 0.0, dphi: 0.0 }, &t).unwrap();
//! assert_eq!((c.tested, c.accepted), (0, 0));
//! assert_eq!(c.evidence, -2.0);
//! assert_eq!(place.pose(), [1.5, 2.0, 0.0]);
//! ```

use super::beam::BeamModel;
use super::expect::FieldLookup;
use super::measure::Sensed;
use crate::f32math::{clamp, exp_fast, ln_fast, sqrt};
use crate::map::field::Expected;
use crate::referencing::gaussian::{in_range, Correction, PoseGaussian, M3};
use crate::referencing::{sensor_position, wrap, EkfConfig, EkfError, Motion, MountM, Reading};

/// A reading corrects a place only when it is more likely the hit than
/// the null's (its responsibility at least this), its variance divided by
/// that responsibility: clutter just inside the gate pulls less, or not at
/// all (measured on the simulator: docs/localization.md).
const RESP_MIN: f32 = 0.5;

/// What tracking a place takes: the field, the shared measurement model,
/// the filter's settings (its motion noise, gate, Huber threshold and
/// variance bounds: the tracker's), and the clip on a reading's evidence
/// (nats).
#[derive(Clone, Copy, Debug)]
pub struct Tracking<'m> {
    /// The field's lookup.
    pub lookup: &'m FieldLookup<'m, 'm>,
    /// The beam model: a reading's score, and a hit's σ for the correction.
    pub beam: &'m BeamModel,
    /// The filter's settings.
    pub ekf: &'m EkfConfig,
    /// A reading's log-ratio over the null is clipped to `±clip`.
    pub clip: f32,
    /// Where the field expects a sure echo, the share of readings that
    /// are it (a hit, the beam model's σ about the expected range); the
    /// rest are scored as the null scores them. Half of it for an unsure
    /// echo.
    pub hit_share: f32,
}

/// Why a place refused a cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlaceError {
    /// The null's scores were not one for each reading.
    Mismatch,
    /// The filter refused the pose or the odometry ([`EkfError`]).
    Filter(EkfError),
}

impl From<EkfError> for PlaceError {
    fn from(e: EkfError) -> Self {
        Self::Filter(e)
    }
}

/// What one cycle did to a place.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlaceCycle {
    /// The cycle's evidence over the null (clipped log-ratios summed).
    pub evidence: f32,
    /// Readings the gate tested ...
    pub tested: u8,
    /// ... and those it took.
    pub accepted: u8,
}

/// A place: its pose and covariance (at the current cycle's start), its
/// evidence over the null since it was born, and the cycles it has lived.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Place {
    g: PoseGaussian,
    evidence: f32,
    cycles: u16,
}

impl Place {
    /// A place at `pose` (x m, y m, φ rad) with standard deviations `sigma`,
    /// its variances within `cfg`'s bounds; no evidence yet. Refused for a
    /// non-finite, negative or out-of-range input.
    pub fn new(pose: [f32; 3], sigma: [f32; 3], cfg: &EkfConfig) -> Result<Self, EkfError> {
        if !sigma.iter().all(|v| v.is_finite()) || sigma.iter().any(|&s| s < 0.0) {
            return Err(EkfError::NotFinite);
        }
        let mut p: M3 = [[0.0; 3]; 3];
        for (i, row) in (0..3).zip(p.iter_mut()) {
            row[i] = sigma[i] * sigma[i];
        }
        Self::with_covariance(pose, p, cfg)
    }

    /// A place at `pose` with covariance `p` (the tracker's own, to score
    /// the tracked pose as a place), its variances within `cfg`'s bounds;
    /// no evidence yet. Refused for a non-finite or out-of-range input, or
    /// a negative variance.
    pub fn with_covariance(pose: [f32; 3], p: M3, cfg: &EkfConfig) -> Result<Self, EkfError> {
        if !pose.iter().chain(p.iter().flatten()).all(|v| v.is_finite())
            || p[0][0] < 0.0
            || p[1][1] < 0.0
            || p[2][2] < 0.0
        {
            return Err(EkfError::NotFinite);
        }
        if !in_range(&pose) {
            return Err(EkfError::OutOfRange);
        }
        let mut g = PoseGaussian::new([pose[0], pose[1], wrap(pose[2])], p);
        g.condition(&cfg.min_var, &cfg.max_var);
        Ok(Self { g, evidence: 0.0, cycles: 0 })
    }

    /// The pose (x m, y m, φ rad).
    pub fn pose(&self) -> [f32; 3] {
        self.g.x
    }

    /// Its covariance.
    pub fn covariance(&self) -> M3 {
        self.g.p
    }

    /// The evidence over the null since it was born, nats.
    pub fn evidence(&self) -> f32 {
        self.evidence
    }

    /// The cycles it has lived (saturating).
    pub fn cycles(&self) -> u16 {
        self.cycles
    }

    /// The place moved to `other`'s pose and covariance, its own evidence
    /// and cycles kept: the tracked place follows the EKF.
    pub(crate) fn moved_to(&mut self, other: &Place) {
        self.g = other.g;
    }

    /// The place with this evidence: for the bank's tests by hand.
    #[cfg(test)]
    pub(crate) fn with_evidence(mut self, evidence: f32) -> Self {
        self.evidence = evidence;
        self
    }

    /// One ring cycle: `sensed` (each transducer's pose relative to the
    /// cycle's start, and its reading) with `null`, the null hypothesis's
    /// log-likelihood of each reading in the same order, then the cycle's
    /// odometry `offset`. An invalid reading, or one whose null score is
    /// not finite, says nothing. Refused, the place unchanged, when `null`
    /// is not as long as `sensed`; a pose the odometry would carry out of
    /// range is refused after the readings are taken.
    pub fn cycle(
        &mut self,
        sensed: &[Sensed],
        null: &[f32],
        offset: &Motion,
        t: &Tracking<'_>,
    ) -> Result<PlaceCycle, PlaceError> {
        if null.len() != sensed.len() {
            return Err(PlaceError::Mismatch);
        }
        let Tracking { lookup, beam, ekf, clip, hit_share } = *t;
        let mut out = PlaceCycle::default();
        for (r, &n) in sensed.iter().zip(null) {
            // A null score that is not finite says nothing of the reading;
            // one below e⁻⁸⁰ is taken as that (`exp(−n)` stays finite).
            if r.reading == Reading::Invalid || !n.is_finite() {
                continue;
            }
            let n = n.max(-80.0);
            let x = self.g.x;
            let (pos, dpos) = sensor_position(&x, MountM { x: r.pose[0], y: r.pose[1] });
            let found = lookup.expected_slope(pos[0] * 1e3, pos[1] * 1e3, x[2] + r.pose[2]);
            // ∂r/∂(x, y, φ) where the field interpolates a plane.
            let hj = match found {
                Some((Expected::Echo { .. }, Some(g))) => Some([g[0], g[1], g[0] * dpos[0] + g[1] * dpos[1]]),
                _ => None,
            };
            // The reading's log-ratio over the null.
            let mut resp = 0.0;
            let ratio = match found {
                Some((Expected::Nothing, _)) => 0.0,
                Some((Expected::Echo { range_mm, sure }, _)) => {
                    let w = if sure { hit_share } else { 0.5 * hit_share };
                    let hit = match r.reading {
                        Reading::Echo { range_mm: z } if z as f32 <= beam.r_max_mm => {
                            // The hit's σ widened by the pose's uncertainty
                            // along the gradient, or across the position
                            // where none is known.
                            let var_m2 = hj.map_or(0.5 * (self.g.p[0][0] + self.g.p[1][1]), |h| self.g.spread(&h));
                            let own = beam.sigma_m(range_mm, sure);
                            let s2 = own * own + var_m2.max(0.0);
                            let d = (z as f32 - range_mm) * 1e-3;
                            exp_fast(-0.5 * d * d / s2) * (0.398_942_3 / sqrt(s2))
                        }
                        _ => 0.0,
                    };
                    // ln((w·hit + (1 − w)·null) / null).
                    let odds = w * hit * exp_fast(-n);
                    resp = odds / (1.0 - w + odds);
                    ln_fast(1.0 - w + odds)
                }
                None => ln_fast(beam.off_field) - n,
            };
            out.evidence += clamp(ratio, -clip, clip);
            let (Some(hj), Some((Expected::Echo { range_mm, sure }, _)), Reading::Echo { range_mm: z }) =
                (hj, found, r.reading)
            else {
                continue;
            };
            if z as f32 > beam.r_max_mm || !sure || resp < RESP_MIN {
                continue;
            }
            let sigma_m = beam.sigma_m(range_mm, sure);
            let c =
                self.g.correct((z as f32 - range_mm) * 1e-3, hj, sigma_m * sigma_m / resp, ekf.gate, ekf.robust_nis);
            if !matches!(c, Correction::Unusable) {
                out.tested = out.tested.saturating_add(1);
            }
            if let Correction::Accepted { .. } = c {
                out.accepted = out.accepted.saturating_add(1);
                self.g.condition(&ekf.min_var, &ekf.max_var);
            }
        }
        self.evidence += out.evidence;
        self.cycles = self.cycles.saturating_add(1);
        if offset.is_finite() {
            self.g.propagate(offset, ekf.motion_noise(offset))?;
            self.g.condition(&ekf.min_var, &ekf.max_var);
        } else {
            return Err(PlaceError::Filter(EkfError::NotFinite));
        }
        Ok(out)
    }
}
