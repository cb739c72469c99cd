//! One localizer, three modes (DESIGN §4.8): *searching* (the particles
//! alone, over all free space or around a given pose), *tracking* (the EKF,
//! the particles asleep) and *lost* (the EKF's lost monitor fired: the
//! particles wake around its estimate, widened, with a share over all free
//! space, and search from the next cycle).
//!
//! The hand-off: when one cluster holds `handoff_weight` of the weight
//! within `handoff_radius_m` and `handoff_angle_rad` of its mean, on
//! `handoff_cycles` cycles in a row, the EKF starts at the cluster's mean
//! with its covariance (never tighter than `handoff_sigma_floor`).
//!
//! The localizer sees readings one at a time, as the controller does; the
//! particles see them a cycle at a time, each at the transducer's pose at
//! its firing relative to the cycle's start (the odometry between carries
//! it), so a ring that fires over half a second while the robot moves is
//! scored where each reading was taken.

use heapless::Vec;

use super::expect::FieldLookup;
use super::history::History;
use super::particles::{Cluster, McConfig, ParticleError, ParticleSet, Sensed, Weighed};
use super::scan::{Candidate, ScanConfig, Sweep, SCAN_KEEP};
use super::{SAME_PLACE_M, SAME_PLACE_RAD};
use crate::credence::Credence;
use crate::f32math::{sin_cos, sqrt};
use crate::map::field::FieldView;
use crate::map::MapSource;
use crate::predict::{Mount, PredictParams};
use crate::referencing::{
    wrap, CycleUpdates, Ekf, EkfConfig, EkfError, Motion, Reading, ReadingReport, Referencer, ReferencerError, Verdict,
    VerdictConfig, VerdictCounts,
};

/// Readings a cycle holds for the particles (a ring of up to 32).
pub const MAX_SENSED: usize = 32;

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

/// Where the localizer starts.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Start {
    /// Anywhere: particles over all free space.
    Unknown,
    /// Near `pose` (x m, y m, φ rad), with standard deviations `sigma`:
    /// particles drawn around it.
    Around {
        /// The pose.
        pose: [f32; 3],
        /// Its standard deviations (m, m, rad).
        sigma: [f32; 3],
    },
    /// At `pose` with standard deviations `sigma`: the EKF tracks at once.
    Known {
        /// The pose.
        pose: [f32; 3],
        /// Its standard deviations (m, m, rad).
        sigma: [f32; 3],
    },
}

/// Why the localizer refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LocalizeError {
    /// A search was asked of a localizer with no particles (`N = 0`).
    NoCapacity,
    /// The map's field has no free space to draw particles from (a map
    /// compiled without a field, or one with no room for the robot).
    NoFreeSpace,
    /// The start pose is not in the map's free space.
    OutsideMap,
    /// A non-finite pose, σ or odometry.
    NotFinite,
    /// A transducer stands farther from the robot's centre than the
    /// field reaches (`reach_mm`): the map must be compiled with more reach.
    RingBeyondField {
        /// The transducer.
        transducer: u8,
    },
    /// The EKF refused.
    Ekf(EkfError),
    /// Prediction or the EKF refused a reading.
    Referencer(ReferencerError),
}

impl From<EkfError> for LocalizeError {
    fn from(e: EkfError) -> Self {
        Self::Ekf(e)
    }
}

impl From<ReferencerError> for LocalizeError {
    fn from(e: ReferencerError) -> Self {
        Self::Referencer(e)
    }
}

impl From<ParticleError> for LocalizeError {
    fn from(e: ParticleError) -> Self {
        match e {
            ParticleError::NoCapacity => Self::NoCapacity,
            ParticleError::NoFreeSpace => Self::NoFreeSpace,
            ParticleError::NotFinite => Self::NotFinite,
        }
    }
}

