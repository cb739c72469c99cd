//! `echoloc-lab simulate`: a run on the simulator ([`crate::simulate`]),
//! reported as JSON, with its figures, a scenario file for the boards, the
//! readings, the log, the trace, a bag and a Foxglove recording on request;
//! with `--from-scans`, a run on a lidar robot's scans ([`crate::from_scans`]).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Args;
use echoloc::scenario::{self, Header, Record};

use crate::map::LabError;
use crate::predict::ring_mounts;
use crate::simulate::world::{self, SimRun, WorldConfig};
use crate::simulate::{
    agreement, apply_start, check_writable, error_plot_path, figures, filters, localization, log_of, report, rows_of,
    start_of, to_records, write_all, BOUNDS, START_SIGMA,
};

/// `simulate`.
#[derive(Args)]
pub struct SimulateArgs {
    /// The map: a blob (.map), a ROS map_server .yaml or a .geojson.
    #[arg(long)]
    map: PathBuf,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Route length, m.
    #[arg(long = "distance-m", default_value_t = 200.0, allow_hyphen_values = true)]
    distance_m: f64,
    /// Fraction of readings inconsistent with the map (unmapped people and
    /// furniture, mapped obstacles removed), 0..=1.
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    inconsistent: f64,
    /// The ring: pioneer16, or a JSON file of [x_m, y_m, heading_deg] per transducer.
    #[arg(long, default_value = "pioneer16")]
    ring: String,
    /// C-space buffer for a .yaml or .geojson map, mm.
    #[arg(long = "buffer-mm", default_value_t = 100)]
    buffer_mm: u32,
    /// How a .yaml map's walls are drawn.
    #[command(flatten)]
    grid: crate::map::load::GridArgs,
    /// One JSON object (the default prints the same, indented).
    #[arg(long)]
    json: bool,
    /// Writes the map with the paths to OUT.png and the error over time to
    /// OUT-error.png (SVG for OUT.svg).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Writes the run as a binary scenario (docs/scenario.md).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Writes the run as a plain CSV log (docs/log.md), with the true pose as
    /// the reference: `echoloc-lab replay` on it gives this run's figures.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Writes the run as a Foxglove recording (MCAP, docs/foxglove.md).
    #[arg(long)]
    mcap: Option<PathBuf>,
    /// Writes the run as a ROS 2 bag (a new rosbag2 directory, MCAP storage,
    /// docs/bags.md): the rows --log writes as Range topics, the ring on
    /// /tf_static, /odom and the true pose as /ground_truth.
    #[arg(long)]
    bag: Option<PathBuf>,
    /// The EKF without recovery while lost, to measure what it does.
    #[arg(long = "no-recovery")]
    no_recovery: bool,
    /// The EKF without Huber's down-weighting of doubtful readings
    /// (`EkfConfig::robust_nis`), to measure what it does.
    #[arg(long = "no-robust")]
    no_robust: bool,
    /// The EKF without learning the odometry's systematic heading errors
    /// (`EkfConfig::calibration`), to measure what it does.
    #[arg(long = "no-calibration")]
    no_calibration: bool,
    /// Predictions without the nearer-surface check
    /// (`PredictParams::nearer_delta_deg`), to measure what it does.
    #[arg(long = "no-nearer-check")]
    no_nearer_check: bool,
    /// The filters are given only the readings consistent with the map, the
    /// others as silence: an oracle of the clutter, to tell the filter's
    /// failures from what the scene leaves to be seen. Not a method.
    #[arg(long = "only-consistent")]
    only_consistent: bool,
    /// What the localizer is told of the start: `unknown` (it searches the
    /// whole map), `x_m,y_m,θ_deg` (it tracks from there), or
    /// `x_m,y_m,θ_deg,σ_m,σ_deg` (it searches around there). Default: the
    /// true start, tracked.
    #[arg(long, allow_hyphen_values = true)]
    start: Option<String>,
    /// A kidnap, `T_s:dx_m,dy_m,dθ_deg`: at T_s the true robot is carried by
    /// (dx, dy) in the map and turned by dθ; the odometry does not see it.
    /// Repeatable.
    #[arg(long = "kidnap", allow_hyphen_values = true)]
    kidnap: Vec<String>,
    /// The EKF alone, without particles to search with when it is lost (the
    /// localizer before issue #27), to measure what they do.
    #[arg(long = "no-particles")]
    no_particles: bool,
    /// The hand-off's margin over the hypothesis bank: a place's summed
    /// lead less Z times the root of its cycles' squared leads must pass
    /// the hand-off's lead (`LocalizerConfig::handoff_z`; default 0), to
    /// measure what it does.
    #[arg(long = "handoff-z", value_parser = parse_handoff_z)]
    handoff_z: Option<f32>,
    /// The places the hypothesis bank keeps besides the cluster, 0–8
    /// (`LocalizerConfig::bank_keep`; default 1, #27's kept rival), to
    /// measure what more do.
    #[arg(long = "bank", value_parser = clap::value_parser!(u8).range(0..=8))]
    bank: Option<u8>,
    /// The hand-off decided by the sequential test between places that
    /// track themselves and the null, at this bound in nats
    /// (`LocalizerConfig::place_test`, issue #48; default: the cluster's
    /// hand-off). `--place-test 150` is `PlaceTest::DEFAULT`.
    #[arg(long = "place-test", value_parser = parse_bound)]
    place_test: Option<f32>,
    /// With --place-test: the places go on while tracking, the tracked
    /// pose among them, the sweep scoring N nodes a cycle to propose
    /// rivals; one that leads the tracked pose, the null and every other
    /// by the bound takes over (`PlaceTest::rival_nodes`, issue #48 item 4;
    /// default 0, none).
    #[arg(long = "place-rivals", value_name = "N", requires = "place_test")]
    place_rivals: Option<u16>,
    /// With --place-test: the share of the readings a place takes to be the
    /// echo the field expects, the rest scored as the null scores them
    /// (`PlaceTest::hit_share`, 0 < W < 1; default 0.5), to measure what it
    /// does.
    #[arg(long = "place-hit-share", value_name = "W", requires = "place_test", value_parser = parse_share)]
    place_hit_share: Option<f32>,
    /// With --place-test: after a wake-up the search ends without a
    /// hand-off only on cycles the EKF trails the null by at most X nats
    /// (`PlaceTest::calm_behind`, 0 ≤ X below the bound; default 0), to
    /// measure what it does.
    #[arg(long = "place-calm-behind", value_name = "X", requires = "place_test", value_parser = parse_nats)]
    place_calm_behind: Option<f32>,
    /// With --place-test: a proposal beside a living place (within a metre
    /// and 20°, farther than a merge) that scores the cycle better joins as
    /// a place of its own (`PlaceTest::join_beside`), to measure what it
    /// does.
    #[arg(long = "place-join-beside", requires = "place_test")]
    place_join_beside: bool,
    /// A reading the verdict does not confirm enters the EKF with its
    /// variance this many times larger (`EkfConfig::unconfirmed_variance_scale`,
    /// issue #49 item 3; default 16, measured in docs/real-buildings.md;
    /// 1: as a confirmed one).
    #[arg(long = "unconfirmed-variance-scale", value_name = "X", value_parser = parse_variance_scale)]
    unconfirmed_variance_scale: Option<f32>,
    /// Writes one CSV row per ring cycle: the mode, the estimate, its σ and
    /// the true pose (docs/localization.md).
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Writes one CSV row per reading: the reading, the prediction at the
    /// estimate, the verdict, what the EKF did, the estimate and the truth.
    #[arg(long = "readings-csv")]
    readings_csv: Option<PathBuf>,
    /// A run derived from a lidar run's scans instead (issue #35).
    #[command(flatten)]
    scans: crate::from_scans::cli::ScansArgs,
}

