//! The localizer's settings.

use super::super::particles::McConfig;
use super::super::scan::ScanConfig;

/// Readings a cycle holds for the particles (a ring of up to 32).
pub const MAX_SENSED: usize = 32;

/// The localizer's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LocalizerConfig {
    /// The particles'.
    pub mcl: McConfig,
    /// The search's proposals ([`crate::localize::scan`]).
    pub scan: ScanConfig,
    /// Hand-off: the cluster's share of the weight ...
    pub handoff_weight: f32,
    /// ... within this distance of its mean, m ...
    pub handoff_radius_m: f32,
    /// ... and this angle, rad ...
    pub handoff_angle_rad: f32,
    /// ... on this many cycles in a row ...
    pub handoff_cycles: u8,
    /// ... each with at least this many readings.
    pub handoff_min_readings: u8,
    /// A scan's candidate that beats the heaviest cluster on the readings
    /// of the last cycles ([`crate::localize::history`]) by this many nats (the
    /// hits widened by `verify_sigma_mm`) enters the set as
    /// `verified_share` of it, not as one particle.
    pub verify_margin: f32,
    /// See `verify_margin`, mm.
    pub verify_sigma_mm: f32,
    /// See `verify_margin`.
    pub verified_share: f32,
    /// The scan's candidates, ranked on the history, this many go on.
    pub verify_keep: u8,
    /// ... and leads the search's best proposal elsewhere on the last
    /// cycles' readings by this many nats, every one of those cycles.
    pub handoff_lead: f32,
    /// ... where a place's lead is its sum less this many times the root
    /// of its cycles' squared leads ([`crate::localize::hypotheses`]): the
    /// margin grows with how alike two places have looked, and two that
    /// stay level are never decided between.
    pub handoff_z: f32,
    /// The places the hypothesis bank keeps besides the cluster (at most
    /// [`BANK`](crate::localize::hypotheses::BANK); 1 is #27's kept rival).
    pub bank_keep: u8,
    /// A place of the bank the cluster leads by this many nats (after the
    /// margin) is refuted and dropped (`+∞`: never; a place goes only when
    /// a stronger one takes its room).
    pub bank_refute: f32,
    /// ... and the EKF's own pose, when it runs beside the particles after
    /// a wake-up, by this many: it tracked until a moment ago, and in heavy
    /// clutter an alias far away can fit the last cycles better than the
    /// truth by 100–150 nats while the EKF's gate says lost for a moment
    /// (depot, `--inconsistent 0.5`, seed 23: at 60 the EKF was moved 25 m
    /// away from a pose 2 cm off). A kidnap is then found later: its
    /// figures in `docs/localization.md`.
    pub handoff_lead_awake: f32,
    /// The EKF's standard deviations at a hand-off are at least these.
    pub handoff_sigma_floor: [f32; 3],
    /// When the EKF is lost, particles are drawn around its estimate with
    /// at least these standard deviations ...
    pub wake_sigma: [f32; 3],
    /// ... or this many times its own, if larger ...
    pub wake_sigma_scale: f32,
    /// ... and this share of them over all free space. While they search,
    /// the EKF goes on beside them (and its estimate is the one reported);
    /// when their heaviest cluster holds half the weight within
    /// `calm_radius_m` and `calm_angle_rad` of it, or its readings fit it
    /// again (the fit monitor and its own gate), and it is not lost, for
    /// `calm_cycles` cycles in a row, the search ends: a false alarm costs
    /// a few cycles, and no relocation.
    pub wake_global: f32,
    /// See `wake_global`.
    pub calm_cycles: u8,
    /// See `wake_global`, m.
    pub calm_radius_m: f32,
    /// See `wake_global`, rad.
    pub calm_angle_rad: f32,
    /// The fit monitor (see `Localizer::monitor`): weight of a cycle in the
    /// short-term average ...
    pub fit_fast: f32,
    /// ... and in the long-term one ...
    pub fit_slow: f32,
    /// ... the drop, nats a reading ...
    pub fit_drop: f32,
    /// ... for this many cycles in a row wakes the particles (0: off).
    pub fit_cycles: u8,
    /// The hand-off decided by the sequential test between places that
    /// track themselves and the null ([`crate::localize::places`], issue
    /// #48) instead of the cluster's weight and lead; `None`: the cluster's.
    /// With it, the EKF's pose is judged against the null too: *lost* when
    /// it trails by the bound (a CUSUM, beside the gate's counts and the
    /// fit monitor), and after a wake-up the search ends without a hand-off
    /// (`calm_cycles`) only while it is not behind.
    pub place_test: Option<PlaceTest>,
}

