//! The messages, version [`PROTOCOL_VERSION`]: plain serde types with their
//! own wire enums, so the wire format changes only when this file does (and
//! the version with it), never because an internal type moved.

use serde::{Deserialize, Serialize};

use crate::controller::{CycleEnd, Step};
use crate::driver::{Outcome, RingReading};
use crate::localize::Mode;
use crate::referencing::{Update, Verdict};

/// The protocol version, the first byte of every frame's payload. 2 since
/// the localizer's mode replaced the lost flag (issue #27), 3 since a
/// cycle says the place test's standing (issue #48; `docs/link.md`).
pub const PROTOCOL_VERSION: u8 = 3;

/// From the robot's computer to the controller.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ToController {
    /// The robot's cumulative odometry pose at a time on the controller's
    /// clock (as its [`Hello`](FromController::Hello) and readings report it).
    Odometry {
        /// Controller clock, µs (wrapping).
        time_us: u32,
        /// x, m, in the odometry frame.
        x: f32,
        /// y, m.
        y: f32,
        /// θ, rad.
        theta: f32,
    },
    /// Where the robot is: the filter restarts there, with these standard
    /// deviations (the map's frame, m and rad).
    SetPose {
        /// x, y (m), φ (rad).
        pose: [f32; 3],
        /// Standard deviations of x, y and φ.
        sigma: [f32; 3],
    },
    /// Find the robot: the particles search all free space (`around:
    /// None`), or around a pose with its standard deviations.
    Search {
        /// The pose (x, y m, φ rad) and its standard deviations, if any.
        around: Option<([f32; 3], [f32; 3])>,
    },
    /// No more odometry will come: finish and report.
    End,
}

/// What the driver made of one firing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireOutcome {
    /// An echo EERUF confirmed (or any echo with EERUF off), mm.
    Range(u32),
    /// An echo with nothing to confirm it yet, mm.
    Unconfirmed(u32),
    /// An echo that disagrees with the previous reading, mm.
    Crosstalk(u32),
    /// Nothing within the maximum range.
    NoEcho,
    /// An echo too late to time.
    Untimed,
    /// The module misbehaved.
    Fault,
}

impl From<&Outcome> for WireOutcome {
    fn from(o: &Outcome) -> Self {
        match *o {
            Outcome::Range { range_mm, .. } => Self::Range(range_mm),
            Outcome::Unconfirmed { range_mm, .. } => Self::Unconfirmed(range_mm),
            Outcome::Crosstalk { range_mm, .. } => Self::Crosstalk(range_mm),
            Outcome::NoEcho => Self::NoEcho,
            Outcome::Untimed { .. } => Self::Untimed,
            Outcome::Fault(_) => Self::Fault,
        }
    }
}

/// The verdict on one reading (`referencing::Verdict`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireVerdict {
    /// Where the map says.
    Confirmed,
    /// Short of the predicted surface.
    UnknownObstacle,
    /// Beyond it, or missed.
    RemovedOrMissed,
    /// An echo where nothing was predicted.
    Unpredicted,
    /// No echo, as predicted.
    NothingAsPredicted,
    /// Nothing to conclude.
    Inconclusive,
}

impl From<Verdict> for WireVerdict {
    fn from(v: Verdict) -> Self {
        match v {
            Verdict::Confirmed => Self::Confirmed,
            Verdict::UnknownObstacle => Self::UnknownObstacle,
            Verdict::RemovedOrMissed => Self::RemovedOrMissed,
            Verdict::Unpredicted => Self::Unpredicted,
            Verdict::NothingAsPredicted => Self::NothingAsPredicted,
            Verdict::Inconclusive => Self::Inconclusive,
        }
    }
}

/// What the filter did with a reading.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireUpdate {
    /// Not fed to the filter (no echo, nothing predicted, inconclusive).
    None,
    /// Passed the gate and corrected the pose.
    Accepted,
    /// Rejected by the gate.
    Gated,
    /// Unusable (degenerate model).
    Unusable,
}

impl From<Option<Update>> for WireUpdate {
    fn from(u: Option<Update>) -> Self {
        match u {
            None => Self::None,
            Some(Update::Accepted { .. }) => Self::Accepted,
            Some(Update::Gated { .. }) => Self::Gated,
            Some(Update::Unusable) => Self::Unusable,
        }
    }
}

/// What the localizer is doing (`localize::Mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireMode {
    /// The particles search; the pose is not known.
    Searching,
    /// The EKF tracks.
    Tracking,
    /// The EKF says it is lost.
    Lost,
}

impl From<Mode> for WireMode {
    fn from(m: Mode) -> Self {
        match m {
            Mode::Searching => Self::Searching,
            Mode::Tracking => Self::Tracking,
            Mode::Lost => Self::Lost,
        }
    }
}