impl core::fmt::Display for LocalizeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NoCapacity => f.write_str("no particles to search with (capacity 0)"),
            Self::NoFreeSpace => f.write_str("the map's field has no free space (compile the map with a field)"),
            Self::OutsideMap => f.write_str("the start pose is not in the map's free space"),
            Self::NotFinite => f.write_str("a non-finite pose, standard deviation or odometry"),
            Self::RingBeyondField { transducer } => {
                write!(f, "transducer {transducer} stands beyond the field's reach (compile the map with more reach)")
            }
            Self::Ekf(e) => write!(f, "EKF: {e:?}"),
            Self::Referencer(e) => write!(f, "{e:?}"),
        }
    }
}

impl core::error::Error for LocalizeError {}

/// The localizer's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LocalizerConfig {
    /// The particles'.
    pub mcl: McConfig,
    /// The search's proposals ([`super::scan`]).
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
    /// of the last cycles ([`super::history`]) by this many nats (the
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
    };
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
    /// Readings of the cycle beyond [`MAX_SENSED`], not seen by the particles.
    pub dropped: u16,
    /// What weighing the particles did (while searching).
    pub weighed: Weighed,
    /// How far the heaviest cluster led the search's best proposal
    /// elsewhere on the last cycles' readings, nats (while searching).
    pub lead: f32,
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
}

/// The localizer: the EKF (with its verdicts) and `N` particles. `N = 0`
/// is the EKF alone.
#[derive(Clone, Debug)]
pub struct Localizer<const N: usize> {
    cfg: LocalizerConfig,
    referencer: Referencer,
    particles: ParticleSet<N>,
    mode: Mode,
    sensed: Vec<Sensed, MAX_SENSED>,
    dropped: u16,
    /// The odometry since the cycle's start, in its frame (x m, y m, φ rad).
    offset: [f32; 3],
    /// The particles' estimate at the cycle's start and its covariance.
    cluster: Option<Cluster>,
    /// The strongest pose found away from the cluster (at the cycle's
    /// start), and the cluster's lead over it summed over every cycle since
    /// it was found (nats): kept from cycle to cycle, because the sweep
    /// visits a node only every few cycles and the history holds 8, and an
    /// alias that only a feature driven past long ago tells apart must
    /// neither count as beaten when it is not proposed nor draw level when
    /// the feature leaves the history.
    rival: Option<([f32; 3], f32)>,
    converged: u8,
    sweep: Sweep,
    history: History,
    /// While searching after a wake, the EKF goes on tracking beside the
    /// particles.
    ekf_awake: bool,
    calm: u8,
    /// The fit monitor's short- and long-term averages, the cycles it has
    /// seen, and the bad ones in a row (the short one below the long one by
    /// the drop).
    fit: (f32, f32),
    fit_seen: u16,
    misfit: u8,
    counts: LocalizerCounts,
}

/// `a ⊕ b`.
fn compose(a: &[f32; 3], b: &[f32; 3]) -> [f32; 3] {
    let (s, c) = sin_cos(a[2]);
    [a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2])]
}

impl<const N: usize> Localizer<N> {
    /// A localizer with settings `cfg`, the EKF's `ekf`, judging with
    /// `verdicts`; `seed` fixes every random draw. It knows nothing yet:
    /// [`Localizer::start`] it (its mode until then is *searching* with no
    /// particles, and it refuses nothing). Infallible, so that the caller's
    /// one copy is built in place (a `Localizer<1024>` is 21 KiB; returned
    /// inside a `Result` it would pass through the stack more than once).
    #[inline]
    pub fn new(cfg: LocalizerConfig, ekf: EkfConfig, verdicts: VerdictConfig, seed: u64) -> Self {
        Self {
            cfg,
            referencer: Referencer::new(Ekf::origin(ekf), verdicts),
            particles: ParticleSet::new(seed),
            mode: Mode::Searching,
            sensed: Vec::new(),
            dropped: 0,
            offset: [0.0; 3],
            cluster: None,
            rival: None,
            converged: 0,
            sweep: Sweep::default(),
            history: History::new(),
            ekf_awake: false,
            calm: 0,
            fit: (0.0, 0.0),
            fit_seen: 0,
            misfit: 0,
            counts: LocalizerCounts::default(),
        }
    }

