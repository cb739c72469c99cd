//! The run through the core, reading by reading, as the firmware runs it:
//! dead reckoning from the odometry alone; the paper's threshold method on
//! its own predictions; and the EKF ([`Referencer`](echoloc::referencing::Referencer)) with the quantised
//! credence net, predicting each transducer at the current estimate before
//! judging its reading.

use echoloc::credence::net::CredenceNet;
use echoloc::driver::SpeedOfSound;
use echoloc::localize::{self, Localizer, LocalizerConfig, Mode, PlaceTest};
use echoloc::map::{FieldView, MapSource};
use echoloc::predict::{Mount, PredictParams};
use echoloc::referencing::calibration::{CalibrationConfig, HeadingBias};
use echoloc::referencing::{
    observe, pose_mm, Ekf, EkfConfig, Motion, MountM, Reading, RecoveryConfig, Threshold, ThresholdConfig, Update,
    Verdict, VerdictConfig, VerdictCounts,
};
use echoloc::scenario::{Header, Record};
use echoloc::window::WindowParams;

use super::world::wrap;

/// The three estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Methods {
    /// Odometry alone.
    DeadReckoning,
    /// The paper's threshold method.
    Threshold,
    /// The EKF.
    Ekf,
}

/// What the EKF's verdict said of one reading, for detection scores.
#[derive(Clone, Copy, Debug, Default)]
pub struct Judged {
    /// Flagged an unmapped object (an unknown obstacle, or an echo where nothing was predicted).
    pub unknown: bool,
    /// Flagged a removed obstacle or a missed echo.
    pub removed: bool,
    /// The obstacle the prediction named.
    pub predicted_obstacle: Option<u16>,
    /// The EKF's verdict (for recordings, `crate::foxglove`).
    pub verdict: Option<Verdict>,
    /// The predicted range, mm.
    pub predicted_mm: Option<u32>,
    /// What the EKF did with it.
    pub update: Option<Update>,
    /// The prediction's κ.
    pub kappa: Option<f32>,
    /// Its echo point's angle off the axis, millidegrees.
    pub theta_mdeg: Option<i32>,
    /// Its cone arc deviation, millidegrees.
    pub delta_mdeg: Option<i32>,
    /// Which of the paper's cases gave it.
    pub case: Option<echoloc::predict::Case>,
}

/// Error figures of one estimate against the truth, over every reading.
#[derive(Clone, Copy, Debug, Default)]
pub struct Errors {
    /// Position RMSE, m.
    pub position_rmse_m: f64,
    /// Heading RMSE, degrees.
    pub heading_rmse_deg: f64,
    /// Largest position error, m.
    pub max_position_m: f64,
    /// At the end, m.
    pub final_position_m: f64,
    /// At the end, degrees.
    pub final_heading_deg: f64,
}

