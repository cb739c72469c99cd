//! Verdicts: one reading against its prediction (paper §5.5, DESIGN §4.6).

use crate::credence::Kappa;
use crate::predict::Prediction;

/// What one transducer read in one firing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reading {
    /// The first echo, as a range in mm.
    Echo {
        /// Range, mm.
        range_mm: u32,
    },
    /// Nothing came back within the listening window.
    NoEcho,
    /// The driver could not judge this firing (a fault, crosstalk, an
    /// untimed echo): nothing is concluded from it.
    Invalid,
}

/// How one reading compares with its prediction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Verdict {
    /// The echo is where the map says, within tolerance.
    Confirmed,
    /// An echo short of the predicted surface: something the map does not
    /// hold stands in front of it.
    UnknownObstacle,
    /// An echo beyond the predicted surface, or no echo where κ was high: the
    /// surface is gone, or the echo was missed (or the pose is off).
    RemovedOrMissed,
    /// An echo where nothing was predicted: an unmapped object.
    Unpredicted,
    /// No echo, as predicted.
    NothingAsPredicted,
    /// Nothing to conclude: no echo where κ was below the "high" mark, a
    /// prediction nearer than the module can range, an echo short of an
    /// ambiguous prediction that a nearer mapped surface may have returned
    /// ([`Prediction::nearer_mm`]), or an invalid reading.
    Inconclusive,
}

/// What the verdicts need beyond the prediction itself.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VerdictConfig {
    /// The driver's timing resolution as a range, mm (half a clock tick of
    /// round trip is ¼ tick · c; a 1 µs clock gives under 1 mm). Added to
    /// each prediction's own tolerance.
    pub timing_mm: u32,
    /// A missing echo counts against the map only when κ was at least this.
    #[cfg_attr(feature = "defmt", defmt(Debug2Format))]
    pub kappa_high: Kappa,
    /// The nearest range the module reports (blanking), mm: predictions
    /// nearer than this are not judged.
    pub min_range_mm: u32,
}

impl VerdictConfig {
    /// Defaults for a Polaroid 6500 module with a 1 µs clock: κ_high = 0.75,
    /// blanking 2.38 ms ≈ 408 mm at 20 °C.
    pub const POLAROID: Self = Self { timing_mm: 1, kappa_high: Kappa::from_bits(3 << 13), min_range_mm: 408 };
}

/// Judges `reading` against `prediction` (`None`: nothing predicted).
///
/// ```
/// use echoloc::referencing::{judge, Reading, Verdict, VerdictConfig};
/// let cfg = VerdictConfig::POLAROID;
/// assert_eq!(judge(Reading::Echo { range_mm: 1200 }, None, &cfg), Verdict::Unpredicted);
/// assert_eq!(judge(Reading::NoEcho, None, &cfg), Verdict::NothingAsPredicted);
/// ```
pub fn judge(reading: Reading, prediction: Option<&Prediction>, cfg: &VerdictConfig) -> Verdict {
    match (reading, prediction) {
        (Reading::Invalid, _) => Verdict::Inconclusive,
        (_, Some(p)) if p.range_mm < cfg.min_range_mm => Verdict::Inconclusive,
        (Reading::Echo { .. }, None) => Verdict::Unpredicted,
        (Reading::NoEcho, None) => Verdict::NothingAsPredicted,
        (Reading::Echo { range_mm }, Some(p)) => {
            let tol = p.tolerance_mm.saturating_add(cfg.timing_mm);
            if range_mm.abs_diff(p.range_mm) <= tol {
                Verdict::Confirmed
            } else if range_mm < p.range_mm {
                // From the nearer mapped surface on, the echo may be the map's own.
                if p.nearer_mm.is_some_and(|n| range_mm.saturating_add(tol) >= n) {
                    Verdict::Inconclusive
                } else {
                    Verdict::UnknownObstacle
                }
            } else {
                Verdict::RemovedOrMissed
            }
        }
        (Reading::NoEcho, Some(p)) if p.kappa >= cfg.kappa_high => Verdict::RemovedOrMissed,
        (Reading::NoEcho, Some(_)) => Verdict::Inconclusive,
    }
}

/// Verdicts counted (over one ring cycle, or a whole run).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VerdictCounts {
    /// [`Verdict::Confirmed`].
    pub confirmed: u32,
    /// [`Verdict::UnknownObstacle`].
    pub unknown_obstacle: u32,
    /// [`Verdict::RemovedOrMissed`].
    pub removed_or_missed: u32,
    /// [`Verdict::Unpredicted`].
    pub unpredicted: u32,
    /// [`Verdict::NothingAsPredicted`].
    pub nothing_as_predicted: u32,
    /// [`Verdict::Inconclusive`].
    pub inconclusive: u32,
}