    /// Starts again from `start` (a pose the robot's computer sent, or none):
    /// the EKF's settings and its odometry calibration are kept.
    pub fn start(&mut self, start: Start, field: &FieldView<'_>) -> Result<(), LocalizeError> {
        let lookup = FieldLookup::new(field);
        match start {
            Start::Known { pose, sigma } => {
                self.referencer.ekf.relocate_diagonal(pose, sigma)?;
                self.mode = Mode::Tracking;
            }
            Start::Unknown => {
                if N == 0 {
                    return Err(LocalizeError::NoCapacity);
                }
                self.particles.seed_global(&lookup, N)?;
                self.mode = Mode::Searching;
            }
            Start::Around { pose, sigma } => {
                if N == 0 {
                    return Err(LocalizeError::NoCapacity);
                }
                if !pose.iter().chain(sigma.iter()).all(|v| v.is_finite()) || sigma.iter().any(|&s| s < 0.0) {
                    return Err(LocalizeError::NotFinite);
                }
                if lookup.field().free_nodes() == 0 {
                    return Err(LocalizeError::NoFreeSpace);
                }
                if !lookup.is_free(pose[0] * 1e3, pose[1] * 1e3) {
                    return Err(LocalizeError::OutsideMap);
                }
                self.particles.seed_around(&lookup, N, pose, sigma, 0.0)?;
                self.mode = Mode::Searching;
            }
        }
        self.sensed.clear();
        self.dropped = 0;
        self.offset = [0.0; 3];
        self.converged = 0;
        self.cluster = None;
        self.rival = None;
        self.history.clear();
        self.ekf_awake = false;
        self.calm = 0;
        self.fit_seen = 0;
        self.misfit = 0;
        if self.mode == Mode::Searching {
            self.cluster = self.particles.cluster(self.cfg.handoff_radius_m, self.cfg.handoff_angle_rad);
        }
        Ok(())
    }

    /// Checks that every transducer of `mounts` stands within the field's
    /// reach (call once with the ring).
    pub fn check_ring(&self, mounts: &[Mount], field: &FieldView<'_>) -> Result<(), LocalizeError> {
        if field.is_empty() {
            return Ok(());
        }
        let reach = field.header().reach_mm as f32;
        for (i, m) in mounts.iter().enumerate() {
            let (x, y) = (m.x_mm as f32, m.y_mm as f32);
            if sqrt(x * x + y * y) > reach {
                return Err(LocalizeError::RingBeyondField { transducer: i as u8 });
            }
        }
        Ok(())
    }

    /// Odometry since the last call (in the robot's frame at the last call).
    pub fn odometry(&mut self, u: &Motion) -> Result<(), LocalizeError> {
        if !u.is_finite() {
            return Err(LocalizeError::NotFinite);
        }
        if self.mode != Mode::Searching || self.ekf_awake {
            self.referencer.odometry(u)?;
        }
        self.offset = compose(&self.offset, &[u.dx, u.dy, u.dphi]);
        Ok(())
    }

    /// One transducer's reading: kept for the particles, and, unless
    /// searching, predicted at the EKF's estimate, judged and fed to it.
    /// While searching there is no pose to judge from: the report has no
    /// prediction and the verdict is inconclusive.
    pub fn reading<M: MapSource + ?Sized, K: Credence + ?Sized>(
        &mut self,
        map: &M,
        mount: &Mount,
        params: &PredictParams,
        credence: &K,
        reading: Reading,
    ) -> Result<ReadingReport, LocalizeError> {
        let m = [mount.x_mm as f32 * 1e-3, mount.y_mm as f32 * 1e-3, (mount.heading_mdeg as f32 * 1e-3).to_radians()];
        let pose = compose(&self.offset, &m);
        if self.sensed.push(Sensed { pose, reading }).is_err() {
            self.dropped = self.dropped.saturating_add(1);
        }
        if self.mode == Mode::Searching && !self.ekf_awake {
            return Ok(ReadingReport { prediction: None, verdict: Verdict::Inconclusive, target: None, update: None });
        }
        Ok(self.referencer.reading(map, mount, params, credence, reading)?)
    }