/// κ at and above which the predictor counts as confident when its
/// agreement with the simulated sonar is measured.
pub const AGREEMENT_KAPPA: f32 = 0.9;

pub fn simulate_cmd(a: &SimulateArgs) -> Result<String, LabError> {
    if !(a.distance_m.is_finite() && a.distance_m > 0.0) {
        return Err(LabError(format!("--distance-m {}: must be a positive number", a.distance_m)));
    }
    if !(0.0..=1.0).contains(&a.inconsistent) {
        return Err(LabError(format!("--inconsistent {}: must be within 0..=1", a.inconsistent)));
    }
    for p in a
        .plot
        .iter()
        .chain(a.plot.as_deref().map(error_plot_path).iter())
        .chain(a.scenario.iter())
        .chain(a.readings_csv.iter())
        .chain(a.log.iter())
        .chain(a.trace.iter())
        .chain(a.mcap.iter())
    {
        check_writable(p)?;
    }
    if let Some(b) = &a.bag {
        crate::bag::write::check_new_dir(b).map_err(|e| LabError(format!("--bag {e}")))?;
    }
    let start_arg =
        a.start.as_deref().map(|s| localization::parse_start(s, "--start")).transpose().map_err(LabError)?;
    let kidnaps =
        a.kidnap.iter().map(|s| localization::parse_kidnap(s)).collect::<Result<Vec<_>, _>>().map_err(LabError)?;
    if kidnaps.windows(2).any(|w| w[1].t_s <= w[0].t_s) {
        return Err(LabError("--kidnap: give the kidnaps in time order".into()));
    }
    let mounts = ring_mounts(&a.ring)?;
    if let Some(i) = mounts.iter().position(|m| !world::within_reach(m)) {
        return Err(LabError(format!(
            "--ring {}: transducer {i} is more than 2 m from the robot's centre (the simulator's robot is not that big)",
            a.ring
        )));
    }
    // A lidar run's own refusals come before the map's compilation.
    let scans = match &a.scans.from_scans {
        None => None,
        Some(_) => {
            if a.scenario.is_some() || !a.kidnap.is_empty() {
                return Err(LabError("--from-scans: --scenario and --kidnap do not apply to a lidar run".into()));
            }
            if a.only_consistent {
                return Err(LabError(
                    "--from-scans: --only-consistent needs the simulator's own world (a lidar run's readings are not labelled consistent or not)".into(),
                ));
            }
            let files = crate::from_scans::cli::Files {
                log: &a.log,
                plot: &a.plot,
                trace: &a.trace,
                mcap: &a.mcap,
                bag: &a.bag,
                readings_csv: &a.readings_csv,
            };
            Some(crate::from_scans::cli::prepare(&a.scans, &files)?)
        }
    };
    let loaded = crate::map::load::load(&a.map, &a.grid.options(a.buffer_mm, true))?;
    let switches = filters::Switches {
        recovery: !a.no_recovery,
        robust: !a.no_robust,
        calibration: !a.no_calibration,
        nearer_check: !a.no_nearer_check,
        particles: !a.no_particles,
        handoff_z: a.handoff_z,
        bank: a.bank,
        place_test: a.place_test,
        rival_nodes: a.place_rivals.unwrap_or(0),
        hit_share: a.place_hit_share,
        calm_behind: a.place_calm_behind,
        join_beside: a.place_join_beside,
        unconfirmed_variance_scale: a.unconfirmed_variance_scale,
    };
    if let Some(scans) = &scans {
        let common = crate::from_scans::cli::Common {
            map: &a.map,
            seed: a.seed,
            mounts,
            loaded: &loaded,
            json: a.json,
            start: start_arg,
            log: a.log.clone(),
            plot: a.plot.clone(),
            trace: a.trace.clone(),
            mcap: a.mcap.clone(),
            bag: a.bag.clone(),
            readings_csv: a.readings_csv.clone(),
            switches,
        };
        return crate::from_scans::cli::run(&common, &a.scans, scans);
    }
    let (map, map_crc) = (loaded.view()?, loaded.crc());
    let mut cfg = WorldConfig::new(a.seed, a.distance_m, a.inconsistent, mounts.clone());
    cfg.kidnaps = kidnaps;
    let mut bar = Progress::new();
    let run = world::simulate_world(&map, &cfg, &mut |f| bar.set(0.5 * f))
        .map_err(|e| LabError(format!("{}: {e}", a.map.display())))?;
    // A small map holds only so much clutter: say when the run has less
    // than asked (tb3_sandbox: 0.48 for 0.7), rather than pass it off.
    if run.inconsistent_fraction + 0.05 < a.inconsistent {
        eprintln!(
            "warning: --inconsistent {}: the clutter this map's world could place makes {:.2}; the run has that",
            a.inconsistent, run.inconsistent_fraction
        );
    }
    let records = to_records(&run.readings)?;
    let header = header(&run, map_crc, &records);
    let mut steps = filters::steps_of_records(&header, &records).map_err(LabError)?;
    if a.only_consistent {
        for (step, r) in steps.iter_mut().zip(&run.readings) {
            if !r.consistent {
                step.reading = echoloc::referencing::Reading::NoEcho;
            }
        }
    }
    let mut start = filters::Start {
        seed: a.seed,
        snapshots: run.kidnaps.iter().map(|k| k.0).collect(),
        cycle_clouds: a.mcap.is_some(),
        switches,
        ..start_of(&header)
    };
    apply_start(&mut start, start_arg);
    let trace = filters::run(&map, map.field(), &mounts, &start, &steps, &mut |f| bar.set(0.5 + 0.5 * f))
        .map_err(|e| LabError(format!("{}: {e}", a.map.display())))?;
    bar.finish();
    let mut report = report(&trace, Some(&run));
    let agreement = agreement::measure(&map, map.field(), &mounts, &run.readings, AGREEMENT_KAPPA, !a.no_nearer_check);
    if let Some(o) = report.as_object_mut() {
        o.insert("agreement".into(), agreement.json());
        let kidnaps: Vec<f64> = run.kidnaps.iter().map(|k| k.0).collect();
        o.insert("localization".into(), localization::report(&trace, &kidnaps));
    }
    // Everything is computed before anything is written, and a failed
    // write takes back the files written before it.
    let mut outputs: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    if let Some(p) = &a.scenario {
        let mut bytes = Vec::new();
        scenario::write(&header, &mounts, &records, |b| bytes.extend_from_slice(b))
            .map_err(|e| LabError(format!("--scenario {}: {e}", p.display())))?;
        outputs.push((p.clone(), bytes));
    }
    if let Some(p) = &a.log {
        outputs.push((p.clone(), log_of(&run.readings, &steps).into_bytes()));
    }
    if let Some(p) = &a.trace {
        outputs.push((p.clone(), localization::trace_csv(&trace).into_bytes()));
    }
    if let Some(p) = &a.readings_csv {
        outputs.push((p.clone(), trace.readings_csv(&steps).into_bytes()));
    }
    if let Some(p) = &a.plot {
        let (paths, errors) =
            figures::draw_as(&map, &run.unmapped, &trace, crate::figure::Format::of(p)).map_err(LabError)?;
        outputs.push((p.clone(), paths));
        outputs.push((error_plot_path(p), errors));
    }
    if let Some(p) = &a.mcap {
        let rec = crate::foxglove::record(&map, &mounts, &steps, &trace, &run.unmapped)
            .map_err(|e| LabError(format!("--mcap: {e}")))?;
        outputs.push((p.clone(), rec.finish().map_err(|e| LabError(format!("--mcap: {e}")))?));
    }
    // The bag is a directory, written whole or not at all; it goes first
    // and is taken back if a file fails.
    if let Some(b) = &a.bag {
        let rows = rows_of(&run.readings, &steps);
        crate::bag::write::write_bag(b, &rows, &mounts, &Default::default())
            .map_err(|e| LabError(format!("--bag {e}")))?;
    }
    if let Err(e) = write_all(&outputs) {
        if let Some(b) = &a.bag {
            let _ = std::fs::remove_dir_all(b);
        }
        return Err(e);
    }
    Ok(if a.json { report.to_string() } else { serde_json::to_string_pretty(&report).unwrap_or_default() })
}

