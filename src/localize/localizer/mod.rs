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
//!
//! | module | what it does |
//! |---|---|
//! | this one | [`Localizer`]: its state, the readings and odometry in, a cycle's end (the modes' changes), the hand-off and the wake-up |
//! | [`config`] | [`LocalizerConfig`]: the hand-off's, the wake-up's and the fit monitor's settings |
//! | [`report`] | [`Mode`], [`CycleReport`], [`LocalizerCounts`]: what it says it did |
//! | [`error`] | [`LocalizeError`] |
//! | `judge` | with `LocalizerConfig::place_test`: the hand-off by the sequential test between places that track themselves and the null, and *lost* when the tracked pose trails the null by the bound |
//! | `monitor` | the fit monitor: do the readings still fit the EKF's pose? |
//! | `verify` | the search's proposals and the hypothesis bank's places scored against the cluster on the last cycles' readings |

pub mod config;
pub mod error;
mod judge;
mod monitor;
pub mod report;
mod verify;

pub use config::{LocalizerConfig, PlaceTest, MAX_SENSED, PLACES};
pub use error::LocalizeError;
pub use report::{CycleReport, LocalizerCounts, Mode};

use heapless::Vec;

use super::expect::FieldLookup;
use super::history::History;
use super::hypotheses::{Bank, Hypothesis};
use super::particles::{Cluster, ParticleSet, Sensed, Weighed};
use super::places::{Places, Standing};
use super::scan::{Candidate, ScanConfig, Sweep, SCAN_KEEP};
use super::{within, SAME_PLACE_M, SAME_PLACE_RAD};
use crate::credence::Credence;
use crate::f32math::{sin_cos, sqrt};
use crate::map::field::FieldView;
use crate::map::MapSource;
use crate::predict::{Mount, PredictParams};
use crate::referencing::{
    wrap, CycleUpdates, Ekf, EkfConfig, Motion, Reading, ReadingReport, Referencer, Verdict, VerdictConfig,
    VerdictCounts,
};
use judge::{Judge, Judged};

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
    /// The places found away from the cluster (at the cycle's start), each
    /// with the cluster's lead over it summed over every cycle since it was
    /// found: kept from cycle to cycle, because the sweep visits a node
    /// only every few cycles and the history holds 8, and an alias that
    /// only a feature driven past long ago tells apart must neither count
    /// as beaten when it is not proposed nor draw level when the feature
    /// leaves the history.
    bank: Bank,
    /// With `place_test` set: the places that track themselves, and the
    /// null, whose test decides the hand-off.
    judge: Option<Judge>,
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
            bank: Bank::new(),
            judge: None,
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
        self.judge = match &self.cfg.place_test {
            Some(t) => Some(Judge::new(t, &self.cfg.mcl.beam)?),
            None => None,
        };
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
        self.bank.clear();
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
            behind: 0.0,
            hypotheses: 0,
            calmed: false,
            fit: [0.0; 3],
            verdicts: VerdictCounts::default(),
            updates: CycleUpdates::default(),
        };
        // The sweep's proposals: the search's, or the rivals' while tracking.
        let mut candidates: heapless::Vec<Candidate, SCAN_KEEP> = heapless::Vec::new();
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
                self.sweep.scan(&self.sensed, &lookup, &cfg.mcl.beam, &cfg.scan, &mut candidates);
                // A cluster that is not the last one has a new bank: the
                // leads were the last one's. (Restating them as the new
                // one's, and keeping the last one as a place, was tried:
                // docs/localization.md.)
                if !same {
                    self.bank.clear();
                }
                // With the place test, it alone decides: the proposals go
                // to the places as the sweep gave them, and the cluster's
                // count and bank stand still.
                let mut leader = None;
                if let (Some(test), Some(judge)) = (&cfg.place_test, self.judge.as_mut()) {
                    let ekf = self.referencer.ekf.config();
                    // The EKF beside the search after a wake-up is a place too.
                    let awake = self.ekf_awake.then_some((&self.referencer.ekf, &self.offset));
                    let standing = judge.cycle(
                        test,
                        &self.sensed,
                        &offset,
                        awake,
                        cluster.as_ref(),
                        &candidates,
                        &lookup,
                        &cfg.mcl.beam,
                        ekf,
                    )?;
                    report.behind = judge.behind;
                    let living = judge.places.living();
                    report.hypotheses = living.len() as u8;
                    report.lead = judge.places.best_margin();
                    if let Standing::Leads { index, .. } = standing {
                        leader = living.get(index).map(|p| (p.pose(), p.covariance()));
                    }
                } else {
                    report.lead = self.verify(&mut candidates, cluster.as_ref(), &lookup);
                    report.hypotheses = u8::from(cluster.is_some()).saturating_add(self.bank.len() as u8);
                }
                let lead = report.lead;
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
                    _ if cfg.place_test.is_some() => 0,
                    (true, true, _) => self.converged.saturating_add(1),
                    (true, false, _) => 1,
                    (false, true, true) => self.converged.saturating_sub(1),
                    _ => 0,
                };
                match (leader, cluster) {
                    // With rivals, the place the test prefers is where the
                    // EKF beside the search already is: the search ends
                    // there, the EKF as it is (no hand-off to the place's
                    // coarser estimate).
                    (Some((x, _)), _)
                        if self.rivals()
                            && self.ekf_awake
                            && within(&x, &self.referencer.ekf.state(), SAME_PLACE_M, SAME_PLACE_RAD) =>
                    {
                        self.calm_down(&mut report);
                    }
                    // The place already took the cycle's odometry.
                    (Some((x, p)), _) => {
                        self.handoff(x, p, None)?;
                        report.handoff = true;
                    }
                    (None, Some(c)) if self.converged >= cfg.handoff_cycles => {
                        self.handoff(c.mean, c.covariance, Some(&offset))?;
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
                        // The bank's places too.
                        for p in self.bank.poses_mut() {
                            *p = compose(p, &self.offset);
                        }
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
                        // monitor and by its own gate. With the place test,
                        // either only while the EKF is not behind the null
                        // by more than `calm_behind` (a drifted EKF whose
                        // readings fit the gate again for a few cycles is
                        // no place to go back to).
                        let fits = self.misfit == 0 && !self.referencer.ekf.is_lost();
                        let level = self
                            .judge
                            .as_ref()
                            .zip(cfg.place_test.as_ref())
                            .is_none_or(|(j, t)| j.behind <= t.calm_behind);
                        let calms = self.ekf_awake && (agrees || fits) && level;
                        self.calm = if calms { self.calm.saturating_add(1) } else { 0 };
                        if self.ekf_awake && self.calm >= cfg.calm_cycles {
                            self.calm_down(&mut report);
                        }
                    }
                }
            }
            Mode::Tracking | Mode::Lost => {
                (report.verdicts, report.updates) = self.referencer.end_cycle();
                self.calm = 0;
                let misfit = self.monitor(&lookup, &mut report);
                let judged = self.trails(&lookup, &mut candidates, &mut report)?;
                let lost = self.referencer.ekf.is_lost() || misfit || judged == Judged::Lost;
                if let Judged::Overtaken(x, p) = judged {
                    // A rival the test prefers: the EKF goes there, the
                    // places kept (the old pose among them).
                    self.handoff(x, p, None)?;
                    report.handoff = true;
                    report.mode = Mode::Tracking;
                    self.counts.takeovers = self.counts.takeovers.saturating_add(1);
                } else if lost && N > 0 {
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

    /// With the place test, the tracked pose against the null (*lost*
    /// when its CUSUM reaches the bound: the report's `behind`), and with
    /// rivals against them (the sweep scoring `rival_nodes` nodes a
    /// cycle to propose them). Out of line, so that its frame is not the
    /// cycle's end's on every path (the EKF's recovery below that is the
    /// deepest); the rivals' proposals are swept into `candidates`, the
    /// cycle's end's buffer for the search's.
    #[inline(never)]
    fn trails(
        &mut self,
        lookup: &FieldLookup<'_, '_>,
        candidates: &mut heapless::Vec<Candidate, SCAN_KEEP>,
        report: &mut CycleReport,
    ) -> Result<Judged, LocalizeError> {
        if N == 0 || lookup.field().is_empty() {
            return Ok(Judged::Holds);
        }
        let (Some(test), Some(judge)) = (&self.cfg.place_test, self.judge.as_mut()) else {
            return Ok(Judged::Holds);
        };
        if test.rival_nodes > 0 {
            let scan = ScanConfig { nodes_per_cycle: test.rival_nodes, ..self.cfg.scan };
            self.sweep.scan(&self.sensed, lookup, &self.cfg.mcl.beam, &scan, candidates);
        }
        let offset = Motion { dx: self.offset[0], dy: self.offset[1], dphi: self.offset[2] };
        let tracked = (&self.referencer.ekf, &self.offset);
        let judged = judge.track(test, &self.sensed, &offset, tracked, candidates, lookup, &self.cfg.mcl.beam)?;
        report.behind = judge.behind;
        if test.rival_nodes > 0 {
            report.hypotheses = judge.places.living().len() as u8;
            report.lead = judge.places.best_margin();
        }
        Ok(judged)
    }

    /// Whether the place test keeps its places while tracking (rivals).
    fn rivals(&self) -> bool {
        self.cfg.place_test.is_some_and(|t| t.rival_nodes > 0)
    }

    /// The search beside the awake EKF ends without a hand-off: the EKF
    /// goes on tracking where it is (the fit monitor takes the readings as
    /// they are now for its long-term average).
    fn calm_down(&mut self, report: &mut CycleReport) {
        self.mode = Mode::Tracking;
        self.ekf_awake = false;
        self.calm = 0;
        self.cluster = None;
        self.bank.clear();
        if let (Some(j), Some(test)) = (self.judge.as_mut(), &self.cfg.place_test) {
            j.clear(test);
        }
        self.fit.1 = self.fit.0;
        self.misfit = 0;
        self.counts.calmed = self.counts.calmed.saturating_add(1);
        report.calmed = true;
    }

    /// The EKF starts at `x` with covariance `p` (its variances at least
    /// the floor's), then takes the cycle's odometry if `offset` says so
    /// (the cluster's mean is at the cycle's start; a place is already at
    /// the next one's).
    fn handoff(&mut self, x: [f32; 3], mut p: [[f32; 3]; 3], offset: Option<&Motion>) -> Result<(), LocalizeError> {
        self.ekf_awake = false;
        self.calm = 0;
        let f = &self.cfg.handoff_sigma_floor;
        for (i, (row, f)) in (0..3).zip(p.iter_mut().zip(f)) {
            if let Some(v) = row.get_mut(i) {
                *v = v.max(f * f);
            }
        }
        self.referencer.ekf.relocate(x, p)?;
        if let Some(offset) = offset {
            self.referencer.ekf.predict(offset)?;
        }
        self.mode = Mode::Tracking;
        self.converged = 0;
        self.cluster = None;
        self.bank.clear();
        if let (Some(j), Some(test)) = (self.judge.as_mut(), &self.cfg.place_test) {
            j.clear(test);
            j.behind = 0.0;
        }
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
        self.bank.clear();
        // With rivals the place that was gaining on the tracked pose keeps
        // its record.
        if let (Some(j), Some(test)) = (self.judge.as_mut(), &self.cfg.place_test) {
            j.clear(test);
        }
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
    /// bank's places away from it, each with the cluster's lead over it
    /// summed over every cycle since it was found (nats). For a viewer
    /// (`echoloc-lab`'s `/hypotheses`); the search itself reads the fields.
    pub fn hypotheses(&self) -> (Option<&Cluster>, &[Hypothesis]) {
        match self.mode {
            Mode::Searching => (self.cluster.as_ref(), self.bank.members()),
            _ => (None, &[]),
        }
    }

    /// The place test's living places (with `place_test` set; at the last
    /// cycle's end, carried to the next cycle's start): each with its pose,
    /// covariance and evidence over the null. For a viewer.
    pub fn places(&self) -> Option<&Places<PLACES>> {
        self.judge.as_ref().map(|j| &j.places)
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