    /// Ends a ring cycle: the EKF's lost monitor, or the particles' update,
    /// resampling and motion; the hand-off and the wake-up.
    pub fn end_cycle(&mut self, field: &FieldView<'_>) -> Result<CycleReport, LocalizeError> {
        let lookup = FieldLookup::new(field);
        let offset = Motion { dx: self.offset[0], dy: self.offset[1], dphi: self.offset[2] };
        let mut report = CycleReport {
            mode: self.mode,
            particles: 0,
            cluster_weight: 0.0,
            injected: 0.0,
            handoff: false,
            woke: false,
            dropped: self.dropped,
            weighed: Weighed::default(),
            lead: 0.0,
            calmed: false,
            fit: [0.0; 3],
            verdicts: VerdictCounts::default(),
            updates: CycleUpdates::default(),
        };
        match self.mode {
            Mode::Searching => {
                let cfg = self.cfg;
                if self.ekf_awake {
                    (report.verdicts, report.updates) = self.referencer.end_cycle();
                    self.monitor(&lookup, &mut report);
                }
                // The model widens with the last cluster's position spread.
                let spread = self.cluster.map_or(f32::INFINITY, |c| {
                    let p = c.covariance;
                    if c.weight >= 0.5 {
                        sqrt((p[0][0] + p[1][1]).max(0.0))
                    } else {
                        f32::INFINITY
                    }
                });
                self.particles.set_spread(spread);
                let w = self.particles.weigh(&self.sensed, &lookup, &cfg.mcl);
                report.weighed = w;
                report.particles = self.particles.len() as u16;
                let cluster = self.particles.cluster(cfg.handoff_radius_m, cfg.handoff_angle_rad);
                report.cluster_weight = cluster.map_or(0.0, |c| c.weight);
                // The cluster's standing: a cycle at the hand-off weight counts
                // one up, a cycle where the same cluster (its mean within the
                // hand-off radius of the last, carried by the odometry) holds
                // at least half counts one down, anything else starts again.
                let same = match (&cluster, &self.cluster) {
                    (Some(c), Some(prev)) => {
                        // The last cluster was carried to this cycle's start.
                        let p = prev.mean;
                        let (dx, dy) = (c.mean[0] - p[0], c.mean[1] - p[1]);
                        dx * dx + dy * dy <= cfg.handoff_radius_m * cfg.handoff_radius_m
                            && wrap(c.mean[2] - p[2]).abs() <= cfg.handoff_angle_rad
                    }
                    _ => false,
                };
                let weight = cluster.map_or(0.0, |c| c.weight);
                let enough = w.readings >= u16::from(cfg.handoff_min_readings);
                // The search's proposals, and how far the cluster leads the
                // best of them elsewhere on the last cycles' readings.
                let mut candidates: heapless::Vec<Candidate, SCAN_KEEP> = heapless::Vec::new();
                self.sweep.scan(&self.sensed, &lookup, &cfg.mcl.beam, &cfg.scan, &mut candidates);
                // A cluster that is not the last one has a new rival.
                if !same {
                    self.rival = None;
                }
                let (lead, rival) = self.verify(&mut candidates, cluster.as_ref(), &lookup);
                report.lead = lead;
                // While the EKF beside the particles still has its own
                // readings (its gate's monitor does not say lost), the
                // particles may confirm it but not move it far: a map with
                // a near-symmetry (depot's half-turn) has an alias that can
                // fit a few cycles better than the truth, and a fit alarm
                // alone does not justify leaving the pose the readings
                // validate.
                let far = self.ekf_awake
                    && !self.referencer.ekf.is_lost()
                    && cluster.as_ref().is_some_and(|c| {
                        let x = self.ekf_at_cycle_start();
                        let (dx, dy) = (c.mean[0] - x[0], c.mean[1] - x[1]);
                        dx * dx + dy * dy > cfg.calm_radius_m * cfg.calm_radius_m
                            || wrap(c.mean[2] - x[2]).abs() > cfg.calm_angle_rad
                    });
                let ahead = lead >= cfg.handoff_lead && !far;
                // A cycle where the cluster keeps half the weight but not the
                // hand-off's share, or its lead, counts one down.
                self.converged = match (weight >= cfg.handoff_weight && enough && ahead, same, weight >= 0.5) {
                    (true, true, _) => self.converged.saturating_add(1),
                    (true, false, _) => 1,
                    (false, true, true) => self.converged.saturating_sub(1),
                    _ => 0,
                };
                match cluster {
                    Some(c) if self.converged >= cfg.handoff_cycles => {
                        self.handoff(&c, &offset)?;
                        report.handoff = true;
                    }
                    _ => {
                        self.particles.resample(&self.sensed, &lookup, &cfg.mcl, 1.0 - weight, &candidates);
                        report.injected = self.particles.injected();
                        self.particles.motion(&offset, &cfg.mcl.motion)?;
                        // The estimate to report until the next cycle: the
                        // cluster found before resampling, moved by the cycle's
                        // odometry.
                        self.cluster = cluster.map(|mut c| {
                            c.mean = compose(&c.mean, &self.offset);
                            c
                        });
                        // The rival too.
                        self.rival = rival.map(|(r, d)| (compose(&r, &self.offset), d));
                        // The particles' heaviest cluster holds half the weight
                        // where the EKF beside them is, cycle after cycle: it
                        // was a false alarm, and the search ends (the fit
                        // monitor takes the readings as they are now for
                        // its long-term average).
                        let agrees = cluster.as_ref().is_some_and(|c| {
                            let x = self.referencer.ekf.state();
                            let p = compose(&c.mean, &self.offset);
                            let (dx, dy) = (p[0] - x[0], p[1] - x[1]);
                            c.weight >= 0.5
                                && dx * dx + dy * dy <= cfg.calm_radius_m * cfg.calm_radius_m
                                && wrap(p[2] - x[2]).abs() <= cfg.calm_angle_rad
                                && !self.referencer.ekf.is_lost()
                        });
                        // Or the EKF's readings fit it again, by the fit
                        // monitor and by its own gate.
                        let fits = self.misfit == 0 && !self.referencer.ekf.is_lost();
                        self.calm = if self.ekf_awake && (agrees || fits) { self.calm.saturating_add(1) } else { 0 };
                        if self.ekf_awake && self.calm >= cfg.calm_cycles {
                            self.mode = Mode::Tracking;
                            self.ekf_awake = false;
                            self.calm = 0;
                            self.cluster = None;
                            self.rival = None;
                            self.fit.1 = self.fit.0;
                            self.misfit = 0;
                            self.counts.calmed = self.counts.calmed.saturating_add(1);
                            report.calmed = true;
                        }
                    }
                }
            }
            Mode::Tracking | Mode::Lost => {
                (report.verdicts, report.updates) = self.referencer.end_cycle();
                self.calm = 0;
                let misfit = self.monitor(&lookup, &mut report);
                let lost = self.referencer.ekf.is_lost() || misfit;
                if lost && N > 0 {
                    report.mode = Mode::Lost;
                    self.wake(&lookup)?;
                    report.woke = true;
                } else {
                    self.mode = if lost { Mode::Lost } else { Mode::Tracking };
                    report.mode = self.mode;
                }
            }
        }
        // The cycle joins the history, which moves to the next cycle's frame.
        self.history.push(&self.sensed);
        self.history.rebase(&self.offset);
        match report.mode {
            Mode::Searching => self.counts.searching = self.counts.searching.saturating_add(1),
            Mode::Tracking => self.counts.tracking = self.counts.tracking.saturating_add(1),
            Mode::Lost => self.counts.lost = self.counts.lost.saturating_add(1),
        }
        self.sensed.clear();
        self.dropped = 0;
        self.offset = [0.0; 3];
        Ok(report)
    }