/// Everything the run produced, one entry per reading.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// Firing times, s.
    pub times: Vec<f64>,
    /// True poses (x m, y m, φ rad), where known.
    pub truth: Vec<Option<[f64; 3]>>,
    /// Dead reckoning.
    pub dead_reckoning: Vec<[f64; 3]>,
    /// The threshold method.
    pub threshold: Vec<[f64; 3]>,
    /// The EKF.
    pub ekf: Vec<[f64; 3]>,
    /// The EKF's verdicts.
    pub verdicts: VerdictCounts,
    /// Per reading, for detection scores.
    pub judged: Vec<Judged>,
    /// Readings the EKF accepted.
    pub accepted: u64,
    /// Readings its gate rejected.
    pub gated: u64,
    /// Of those accepted, the ones only their scaled variance let in
    /// (`CycleUpdates::weak`: not confirmed at the estimate, and past the
    /// plain gate); the lost monitor does not count them as validating.
    pub weak: u64,
    /// Times it became lost.
    pub lost_count: u32,
    /// Times it stopped being lost.
    pub lost_cleared: u32,
    /// Cycles it ended lost.
    pub cycles_lost: u32,
    /// Times a lost filter took a recovered pose.
    pub recoveries: u32,
    /// Readings that moved the threshold method's pose.
    pub threshold_corrections: u32,
    /// Distance driven, m: along the truth where every reading has one,
    /// else along the odometry.
    pub distance_m: f64,
    /// The EKF's final covariance (m², m·rad, rad²).
    pub covariance: [[f32; 3]; 3],
    /// Duration, s.
    pub duration_s: f64,
    /// The EKF's odometry calibration at the end, if it made one.
    pub calibration: Option<HeadingBias>,
    /// One row per ring cycle: what the localizer reported at its end.
    pub cycles: Vec<CycleRow>,
    /// The particle cloud at the moments that matter (the start, before each
    /// hand-off, at each wake-up and at the times asked for).
    pub clouds: Vec<Cloud>,
    /// The cloud at every cycle's end that held particles, when asked.
    pub cycle_clouds: Vec<CycleCloud>,
    /// With the place test: its living places at every searching cycle's
    /// end that had some (carried to the next cycle's start), as a viewer
    /// shows them: (the row of [`Trace::cycles`], the places).
    pub cycle_places: Vec<(usize, Vec<PlaceRow>)>,
    /// The localizer's counts.
    pub localizer: localize::LocalizerCounts,
    /// Per reading: the localizer's mode after it.
    pub modes: Vec<Mode>,
    /// Per reading: the estimate's covariance after it, upper triangle
    /// xx, xy, xφ, yy, yφ, φφ (m², m·rad, rad²).
    pub covariance_after: Vec<[f32; 6]>,
}

/// One of the place test's living places at a cycle's end.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaceRow {
    /// Its pose (x m, y m, φ rad) ...
    pub pose: [f32; 3],
    /// ... its position covariance (σ²x, σxy, σ²y) ...
    pub covariance: [f32; 3],
    /// ... its evidence over the null, nats ...
    pub evidence: f32,
    /// ... its smallest lead over the null and every other as the test
    /// counts it (the hand-off at the bound), nats ...
    pub margin: f32,
    /// ... and the cycles it has lived.
    pub cycles: u16,
}

/// What the localizer reported at the end of a ring cycle.
#[derive(Clone, Copy, Debug)]
pub struct CycleRow {
    /// The cycle's last firing, s.
    pub time_s: f64,
    /// The cycle's mode.
    pub mode: Mode,
    /// The estimate after the cycle (x m, y m, φ rad) ...
    pub state: [f32; 3],
    /// ... and its covariance.
    pub covariance: [[f32; 3]; 3],
    /// The true pose at the cycle's last firing, where known.
    pub truth: Option<[f64; 3]>,
    /// The EKF took over at this cycle's end.
    pub handoff: bool,
    /// The particles woke at this cycle's end.
    pub woke: bool,
    /// The search ended because the EKF beside it was no longer lost.
    pub calmed: bool,
    /// Particles weighed (while searching).
    pub particles: u16,
    /// Particles held after the cycle (what a cloud of it shows).
    pub held: u16,
    /// How far the heaviest cluster led the best place found elsewhere on
    /// the last cycles' readings, nats (while searching).
    pub lead: f32,
    /// With the place test, how far the EKF's pose trails the null, nats
    /// (the CUSUM that says *lost* at the bound).
    pub behind: f32,
    /// While searching, the heaviest cluster after the cycle: its mean, its
    /// position covariance (σ²x, σxy, σ²y) and its weight ...
    pub cluster: Option<([f32; 3], [f32; 3], f32)>,
    /// ... and the strongest place of the hypothesis bank away from it with
    /// the cluster's lead over it (nats) ...
    pub rival: Option<([f32; 3], f32)>,
    /// ... and how many places the search weighs: the cluster and the
    /// bank's.
    pub hypotheses: u8,
    /// The heaviest cluster's weight (while searching).
    pub cluster_weight: f32,
    /// Distance driven since the start, m (along the truth where known,
    /// else the odometry).
    pub distance_m: f64,
}