/// The sequential test's settings when it decides the hand-off: each
/// cycle the particles' heaviest cluster (holding at least
/// `cluster_weight`) and the sweep's best `proposals` places are proposed
/// to a bank of [`PLACES`] places, each corrected by the field as it goes;
/// the hand-off goes to the place `bound` ahead of the null and every
/// other.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlaceTest {
    /// The test's bound, nats.
    pub bound: f32,
    /// The sweep's places proposed a cycle (best first).
    pub proposals: u8,
    /// The cluster is proposed when it holds this share of the weight.
    pub cluster_weight: f32,
    /// A sweep's proposal starts with these standard deviations (m, m,
    /// rad); the cluster's with its own covariance, at least `floor`.
    pub sweep_sigma: [f32; 3],
    /// See `sweep_sigma`.
    pub floor: [f32; 3],
    /// A reading's log-ratio over the null is clipped to `±clip`, nats.
    pub clip: f32,
    /// The share of readings that are the expected echo
    /// ([`crate::localize::place::Tracking::hit_share`]).
    pub hit_share: f32,
    /// The null's memory, readings ([`crate::localize::NullModel`]).
    pub null_memory: f32,
    /// While tracking, the free nodes the sweep scores a cycle to propose
    /// rivals to the tracked pose (issue #48 item 4): the places are kept
    /// through the hand-off, the tracked pose is one of them, and a rival
    /// that leads it, the null and every other by the bound takes over.
    /// 0: no rivals; the tracked pose is judged against the null alone.
    pub rival_nodes: u16,
    /// After a wake-up the search ends without a hand-off (a calm) only on
    /// cycles the EKF trails the null by at most this, nats (its CUSUM,
    /// the report's `behind`); at least 0 and below the bound.
    pub calm_behind: f32,
    /// A proposal within a metre and 20° of a living place (not the
    /// tracked one), farther than a merge, that scores the cycle's readings
    /// better than it joins as a place of its own instead of being held
    /// ([`crate::localize::Places::propose_beside`]). Off by default:
    /// measured in docs/localization.md (*a proposal beside a place*).
    pub join_beside: bool,
}

/// The places the test weighs at once.
pub const PLACES: usize = 8;

impl PlaceTest {
    /// As measured on the simulator (docs/localization.md, *the bank end
    /// to end*): the bound 150 nats, four of the sweep's places a cycle,
    /// the cluster from a tenth of the weight, a reading clipped to 2 nats,
    /// half the readings the expected echo, the null remembering 400.
    pub const DEFAULT: Self = Self {
        bound: 150.0,
        proposals: 4,
        cluster_weight: 0.1,
        sweep_sigma: [0.15, 0.15, 0.05],
        floor: [0.1, 0.1, 0.05],
        clip: 2.0,
        hit_share: 0.5,
        null_memory: 400.0,
        rival_nodes: 0,
        calm_behind: 0.0,
        join_beside: false,
    };
}

impl LocalizerConfig {
    /// The hand-off (95 % within 0.2 m and 5°, five cycles in a
    /// row), and a lost EKF's particles within ±0.5 m and ±15° of it (or
    /// three of its σ) with 30 % over all free space.
    pub const DEFAULT: Self = Self {
        mcl: McConfig::DEFAULT,
        scan: ScanConfig::DEFAULT,
        handoff_weight: 0.95,
        handoff_radius_m: 0.2,
        handoff_angle_rad: 5.0 * core::f32::consts::PI / 180.0,
        handoff_cycles: 5,
        handoff_min_readings: 4,
        verify_margin: 15.0,
        verify_sigma_mm: 150.0,
        verified_share: 0.15,
        verify_keep: 16,
        handoff_lead: 25.0,
        handoff_z: 0.0,
        bank_keep: 1,
        bank_refute: f32::INFINITY,
        handoff_lead_awake: 150.0,
        handoff_sigma_floor: [0.10, 0.10, 3.0 * core::f32::consts::PI / 180.0],
        wake_sigma: [0.5, 0.5, 15.0 * core::f32::consts::PI / 180.0],
        wake_sigma_scale: 3.0,
        wake_global: 0.3,
        calm_cycles: 3,
        calm_radius_m: 0.5,
        calm_angle_rad: 10.0 * core::f32::consts::PI / 180.0,
        fit_fast: 0.5,
        fit_slow: 0.02,
        fit_drop: 0.45,
        fit_cycles: 3,
        place_test: None,
    };
}