    /// The fit monitor: the readings' mean log-likelihood at the EKF's pose
    /// (at the cycle's start), its short- and long-term averages (augmented
    /// MCL's, on the EKF's one hypothesis); true when the short one has
    /// been `fit_drop` below the long one for `fit_cycles` cycles in a row:
    /// the readings no longer fit the pose, as after a kidnap, well before
    /// the gate's counts say so.
    fn monitor(&mut self, lookup: &FieldLookup<'_, '_>, report: &mut CycleReport) -> bool {
        let c = &self.cfg;
        let k = Sensed::usable(&self.sensed);
        if N == 0 || lookup.field().is_empty() || k < usize::from(c.handoff_min_readings) {
            return false;
        }
        let start = self.ekf_at_cycle_start();
        let fit = ParticleSet::<0>::log_likelihood(&start, &self.sensed, lookup, &c.mcl.beam, 0.0) / k as f32;
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
        self.fit_seen > u16::from(c.fit_cycles) * 4 && self.misfit >= c.fit_cycles
    }

    /// The EKF's estimate carried back to the cycle's start (where the
    /// particles stand and the readings are expressed): now ⊕ offset⁻¹.
    fn ekf_at_cycle_start(&self) -> [f32; 3] {
        let now = self.referencer.ekf.state();
        let (s, co) = sin_cos(self.offset[2]);
        let (ox, oy) = (-(co * self.offset[0] + s * self.offset[1]), s * self.offset[0] - co * self.offset[1]);
        compose(&now, &[ox, oy, -self.offset[2]])
    }