/// The particles at one moment.
#[derive(Clone, Debug)]
pub struct Cloud {
    /// When, s.
    pub time_s: f64,
    /// Why: "start", "handoff", "wake", or "asked".
    pub why: &'static str,
    /// The particles (x m, y m, φ rad).
    pub particles: Vec<[f32; 3]>,
}

/// The particles at a cycle's end, with their weights (kept when
/// [`Start::cycle_clouds`] asks, for the recordings' `/particles`).
#[derive(Clone, Debug)]
pub struct CycleCloud {
    /// The row of [`Trace::cycles`] it ends.
    pub cycle: usize,
    /// The particles (x m, y m, φ rad) ...
    pub poses: Vec<[f32; 3]>,
    /// ... and their weights as the set holds them (summing to 1).
    pub weights: Vec<f32>,
}

impl Trace {
    /// One CSV row per reading (`--readings-csv`): the time, the reading,
    /// the prediction at the estimate (range, κ, θ, δ, case), the verdict,
    /// what the EKF did (its innovation and ν²/S), the estimate and the truth.
    pub fn readings_csv(&self, steps: &[Step]) -> String {
        let mut out = String::from(
            "time_s,cycle,transducer,range_mm,predicted_mm,kappa,theta_deg,delta_deg,case,verdict,update,innovation_m,nis,x_m,y_m,theta_rad,ref_x_m,ref_y_m,ref_theta_rad\n",
        );
        let opt = |v: Option<String>| v.unwrap_or_default();
        for ((s, j), (e, t)) in steps.iter().zip(&self.judged).zip(self.ekf.iter().zip(&self.truth)) {
            let (update, innovation, nis) = match j.update {
                Some(Update::Accepted { innovation, nis }) => ("accepted", Some(innovation), Some(nis)),
                Some(Update::Gated { innovation, nis }) => ("gated", Some(innovation), Some(nis)),
                Some(Update::Unusable) => ("unusable", None, None),
                None => ("", None, None),
            };
            let range = match s.reading {
                Reading::Echo { range_mm } => range_mm.to_string(),
                _ => String::new(),
            };
            out.push_str(&format!(
                "{:.6},{},{},{range},{},{},{},{},{},{},{update},{},{},{:.6},{:.6},{:.6},{},{},{}\n",
                s.time_s,
                s.cycle,
                s.transducer,
                opt(j.predicted_mm.map(|v| v.to_string())),
                opt(j.kappa.map(|k| format!("{k:.4}"))),
                opt(j.theta_mdeg.map(|v| format!("{:.3}", f64::from(v) / 1000.0))),
                opt(j.delta_mdeg.map(|v| format!("{:.3}", f64::from(v) / 1000.0))),
                opt(j.case.map(|c| format!("{c:?}"))),
                opt(j.verdict.map(|v| format!("{v:?}"))),
                opt(innovation.map(|v| format!("{v:.4}"))),
                opt(nis.map(|v| format!("{v:.3}"))),
                e[0],
                e[1],
                e[2],
                opt(t.map(|t| format!("{:.6}", t[0]))),
                opt(t.map(|t| format!("{:.6}", t[1]))),
                opt(t.map(|t| format!("{:.6}", t[2]))),
            ));
        }
        out
    }

    fn track(&self, m: Methods) -> &[[f64; 3]] {
        match m {
            Methods::DeadReckoning => &self.dead_reckoning,
            Methods::Threshold => &self.threshold,
            Methods::Ekf => &self.ekf,
        }
    }

