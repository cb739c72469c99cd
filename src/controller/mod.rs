//! The sonar controller's loop: the ring driver's readings and the robot's
//! odometry in, a corrected pose out, one reading at a time.
//!
//! | file | what it does |
//! |---|---|
//! | this one | [`Controller`]: a ring reading and the odometry up to it through prediction, verdict and the EKF, with per-cycle counts |
//! | [`odometry`] | [`OdometrySync`]: the robot's cumulative odometry, as it arrives from the main computer, turned into the increment up to each reading's time |
//! | [`replay`] | a scenario through the real ring driver (over the scenario's replay bench) and the controller, scored against its truth |
//!
//! The same code runs on every board and in the host tests: a board owns
//! the driver and the link, and calls [`Controller::step`] with each
//! [`RingReading`] the driver returns.
//!
//! What the driver's outcomes become:
//!
//! | driver outcome | judged as |
//! |---|---|
//! | `Range`, `Unconfirmed`, `Crosstalk` | an echo at its range (the verdict and the EKF's gate judge it against the map; EERUF's opinion is passed on to the caller, not used to drop it) |
//! | `NoEcho` | no echo |
//! | `Untimed`, `Fault` | [`Reading::Invalid`]: something came back but its time is unknown, or the module misbehaved; predicted, judged inconclusive, never fed to the filter; counted in [`LoopCounts::invalid`] |

pub mod odometry;
pub mod replay;

pub use odometry::{OdometryError, OdometrySample, OdometrySync};

use crate::credence::Credence;
use crate::driver::{Outcome, RingReading};
use crate::localize::{self, LocalizeError, Localizer, Mode, Start};
use crate::map::{FieldView, MapSource};
use crate::predict::{Mount, PredictParams};
use crate::referencing::{CycleUpdates, Motion, Reading, ReadingReport, Referencer, ReferencerError, VerdictCounts};

/// Why a reading could not be processed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControllerError {
    /// The driver reported a transducer the controller has no mount for.
    NoSuchTransducer(u8),
    /// Prediction or the filter refused.
    Referencer(ReferencerError),
    /// The localizer refused (non-finite odometry, a start outside the map).
    Localize(LocalizeError),
}

impl From<ReferencerError> for ControllerError {
    fn from(e: ReferencerError) -> Self {
        Self::Referencer(e)
    }
}

impl From<LocalizeError> for ControllerError {
    fn from(e: LocalizeError) -> Self {
        match e {
            LocalizeError::Referencer(r) => Self::Referencer(r),
            e => Self::Localize(e),
        }
    }
}

impl core::fmt::Display for ControllerError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NoSuchTransducer(t) => write!(f, "no mount for transducer {t}"),
            Self::Referencer(e) => write!(f, "{e:?}"),
            Self::Localize(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for ControllerError {}

/// A finished ring cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleEnd {
    /// Which cycle.
    pub cycle: u32,
    /// Its verdicts.
    pub verdicts: VerdictCounts,
    /// What the EKF's gate did with its readings.
    pub updates: CycleUpdates,
    /// What the localizer did: its mode in that cycle, the particles, a
    /// hand-off or a wake-up.
    pub localizer: localize::CycleReport,
}

/// What one ring reading became.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Step {
    /// The previous cycle, if this reading started a new one.
    pub cycle_end: Option<CycleEnd>,
    /// What was judged.
    pub reading: Reading,
    /// Prediction, verdict, target and the filter's update.
    pub report: ReadingReport,
}

/// Counts over the run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopCounts {
    /// Ring readings processed.
    pub readings: u32,
    /// Echoes judged.
    pub echoes: u32,
    /// Of them, echoes EERUF had not confirmed (`Unconfirmed`, `Crosstalk`).
    pub unconfirmed: u32,
    /// "No echo" judged.
    pub no_echo: u32,
    /// Untimed echoes and faults, judged [`Reading::Invalid`].
    pub invalid: u32,
    /// Cycles finished.
    pub cycles: u32,
}

/// The reading a driver outcome stands for.
pub const fn reading_of(outcome: &Outcome) -> Reading {
    match *outcome {
        Outcome::Range { range_mm, .. }
        | Outcome::Unconfirmed { range_mm, .. }
        | Outcome::Crosstalk { range_mm, .. } => Reading::Echo { range_mm },
        Outcome::NoEcho => Reading::NoEcho,
        Outcome::Untimed { .. } | Outcome::Fault(_) => Reading::Invalid,
    }
}