    /// Scores the scan's candidates and the heaviest cluster's mean on the
    /// history and this cycle: a candidate ahead by the margin becomes
    /// `verified_share` of the set.
    /// Returns how far the cluster leads the strongest pose away from it
    /// (more than a metre or 20°), nats (`+∞` with none, `−∞` with no
    /// cluster), and that pose with the lead, the rival to keep: the
    /// cluster's lead over a candidate is measured on the history; over the
    /// rival kept from earlier cycles it is the lead it had plus this
    /// cycle's readings' say, and whichever is the smaller stands. A rival
    /// that leads the cluster by the margin goes into the set like a
    /// verified candidate.
    fn verify(
        &self,
        candidates: &mut heapless::Vec<Candidate, SCAN_KEEP>,
        cluster: Option<&Cluster>,
        lookup: &FieldLookup<'_, '_>,
    ) -> (f32, Option<([f32; 3], f32)>) {
        let c = &self.cfg;
        if candidates.is_empty() && self.rival.is_none() {
            return (if cluster.is_some() { f32::INFINITY } else { f32::NEG_INFINITY }, None);
        }
        let extra = c.verify_sigma_mm * c.verify_sigma_mm;
        let beam = &c.mcl.beam;
        // Every candidate scored on the history and this cycle; the best few
        // go on (best first), the first of them in number if it beats the
        // heaviest cluster by the margin.
        for cand in candidates.iter_mut() {
            cand.score = self.history.score(&cand.pose, &self.sensed, lookup, beam, extra);
            cand.copies = 1;
        }
        // Best first: an insertion sort (at most SCAN_KEEP, and core's sorts
        // link a panic for orderings that are not total).
        for i in 1..candidates.len() {
            let mut j = i;
            while j > 0 {
                let (Some(a), Some(b)) = (candidates.get(j - 1), candidates.get(j)) else { break };
                if a.score.total_cmp(&b.score).is_ge() {
                    break;
                }
                candidates.swap(j - 1, j);
                j -= 1;
            }
        }
        candidates.truncate(usize::from(c.verify_keep).max(1));
        let score = |p: &[f32; 3]| self.history.score(p, &self.sensed, lookup, beam, extra);
        // A pose's best score nearby: coordinate ascent in x, y and φ with
        // halving steps (0.12 m and 3° down to 0.03 m and 0.75°). The scan's
        // proposals stand on the node grid and its heading bins, the
        // cluster's mean wherever its particles are: each is refined the
        // same way before they are compared, or the incumbent would win by
        // its finer placement alone (in a symmetric map, against its alias).
        let refine = |start: [f32; 3], s0: f32| {
            let (mut best, mut s) = (start, s0);
            for (step_m, step_rad) in [(0.12f32, 0.052f32), (0.06, 0.026), (0.03, 0.013)] {
                for axis in 0..3 {
                    let step = if axis == 2 { step_rad } else { step_m };
                    for sign in [-1.0f32, 1.0] {
                        let mut p = best;
                        if let Some(v) = p.get_mut(axis) {
                            *v += sign * step;
                        }
                        let v = score(&p);
                        if v > s {
                            (best, s) = (p, v);
                        }
                    }
                }
            }
            (best, s)
        };
        let (own_pose, own) = match cluster {
            Some(k) => refine(k.mean, score(&k.mean)),
            None => ([0.0; 3], f32::NEG_INFINITY),
        };
        let elsewhere = |p: &[f32; 3]| {
            cluster.is_none_or(|k| {
                dist2(p, &k.mean) > SAME_PLACE_M * SAME_PLACE_M || heading_apart(p, &k.mean) > SAME_PLACE_RAD
            })
        };
        let mut rival = None;
        let mut lead = if cluster.is_some() { f32::INFINITY } else { f32::NEG_INFINITY };
        if let Some(k) = candidates.iter_mut().find(|k| elsewhere(&k.pose)) {
            (k.pose, k.score) = refine(k.pose, k.score);
            lead = own - k.score;
            rival = Some((k.pose, lead));
        }
        // With no cluster there is nothing to lead, and no rival to keep.
        let kept = self.rival.filter(|(r, _)| cluster.is_some() && elsewhere(r)).and_then(|(r, lead)| {
            let (p, _) = refine(r, score(&r));
            // This cycle's readings alone, at the two refined poses.
            let now = |q: &[f32; 3]| ParticleSet::<0>::log_likelihood(q, &self.sensed, lookup, beam, extra);
            let lead = lead + now(&own_pose) - now(&p);
            elsewhere(&p).then_some((p, lead))
        });
        if let Some((p, lead)) = kept {
            // The same hypothesis as this cycle's candidate keeps its sum;
            // another one stands if it is the stronger.
            // (Not `!elsewhere`: a NaN pose is neither near nor elsewhere.)
            let near = |a: &[f32; 3], b: &[f32; 3]| {
                dist2(a, b) <= SAME_PLACE_M * SAME_PLACE_M && heading_apart(a, b) <= SAME_PLACE_RAD
            };
            if rival.is_none_or(|(q, d)| near(&p, &q) || lead < d) {
                rival = Some((p, lead));
            }
        }
        let rival = rival.filter(|_| cluster.is_some());
        if let Some((_, d)) = rival {
            lead = d;
        }
        if self.ekf_awake {
            // The EKF beside the particles is a hypothesis too: a cluster
            // elsewhere must lead it as well, by the larger margin (it
            // tracked until a moment ago).
            let x = self.ekf_at_cycle_start();
            if elsewhere(&x) {
                let ekf = self.history.score(&x, &self.sensed, lookup, beam, extra);
                lead = lead.min(own - (ekf + c.handoff_lead_awake - c.handoff_lead));
            }
        }
        let share = ((c.verified_share * self.particles.len() as f32) as u16).max(1);
        if let Some(first) = candidates.first_mut() {
            if !self.history.is_empty() && first.score > own + c.verify_margin {
                first.copies = share;
            }
        }
        if let Some((p, d)) = rival {
            if d < -c.verify_margin && candidates.first().is_none_or(|k| k.copies <= 1) {
                candidates.truncate(SCAN_KEEP - 1);
                let _ = candidates.insert(0, Candidate { pose: p, score: own - d, copies: share });
            }
        }
        (lead, rival)
    }