    /// Position and heading errors of `m` at each reading that has a true
    /// pose: (time s, position error m, heading error degrees).
    pub fn error_series(&self, m: Methods) -> Vec<(f64, f64, f64)> {
        self.track(m)
            .iter()
            .zip(&self.truth)
            .zip(&self.times)
            .filter_map(|((e, t), &time)| {
                t.map(|t| (time, (e[0] - t[0]).hypot(e[1] - t[1]), wrap(e[2] - t[2]).to_degrees()))
            })
            .collect()
    }

    /// Error figures of `m`; `None` when no reading has a true pose.
    pub fn errors(&self, m: Methods) -> Option<Errors> {
        let s = self.error_series(m);
        let last = *s.last()?;
        let n = s.len() as f64;
        let (p2, h2) = s.iter().fold((0.0, 0.0), |(a, b), (_, p, h)| (a + p * p, b + h * h));
        Some(Errors {
            position_rmse_m: (p2 / n).sqrt(),
            heading_rmse_deg: (h2 / n).sqrt(),
            max_position_m: s.iter().map(|e| e.1).fold(0.0, f64::max),
            final_position_m: last.1,
            final_heading_deg: last.2.abs(),
        })
    }

    /// The final estimate of `m`.
    pub fn final_pose(&self, m: Methods) -> Option<[f64; 3]> {
        self.track(m).last().copied()
    }

    /// Every estimate of `m`, one per reading.
    pub fn poses(&self, m: Methods) -> &[[f64; 3]] {
        self.track(m)
    }
}

/// One reading as the filters take it: what the firmware's loop has after
/// the driver (a range, or none) and the odometry since the previous one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// Firing time, s.
    pub time_s: f64,
    /// Ring cycle: the lost monitor closes a cycle when it changes.
    pub cycle: u32,
    /// Transducer index.
    pub transducer: u8,
    /// Odometry since the previous step, in its frame.
    pub odometry: Motion,
    /// The reading.
    pub reading: Reading,
    /// The true (reference) pose, where known.
    pub truth: Option<[f32; 3]>,
}

/// What the localizer is told of the start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StartMode {
    /// The pose, with its σ: the EKF tracks from the first reading.
    Known,
    /// Near the pose, within its σ: the particles search around it.
    Around,
    /// Nothing: the particles search all free space.
    Unknown,
}

/// Particles of the lab's localizer (the boards' figure).
pub const PARTICLES: usize = 1024;

/// Where the filters start: the pose and its standard deviations (m, m, rad).
#[derive(Clone, Debug, PartialEq)]
pub struct Start {
    /// x m, y m, φ rad.
    pub pose: [f32; 3],
    /// Standard deviations.
    pub sigma: [f32; 3],
    /// What the localizer is told (the dead reckoning and the threshold
    /// method start at `pose` whatever this is).
    pub mode: StartMode,
    /// Seed of the particles' draws.
    pub seed: u64,
    /// Times (s) at which to keep the particle cloud.
    pub snapshots: Vec<f64>,
    /// Whether to keep the cloud at every cycle's end that holds particles
    /// ([`Trace::cycle_clouds`]; 16 B a particle a cycle: for recordings).
    pub cycle_clouds: bool,
    /// Which parts of the filters run.
    pub switches: Switches,
}