fn header(run: &SimRun, map_crc: u32, records: &[Record]) -> Header {
    let start = records.first().map_or([0.0; 3], |r| r.truth);
    Header {
        map_crc,
        speed_um_per_s: run.sound.um_per_s(),
        period_us: run.period_us,
        slot_us: run.slot_us,
        start,
        start_sigma: START_SIGMA,
        bound_position_m: BOUNDS.0,
        bound_heading_deg: BOUNDS.1,
    }
}

/// A progress bar on stderr, shown only once a run has taken a second.
struct Progress {
    start: Instant,
    bar: Option<indicatif::ProgressBar>,
}

impl Progress {
    fn new() -> Self {
        Self { start: Instant::now(), bar: None }
    }

    fn set(&mut self, f: f64) {
        if self.bar.is_none() && self.start.elapsed() > Duration::from_secs(1) {
            let b = indicatif::ProgressBar::with_draw_target(Some(1000), indicatif::ProgressDrawTarget::stderr());
            b.set_style(
                indicatif::ProgressStyle::with_template("simulate [{bar:40}] {percent:>3}% {elapsed}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            self.bar = Some(b);
        }
        if let Some(b) = &self.bar {
            b.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
        }
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

/// `--place-test`: a finite positive number of nats.
fn parse_bound(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(b) if b.is_finite() && b > 0.0 => Ok(b),
        _ => Err(format!("{s:?} is not a finite number of nats > 0")),
    }
}

/// `--place-calm-behind`: a finite number of nats, at least 0 (the bound
/// is checked by the localizer, which refuses one at or past it).
fn parse_nats(s: &str) -> Result<f32, String> {
    parse_at_least(s, 0.0)
}

/// `--place-hit-share`: strictly between 0 and 1 (at 0 no place gains on
/// any reading, at 1 a reading the field does not expect is impossible).
fn parse_share(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(w) if w > 0.0 && w < 1.0 => Ok(w),
        _ => Err(format!("{s:?} is not a share strictly between 0 and 1")),
    }
}

/// `--unconfirmed-variance-scale`: finite and at least 1 (below it an
/// unconfirmed reading would weigh more than a confirmed one).
fn parse_variance_scale(s: &str) -> Result<f32, String> {
    parse_at_least(s, 1.0)
}

/// `--handoff-z`: finite and not negative.
fn parse_handoff_z(s: &str) -> Result<f32, String> {
    parse_at_least(s, 0.0)
}

/// A finite number no smaller than `min`.
fn parse_at_least(s: &str, min: f32) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x.is_finite() && x >= min => Ok(x),
        _ => Err(format!("{s:?} is not a finite number ≥ {min}")),
    }
}