    /// The EKF starts at the cluster (at the cycle's start), then takes the
    /// cycle's odometry.
    fn handoff(&mut self, c: &Cluster, offset: &Motion) -> Result<(), LocalizeError> {
        self.ekf_awake = false;
        self.calm = 0;
        let f = &self.cfg.handoff_sigma_floor;
        let mut p = c.covariance;
        for (i, row) in p.iter_mut().enumerate() {
            row[i] = row[i].max(f[i] * f[i]);
        }
        self.referencer.ekf.relocate(c.mean, p)?;
        self.referencer.ekf.predict(offset)?;
        self.mode = Mode::Tracking;
        self.converged = 0;
        self.cluster = None;
        self.rival = None;
        self.counts.handoffs = self.counts.handoffs.saturating_add(1);
        Ok(())
    }

    /// The EKF is lost: particles around its estimate, widened, and a share
    /// over all free space.
    fn wake(&mut self, lookup: &FieldLookup<'_, '_>) -> Result<(), LocalizeError> {
        let x = self.referencer.ekf.state();
        let p = self.referencer.ekf.covariance();
        let c = &self.cfg;
        let sigma: [f32; 3] = core::array::from_fn(|i| {
            let own = sqrt(p[i][i].max(0.0)) * c.wake_sigma_scale;
            own.max(c.wake_sigma[i])
        });
        let global = if lookup.field().free_nodes() == 0 { 0.0 } else { c.wake_global };
        self.particles.seed_around(lookup, N, x, sigma, global)?;
        self.mode = Mode::Searching;
        self.ekf_awake = true;
        self.calm = 0;
        self.converged = 0;
        self.rival = None;
        self.cluster = self.particles.cluster(c.handoff_radius_m, c.handoff_angle_rad);
        self.counts.wakes = self.counts.wakes.saturating_add(1);
        Ok(())
    }