/// The switches `simulate` takes for the filters (`--no-robust`,
/// `--bank` …), the same whatever the readings' source (a simulated
/// world or a lidar run).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Switches {
    /// Whether a lost EKF may recover (`echoloc::referencing::recovery`);
    /// off only to measure what recovery does.
    pub recovery: bool,
    /// Whether doubtful readings are weighted down (`EkfConfig::robust_nis`);
    /// off only to measure what that does.
    pub robust: bool,
    /// Whether the EKF learns the odometry's systematic heading errors
    /// (`echoloc::referencing::calibration`); off only to measure what that does.
    pub calibration: bool,
    /// Whether predictions carry the nearer-surface check
    /// (`PredictParams::nearer_delta_deg`, which makes echoes a nearer mapped
    /// surface may have returned inconclusive); off only to measure what it does.
    pub nearer_check: bool,
    /// Whether the localizer has particles to search with when lost (off:
    /// the EKF alone, as before issue #27).
    pub particles: bool,
    /// The hand-off's margin over the hypothesis bank
    /// (`LocalizerConfig::handoff_z`); `None`: the default.
    pub handoff_z: Option<f32>,
    /// The places the hypothesis bank keeps (`LocalizerConfig::bank_keep`);
    /// `None`: the default.
    pub bank: Option<u8>,
    /// The sequential test's bound (`LocalizerConfig::place_test`, the
    /// rest `PlaceTest::DEFAULT`); `None`: the cluster's hand-off.
    pub place_test: Option<f32>,
    /// With the place test, the nodes the sweep scores a tracking cycle to
    /// propose rivals to the tracked pose (`PlaceTest::rival_nodes`; 0: none).
    pub rival_nodes: u16,
    /// With the place test, `PlaceTest::hit_share`; `None`: the default.
    pub hit_share: Option<f32>,
    /// With the place test, `PlaceTest::calm_behind`; `None`: the default.
    pub calm_behind: Option<f32>,
    /// With the place test, `PlaceTest::join_beside`.
    pub join_beside: bool,
    /// `EkfConfig::unconfirmed_variance_scale`; `None`: the default.
    pub unconfirmed_variance_scale: Option<f32>,
}

impl Switches {
    /// Every part on, the defaults.
    pub const EVERYTHING: Self = Self {
        recovery: true,
        robust: true,
        calibration: true,
        nearer_check: true,
        particles: true,
        handoff_z: None,
        bank: None,
        place_test: None,
        rival_nodes: 0,
        hit_share: None,
        calm_behind: None,
        join_beside: false,
        unconfirmed_variance_scale: None,
    };
}

impl Start {
    /// At `pose` with standard deviations `sigma`, every part of the EKF on.
    pub fn with_everything(pose: [f32; 3], sigma: [f32; 3]) -> Self {
        Self {
            pose,
            sigma,
            mode: StartMode::Known,
            seed: 1,
            snapshots: Vec::new(),
            cycle_clouds: false,
            switches: Switches::EVERYTHING,
        }
    }
}

/// A scenario's records as steps: ranges from the echo times by the
/// scenario's speed of sound, firing times unwrapped (they wrap at 2³² µs,
/// 71 min).
pub fn steps_of_records(header: &Header, records: &[Record]) -> Result<Vec<Step>, String> {
    let sound = SpeedOfSound::from_um_per_s(header.speed_um_per_s).map_err(|e| format!("speed of sound: {e:?}"))?;
    let mut clock = crate::clock::Unwrap::default();
    Ok(records
        .iter()
        .map(|r| Step {
            time_s: clock.next(r.time_us) as f64 / 1e6,
            cycle: r.cycle,
            transducer: r.transducer,
            odometry: Motion { dx: r.odometry[0], dy: r.odometry[1], dphi: r.odometry[2] },
            reading: match r.echo_us {
                Some(us) => Reading::Echo { range_mm: sound.range_mm(us) },
                None => Reading::NoEcho,
            },
            truth: Some(r.truth),
        })
        .collect())
}

/// The prediction settings of the boards: the Polaroid 6500's window on the
/// map's buffer (`buffer_mm`) and its face lobe, from its localization
/// `field` (`WindowParams::with_map_lobe`).
pub fn predict_params(buffer_mm: u32, field: &FieldView<'_>) -> PredictParams {
    PredictParams::new(WindowParams { tb_mm: buffer_mm, ..WindowParams::POLAROID_6500 }.with_map_lobe(field))
}