impl VerdictCounts {
    /// Counts one verdict.
    pub fn add(&mut self, v: Verdict) {
        let n = match v {
            Verdict::Confirmed => &mut self.confirmed,
            Verdict::UnknownObstacle => &mut self.unknown_obstacle,
            Verdict::RemovedOrMissed => &mut self.removed_or_missed,
            Verdict::Unpredicted => &mut self.unpredicted,
            Verdict::NothingAsPredicted => &mut self.nothing_as_predicted,
            Verdict::Inconclusive => &mut self.inconclusive,
        };
        *n = n.saturating_add(1);
    }

    /// Readings judged against the map (all but the inconclusive).
    pub fn judged(&self) -> u32 {
        self.confirmed
            .saturating_add(self.unknown_obstacle)
            .saturating_add(self.removed_or_missed)
            .saturating_add(self.unpredicted)
            .saturating_add(self.nothing_as_predicted)
    }

    /// Every reading counted.
    pub fn total(&self) -> u32 {
        self.judged().saturating_add(self.inconclusive)
    }
}

impl core::ops::AddAssign for VerdictCounts {
    fn add_assign(&mut self, o: Self) {
        self.confirmed = self.confirmed.saturating_add(o.confirmed);
        self.unknown_obstacle = self.unknown_obstacle.saturating_add(o.unknown_obstacle);
        self.removed_or_missed = self.removed_or_missed.saturating_add(o.removed_or_missed);
        self.unpredicted = self.unpredicted.saturating_add(o.unpredicted);
        self.nothing_as_predicted = self.nothing_as_predicted.saturating_add(o.nothing_as_predicted);
        self.inconclusive = self.inconclusive.saturating_add(o.inconclusive);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;
    use crate::predict::Case;

    fn pred(range_mm: u32, kappa: f32) -> Prediction {
        Prediction {
            range_mm,
            kappa: Kappa::from_num(kappa),
            theta_mdeg: 0,
            delta_mdeg: 0,
            piece: 0,
            obstacle: 0,
            edge: 0,
            point: Point::new(0, 0),
            tolerance_mm: 50,
            case: Case::I,
            nearer_mm: None,
        }
    }

    #[test]
    fn every_verdict() {
        let cfg = VerdictConfig::POLAROID;
        let p = pred(2000, 0.9);
        let j = |r, p| judge(r, p, &cfg);
        // Tolerance 50 + 1 mm of timing: 51 confirms, 52 does not.
        assert_eq!(j(Reading::Echo { range_mm: 2051 }, Some(&p)), Verdict::Confirmed);
        assert_eq!(j(Reading::Echo { range_mm: 1949 }, Some(&p)), Verdict::Confirmed);
        assert_eq!(j(Reading::Echo { range_mm: 2052 }, Some(&p)), Verdict::RemovedOrMissed);
        assert_eq!(j(Reading::Echo { range_mm: 1948 }, Some(&p)), Verdict::UnknownObstacle);
        assert_eq!(j(Reading::NoEcho, Some(&p)), Verdict::RemovedOrMissed);
        let weak = pred(2000, 0.6);
        assert_eq!(j(Reading::NoEcho, Some(&weak)), Verdict::Inconclusive);
        assert_eq!(j(Reading::Echo { range_mm: 900 }, None), Verdict::Unpredicted);
        assert_eq!(j(Reading::NoEcho, None), Verdict::NothingAsPredicted);
        assert_eq!(j(Reading::Invalid, Some(&p)), Verdict::Inconclusive);
        let near = pred(300, 0.9);
        assert_eq!(j(Reading::Echo { range_mm: 300 }, Some(&near)), Verdict::Inconclusive);
        // A mapped corner at 1 400 mm in the beam: an echo from it on (less
        // the tolerance) may be the map's own; nearer still, it is not.
        let ambiguous = Prediction { nearer_mm: Some(1400), ..p };
        assert_eq!(j(Reading::Echo { range_mm: 1349 }, Some(&ambiguous)), Verdict::Inconclusive);
        assert_eq!(j(Reading::Echo { range_mm: 1700 }, Some(&ambiguous)), Verdict::Inconclusive);
        assert_eq!(j(Reading::Echo { range_mm: 1348 }, Some(&ambiguous)), Verdict::UnknownObstacle);
        assert_eq!(j(Reading::Echo { range_mm: 2000 }, Some(&ambiguous)), Verdict::Confirmed);
    }

    #[test]
    fn counts_add_up() {
        let mut c = VerdictCounts::default();
        for v in [Verdict::Confirmed, Verdict::Confirmed, Verdict::Inconclusive, Verdict::Unpredicted] {
            c.add(v);
        }
        assert_eq!((c.confirmed, c.judged(), c.total()), (2, 3, 4));
        let mut d = c;
        d += c;
        assert_eq!(d.total(), 8);
    }
}