    /// What the localizer is doing now.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Whether the estimate to report is the particles' (searching, with no
    /// EKF beside them: until they hand off, a woken search reports the
    /// EKF's estimate, marked searching).
    fn particles_report(&self) -> Option<&Cluster> {
        match (self.mode, &self.cluster) {
            (Mode::Searching, Some(c)) if !self.ekf_awake => Some(c),
            _ => None,
        }
    }

    /// The estimate now (x m, y m, φ rad): the EKF's, or while searching
    /// from no pose the heaviest cluster's moved by the odometry since.
    pub fn state(&self) -> [f32; 3] {
        match self.particles_report() {
            Some(c) => compose(&c.mean, &self.offset),
            None => self.referencer.ekf.state(),
        }
    }

    /// Its covariance: the EKF's, or while the particles report, the whole
    /// set's spread about their cluster's mean (how unsure they are).
    pub fn covariance(&self) -> [[f32; 3]; 3] {
        match self.particles_report() {
            Some(c) => c.spread,
            None => self.referencer.ekf.covariance(),
        }
    }

    /// The EKF and its verdicts.
    pub fn referencer(&self) -> &Referencer {
        &self.referencer
    }

    /// The particles.
    pub fn particles(&self) -> &ParticleSet<N> {
        &self.particles
    }

    /// The places the search weighs now (while searching; at the last
    /// cycle's end, in that cycle's frame): the heaviest cluster, and the
    /// strongest pose found away from it with the cluster's lead over it
    /// summed over every cycle since it was found (nats). For a viewer
    /// (`echoloc-lab`'s `/hypotheses`); the search itself reads the fields.
    pub fn hypotheses(&self) -> (Option<&Cluster>, Option<([f32; 3], f32)>) {
        match self.mode {
            Mode::Searching => (self.cluster.as_ref(), self.rival),
            _ => (None, None),
        }
    }

    /// The settings.
    pub fn config(&self) -> &LocalizerConfig {
        &self.cfg
    }

    /// Counts over the run.
    pub fn counts(&self) -> LocalizerCounts {
        self.counts
    }
}

/// The squared distance between two poses' positions, m².
#[inline(always)]
fn dist2(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
    dx * dx + dy * dy
}

/// The difference of two poses' headings, rad, in `[0, π]` (apart: the
/// callers look at it only when the positions are close, it costs a wrap).
#[inline(always)]
fn heading_apart(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    wrap(a[2] - b[2]).abs()
}