/// [`predict_params`], without the nearer-surface check unless
/// `nearer_check` (off only to measure what it does).
pub fn predict_params_with(buffer_mm: u32, field: &FieldView<'_>, nearer_check: bool) -> PredictParams {
    let mut params = predict_params(buffer_mm, field);
    if !nearer_check {
        params.nearer_delta_deg = None;
    }
    params
}

fn compose(x: [f64; 3], u: &Motion) -> [f64; 3] {
    let (s, c) = x[2].sin_cos();
    let (dx, dy) = (f64::from(u.dx), f64::from(u.dy));
    [x[0] + c * dx - s * dy, x[1] + s * dx + c * dy, wrap(x[2] + f64::from(u.dphi))]
}

fn f64x3(v: [f32; 3]) -> [f64; 3] {
    v.map(f64::from)
}

/// Runs every step through the three estimates; the EKF inside the
/// localizer (with [`PARTICLES`] particles, or none when `start.switches.particles`
/// is off) on the map's localization `field`.
pub fn run<M: MapSource>(
    map: &M,
    field: &FieldView<'_>,
    mounts: &[Mount],
    start: &Start,
    steps: &[Step],
    progress: &mut dyn FnMut(f64),
) -> Result<Trace, String> {
    if start.switches.particles {
        run_with::<M, PARTICLES>(map, field, mounts, start, steps, progress)
    } else {
        run_with::<M, 0>(map, field, mounts, start, steps, progress)
    }
}

