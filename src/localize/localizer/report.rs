//! What the localizer says it did: its mode, a cycle's report, the run's counts.

use super::super::particles::Weighed;
use crate::referencing::{CycleUpdates, VerdictCounts};

/// What the localizer is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    /// The particles search; the estimate is their heaviest cluster's.
    Searching,
    /// The EKF tracks; the particles sleep.
    Tracking,
    /// The EKF says it is lost (with no particles to search, it stays so
    /// until its own recovery finds the pose).
    Lost,
}

impl Mode {
    /// `searching`, `tracking` or `lost`.
    pub const fn name(self) -> &'static str {
        match self {
            Mode::Searching => "searching",
            Mode::Tracking => "tracking",
            Mode::Lost => "lost",
        }
    }
}

/// What a ring cycle's end did.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleReport {
    /// The mode of the cycle that ended (`Lost` on the cycle the EKF was
    /// found lost, though the particles search from the next).
    pub mode: Mode,
    /// The particles weighed (0 unless searching).
    pub particles: u16,
    /// The heaviest cluster's share of the weight (0 unless searching).
    pub cluster_weight: f32,
    /// The share of the set injected at random.
    pub injected: f32,
    /// The EKF took over from the particles.
    pub handoff: bool,
    /// The particles woke (the EKF was lost).
    pub woke: bool,
    /// Readings of the cycle beyond [`MAX_SENSED`](super::MAX_SENSED), not seen by the particles.
    pub dropped: u16,
    /// What weighing the particles did (while searching).
    pub weighed: Weighed,
    /// How far the heaviest cluster led the search's best proposal
    /// elsewhere on the last cycles' readings, nats (while searching);
    /// with the place test (`LocalizerConfig::place_test`), the best
    /// place's smallest lead over the null and every other place, which
    /// the hand-off waits to reach the bound.
    pub lead: f32,
    /// With the place test: how far the EKF's pose (tracking, or beside
    /// the search after a wake-up) trails the null, nats: the CUSUM of the
    /// null's lead over it, *lost* at the test's bound; 0 otherwise.
    pub behind: f32,
    /// The places the search weighs (while searching): the heaviest
    /// cluster and the hypothesis bank's places away from it, or with the
    /// place test its living places. More than one alive and level, the
    /// search goes on.
    pub hypotheses: u8,
    /// The search ended because the EKF beside it was no longer lost.
    pub calmed: bool,
    /// The cycle's verdicts (none while searching with no EKF beside).
    pub verdicts: VerdictCounts,
    /// What the EKF's gate did with the cycle's readings.
    pub updates: CycleUpdates,
    /// While tracking: the mean log-likelihood a reading of the cycle had
    /// at the EKF's pose (the particles' model), and the monitor's short-
    /// and long-term averages of it.
    pub fit: [f32; 3],
}

/// Counts over the run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LocalizerCounts {
    /// Cycles ended searching.
    pub searching: u32,
    /// Cycles ended tracking.
    pub tracking: u32,
    /// Cycles ended lost.
    pub lost: u32,
    /// Hand-offs to the EKF.
    pub handoffs: u32,
    /// Times the particles woke.
    pub wakes: u32,
    /// Searches ended because the EKF beside them was no longer lost.
    pub calmed: u32,
    /// Hand-offs while tracking: a rival the place test preferred to the
    /// tracked pose (counted in `handoffs` too).
    pub takeovers: u32,
}