/// The loop's state: the map and its localization field, the ring's
/// mounts, the credence, and the [`Localizer`] (EKF, verdicts and `N`
/// particles; `N = 0`: the EKF alone) it drives.
#[derive(Debug)]
pub struct Controller<'a, M: ?Sized, K: ?Sized, const N: usize = 0> {
    map: &'a M,
    field: &'a FieldView<'a>,
    mounts: &'a [Mount],
    params: PredictParams,
    credence: &'a K,
    localizer: &'a mut Localizer<N>,
    cycle: Option<u32>,
    counts: LoopCounts,
}

impl<'a, M: MapSource + ?Sized, K: Credence + ?Sized, const N: usize> Controller<'a, M, K, N> {
    /// A controller over `map` (whose localization field is `field`) for a
    /// ring whose transducer `i` sits at `mounts[i]`, localizing with
    /// `localizer` (started as its holder chose; the holder keeps it, as a
    /// board keeps it in one place: 21 KiB at 1 024 particles).
    pub fn new(
        map: &'a M,
        field: &'a FieldView<'a>,
        mounts: &'a [Mount],
        params: PredictParams,
        credence: &'a K,
        localizer: &'a mut Localizer<N>,
    ) -> Self {
        Self { map, field, mounts, params, credence, localizer, cycle: None, counts: LoopCounts::default() }
    }

    /// One ring reading, with the odometry `u` since the previous one (in
    /// the robot's frame at the previous reading). In this order: the
    /// previous cycle is closed if `r` starts a new one (the EKF's lost
    /// monitor runs there), the odometry is applied, then the reading is
    /// predicted at the estimate, judged and fed to the filter.
    pub fn step(&mut self, u: &Motion, r: &RingReading) -> Result<Step, ControllerError> {
        let mount =
            self.mounts.get(usize::from(r.transducer)).ok_or(ControllerError::NoSuchTransducer(r.transducer))?;
        let cycle_end = match self.cycle {
            Some(c) if c != r.cycle => self.close_cycle(c)?,
            _ => None,
        };
        self.cycle = Some(r.cycle);
        self.localizer.odometry(u)?;
        self.counts.readings = self.counts.readings.saturating_add(1);
        let reading = reading_of(&r.outcome);
        match reading {
            Reading::Echo { .. } => self.counts.echoes = self.counts.echoes.saturating_add(1),
            Reading::NoEcho => self.counts.no_echo = self.counts.no_echo.saturating_add(1),
            Reading::Invalid => self.counts.invalid = self.counts.invalid.saturating_add(1),
        }
        if matches!(r.outcome, Outcome::Unconfirmed { .. } | Outcome::Crosstalk { .. }) {
            self.counts.unconfirmed = self.counts.unconfirmed.saturating_add(1);
        }
        let report = self.localizer.reading(self.map, mount, &self.params, self.credence, reading)?;
        Ok(Step { cycle_end, reading, report })
    }

    /// Starts localizing again from `start` (a pose the robot's computer
    /// sent, or a search); the cycle in progress and the counts go on.
    pub fn restart(&mut self, start: Start) -> Result<(), ControllerError> {
        Ok(self.localizer.start(start, self.field)?)
    }

    /// Closes the cycle in progress (at the end of a run).
    pub fn finish(&mut self) -> Result<Option<CycleEnd>, ControllerError> {
        match self.cycle.take() {
            Some(c) => self.close_cycle(c),
            None => Ok(None),
        }
    }

    fn close_cycle(&mut self, cycle: u32) -> Result<Option<CycleEnd>, ControllerError> {
        let localizer = self.localizer.end_cycle(self.field)?;
        self.counts.cycles = self.counts.cycles.saturating_add(1);
        Ok(Some(CycleEnd { cycle, verdicts: localizer.verdicts, updates: localizer.updates, localizer }))
    }

    /// The estimate: x, y (m), φ (rad).
    pub fn state(&self) -> [f32; 3] {
        self.localizer.state()
    }

    /// Its covariance.
    pub fn covariance(&self) -> [[f32; 3]; 3] {
        self.localizer.covariance()
    }

    /// What the localizer is doing.
    pub fn mode(&self) -> Mode {
        self.localizer.mode()
    }

    /// Whether the localizer does not know where the robot is (lost, or
    /// searching).
    pub fn is_lost(&self) -> bool {
        self.localizer.mode() != Mode::Tracking
    }

    /// The EKF and its verdict counts.
    pub fn referencer(&self) -> &Referencer {
        self.localizer.referencer()
    }

    /// The localizer.
    pub fn localizer(&self) -> &Localizer<N> {
        self.localizer
    }

    /// Counts over the run.
    pub fn counts(&self) -> LoopCounts {
        self.counts
    }

    /// The ring's mounts.
    pub fn mounts(&self) -> &'a [Mount] {
        self.mounts
    }
}