fn run_with<M: MapSource, const N: usize>(
    map: &M,
    field: &FieldView<'_>,
    mounts: &[Mount],
    start: &Start,
    steps: &[Step],
    progress: &mut dyn FnMut(f64),
) -> Result<Trace, String> {
    let net = CredenceNet::shipped();
    let params = predict_params_with(map.buffer_mm(), field, start.switches.nearer_check);
    let verdicts = VerdictConfig::POLAROID;
    let mut cfg = EkfConfig::DEFAULT;
    if !start.switches.recovery {
        cfg.recovery = RecoveryConfig::OFF;
    }
    if !start.switches.robust {
        cfg.robust_nis = f32::INFINITY;
    }
    if !start.switches.calibration {
        cfg.calibration = CalibrationConfig::OFF;
    }
    if let Some(x) = start.switches.unconfirmed_variance_scale {
        cfg.unconfirmed_variance_scale = x;
    }
    // Checked as `Ekf::new` checks it, for the message.
    Ekf::new(start.pose, start.sigma, cfg).map_err(|e| format!("start: {e:?}"))?;
    let how = match start.mode {
        StartMode::Known => localize::Start::Known { pose: start.pose, sigma: start.sigma },
        StartMode::Around => localize::Start::Around { pose: start.pose, sigma: start.sigma },
        StartMode::Unknown => localize::Start::Unknown,
    };
    let d = LocalizerConfig::DEFAULT;
    let lcfg = LocalizerConfig {
        handoff_z: start.switches.handoff_z.unwrap_or(d.handoff_z),
        bank_keep: start.switches.bank.unwrap_or(d.bank_keep),
        place_test: start.switches.place_test.map(|bound| PlaceTest {
            bound,
            rival_nodes: start.switches.rival_nodes,
            hit_share: start.switches.hit_share.unwrap_or(PlaceTest::DEFAULT.hit_share),
            calm_behind: start.switches.calm_behind.unwrap_or(PlaceTest::DEFAULT.calm_behind),
            join_beside: start.switches.join_beside,
            ..PlaceTest::DEFAULT
        }),
        ..d
    };
    let mut loc: Box<Localizer<N>> = Box::new(Localizer::new(lcfg, cfg, verdicts, start.seed));
    loc.start(how, field).map_err(|e| format!("start: {e}"))?;
    if N > 0 {
        loc.check_ring(mounts, field).map_err(|e| format!("--ring: {e}"))?;
    }
    let mut thr = Threshold::new(start.pose, ThresholdConfig::DEFAULT);
    let mut dr = f64x3(start.pose);
    let mut t = Trace::default();
    let mut cycle = steps.first().map_or(0, |r| r.cycle);
    let mut prev_truth: Option<[f64; 3]> = None;
    let mut odometry_m = 0.0;
    let all_true = steps.iter().all(|s| s.truth.is_some());
    let mut snapshots: Vec<f64> = start.snapshots.clone();
    snapshots.sort_by(f64::total_cmp);
    if loc.mode() == Mode::Searching {
        t.clouds.push(Cloud {
            time_s: steps.first().map_or(0.0, |s| s.time_s),
            why: "start",
            particles: loc.particles().poses().to_vec(),
        });
    }
    let mut last: Option<(f64, Option<[f64; 3]>)> = None;
    let cycle_clouds = start.cycle_clouds;
    let mut close = |loc: &mut Localizer<N>, t: &mut Trace, last: Option<(f64, Option<[f64; 3]>)>, travelled: f64| {
        let before = loc.particles().poses().to_vec();
        let rep = loc.end_cycle(field).map_err(|e| format!("{e}"))?;
        t.weak += u64::from(rep.updates.weak);
        let (time_s, truth) = last.unwrap_or((0.0, None));
        if rep.handoff {
            t.clouds.push(Cloud { time_s, why: "handoff", particles: before });
        } else if rep.woke {
            t.clouds.push(Cloud { time_s, why: "wake", particles: loc.particles().poses().to_vec() });
        }
        while snapshots.first().is_some_and(|&s| s <= time_s) {
            snapshots.remove(0);
            if !loc.particles().is_empty() && loc.mode() == Mode::Searching {
                t.clouds.push(Cloud { time_s, why: "asked", particles: loc.particles().poses().to_vec() });
            }
        }
        let places = match (loc.places(), rep.mode) {
            // Searching, or tracking with rivals (the tracked pose among them).
            (Some(b), m) if !rep.handoff && (m == Mode::Searching || rep.hypotheses > 0) => (0..b.living().len())
                .map(|i| {
                    let p = &b.living()[i];
                    let c = p.covariance();
                    PlaceRow {
                        pose: p.pose(),
                        covariance: [c[0][0], c[0][1], c[1][1]],
                        evidence: p.evidence(),
                        margin: b.margin_of(i),
                        cycles: p.cycles(),
                    }
                })
                .collect(),
            _ => Vec::new(),
        };
        if !places.is_empty() {
            t.cycle_places.push((t.cycles.len(), places));
        }
        let (cluster, bank) = loc.hypotheses();
        let rival = bank.iter().min_by(|a, b| a.lead.total_cmp(&b.lead)).map(|h| (h.pose, h.lead));
        let cluster = cluster.map(|c| {
            let p = c.covariance;
            (c.mean, [p[0][0], p[0][1], p[1][1]], c.weight)
        });
        // The cloud the search goes on with (none while tracking, nor once
        // the search has handed off).
        let held = if rep.mode == Mode::Tracking || rep.handoff { 0 } else { loc.particles().len() };
        if cycle_clouds && held > 0 {
            t.cycle_clouds.push(CycleCloud {
                cycle: t.cycles.len(),
                poses: loc.particles().poses().to_vec(),
                weights: loc.particles().weights().to_vec(),
            });
        }
        t.cycles.push(CycleRow {
            time_s,
            mode: rep.mode,
            state: loc.state(),
            covariance: loc.covariance(),
            truth,
            handoff: rep.handoff,
            woke: rep.woke,
            calmed: rep.calmed,
            particles: rep.particles,
            held: held as u16,
            lead: rep.lead,
            behind: rep.behind,
            cluster,
            rival,
            hypotheses: rep.hypotheses,
            cluster_weight: rep.cluster_weight,
            distance_m: travelled,
        });
        Ok::<(), String>(())
    };
    for (i, r) in steps.iter().enumerate() {
        if r.cycle != cycle {
            let travelled = if all_true { t.distance_m } else { odometry_m };
            close(&mut loc, &mut t, last, travelled)?;
            cycle = r.cycle;
        }
        let mount = mounts
            .get(usize::from(r.transducer))
            .ok_or_else(|| format!("reading {i}: no transducer {}", r.transducer))?;
        let u = r.odometry;
        let before = dr;
        dr = compose(dr, &u);
        odometry_m += (dr[0] - before[0]).hypot(dr[1] - before[1]);
        thr.predict(&u);
        loc.odometry(&u).map_err(|e| format!("reading {i}: {e}"))?;
        let reading = r.reading;
        // The threshold method predicts from its own pose.
        let o = observe(map, &pose_mm(thr.state()), mount, &params, &net, reading, &verdicts)
            .map_err(|e| format!("reading {i}: {e:?}"))?;
        if let (Reading::Echo { range_mm }, Some(p), Some(target)) = (reading, o.prediction, o.target) {
            thr.update(range_mm as f32 / 1000.0, p.kappa.to_num::<f32>(), MountM::from(mount), &target);
        }
        let rep = loc.reading(map, mount, &params, &net, reading).map_err(|e| format!("reading {i}: {e}"))?;
        match rep.update {
            Some(Update::Accepted { .. }) => t.accepted += 1,
            Some(Update::Gated { .. }) => t.gated += 1,
            _ => {}
        }
        t.judged.push(Judged {
            unknown: matches!(rep.verdict, Verdict::UnknownObstacle | Verdict::Unpredicted),
            removed: rep.verdict == Verdict::RemovedOrMissed,
            predicted_obstacle: rep.prediction.map(|p| p.obstacle),
            verdict: Some(rep.verdict),
            predicted_mm: rep.prediction.map(|p| p.range_mm),
            update: rep.update,
            kappa: rep.prediction.map(|p| p.kappa.to_num::<f32>()),
            theta_mdeg: rep.prediction.map(|p| p.theta_mdeg),
            delta_mdeg: rep.prediction.map(|p| p.delta_mdeg),
            case: rep.prediction.map(|p| p.case),
        });
        let truth = r.truth.map(f64x3);
        if let (Some(p), Some(q)) = (prev_truth, truth) {
            t.distance_m += (q[0] - p[0]).hypot(q[1] - p[1]);
        }
        prev_truth = truth.or(prev_truth);
        last = Some((r.time_s, truth));
        t.times.push(r.time_s);
        t.truth.push(truth);
        t.dead_reckoning.push(dr);
        t.threshold.push(f64x3(thr.state()));
        t.ekf.push(f64x3(loc.state()));
        let p = loc.covariance();
        t.covariance_after.push([p[0][0], p[0][1], p[0][2], p[1][1], p[1][2], p[2][2]]);
        t.modes.push(loc.mode());
        if i % 256 == 0 {
            progress(i as f64 / steps.len().max(1) as f64);
        }
    }
    let travelled = if all_true { t.distance_m } else { odometry_m };
    close(&mut loc, &mut t, last, travelled)?;
    if !all_true {
        t.distance_m = odometry_m;
    }
    let ekf = &loc.referencer().ekf;
    t.covariance = loc.covariance();
    t.calibration = ekf.calibration().estimate();
    t.verdicts = loc.referencer().totals();
    t.lost_count = ekf.lost_count();
    // Every time it became lost but the last was cleared, and that one too unless it is still lost.
    t.lost_cleared = t.lost_count - u32::from(ekf.is_lost());
    t.cycles_lost = ekf.cycles_lost();
    t.recoveries = ekf.recoveries();
    t.threshold_corrections = thr.corrections();
    t.localizer = loc.counts();
    t.duration_s = t.times.last().copied().unwrap_or(0.0) - t.times.first().copied().unwrap_or(0.0);
    Ok(t)
}