/// One reading and the estimate after it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReadingReport {
    /// Controller clock when the transducer fired, µs.
    pub time_us: u32,
    /// Ring cycle.
    pub cycle: u32,
    /// Transducer.
    pub transducer: u8,
    /// What the driver found.
    pub outcome: WireOutcome,
    /// The predicted range, mm, if anything credible was predicted.
    pub predicted_mm: Option<u32>,
    /// Its credence κ, 0..1 (0 without a prediction).
    pub kappa: f32,
    /// The verdict.
    pub verdict: WireVerdict,
    /// What the filter did.
    pub update: WireUpdate,
    /// The estimate after the reading: x, y (m), φ (rad).
    pub pose: [f32; 3],
    /// Its covariance, upper triangle: xx, xy, xφ, yy, yφ, φφ.
    pub covariance: [f32; 6],
    /// What the localizer is doing (version 1 had a lost flag here).
    pub mode: WireMode,
}

impl ReadingReport {
    /// The report of `step` for ring reading `r`, with the estimate `pose`,
    /// covariance `p` and the localizer's mode after it.
    pub fn new(r: &RingReading, step: &Step, pose: [f32; 3], p: [[f32; 3]; 3], mode: Mode) -> Self {
        let prediction = step.report.prediction;
        Self {
            time_us: r.fired_at_us,
            cycle: r.cycle,
            transducer: r.transducer,
            outcome: WireOutcome::from(&r.outcome),
            predicted_mm: prediction.map(|p| p.range_mm),
            kappa: prediction.map_or(0.0, |p| p.kappa.to_num::<f32>()),
            verdict: step.report.verdict.into(),
            update: step.report.update.into(),
            pose,
            covariance: [p[0][0], p[0][1], p[0][2], p[1][1], p[1][2], p[2][2]],
            mode: mode.into(),
        }
    }
}

/// A finished ring cycle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleReport {
    /// Which cycle.
    pub cycle: u32,
    /// Verdicts: confirmed, unknown obstacle, removed or missed,
    /// unpredicted, nothing as predicted, inconclusive.
    pub verdicts: [u16; 6],
    /// Readings the gate tested, and accepted.
    pub gate: [u16; 2],
    /// The localizer's mode in the cycle.
    pub mode: WireMode,
    /// Particles weighed (while searching).
    pub particles: u16,
    /// The EKF took over from the particles at its end.
    pub handoff: bool,
    /// The places the search weighs (while searching): with the place test,
    /// its living places (version 3).
    pub hypotheses: u8,
    /// While searching, the best place's smallest lead over the null and
    /// every other, nats: the hand-off waits for the test's bound (version 3).
    pub lead: f32,
    /// With the place test, how far the EKF's pose trails the null, nats:
    /// *lost* at the bound (version 3).
    pub behind: f32,
}

impl From<&CycleEnd> for CycleReport {
    fn from(c: &CycleEnd) -> Self {
        let v = &c.verdicts;
        let n = |x: u32| x.min(u32::from(u16::MAX)) as u16;
        Self {
            cycle: c.cycle,
            verdicts: [
                n(v.confirmed),
                n(v.unknown_obstacle),
                n(v.removed_or_missed),
                n(v.unpredicted),
                n(v.nothing_as_predicted),
                n(v.inconclusive),
            ],
            gate: [c.updates.tested, c.updates.accepted],
            mode: c.localizer.mode.into(),
            particles: c.localizer.particles,
            handoff: c.localizer.handoff,
            hypotheses: c.localizer.hypotheses,
            lead: c.localizer.lead,
            behind: c.localizer.behind,
        }
    }
}

/// Frames the controller received, by fate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RxCounts {
    /// Decoded and taken.
    pub ok: u32,
    /// Longer than the receive buffer.
    pub overflow: u32,
    /// Not valid COBS.
    pub cobs: u32,
    /// Shorter than a version byte and a CRC.
    pub short: u32,
    /// CRC mismatch.
    pub crc: u32,
    /// Another protocol version.
    pub version: u32,
    /// A sound frame whose payload is no message (or has bytes left over).
    pub decode: u32,
}

impl RxCounts {
    /// Every frame dropped.
    pub fn dropped(&self) -> u32 {
        self.overflow + self.cobs + self.short + self.crc + self.version + self.decode
    }
}

/// From the controller to the robot's computer.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FromController {
    /// Sent first: what the controller runs.
    Hello {
        /// [`PROTOCOL_VERSION`].
        protocol: u8,
        /// Transducers in the ring.
        transducers: u8,
        /// CRC-32 of the map blob it holds.
        map_crc: u32,
        /// Its clock now, µs.
        time_us: u32,
    },
    /// One reading.
    Reading(ReadingReport),
    /// One finished cycle.
    Cycle(CycleReport),
    /// The link's own health, sent at the end (and on request of a board).
    Status {
        /// Frames received, by fate.
        rx: RxCounts,
        /// Odometry messages refused (out of order, non-finite).
        odometry_refused: u32,
        /// Readings processed.
        readings: u32,
        /// Readings dropped because no odometry covered their time soon enough.
        stale: u32,
    },
}
