//! `echoloc-lab simulate --from-scans RUN --map MAP`: one rung's JSON
//! report (simulate's keys, plus `from_scans` and `at_truth`), or
//! `--ladder`: every rung, a table.

use std::path::PathBuf;

use clap::Args;
use serde_json::{json, Value};

use super::{at_truth, derive, map_covers, run_filters, summary, MapInputs, Readings};
use crate::error::LabError;
use crate::files::{error_plot_path, write_all};
use crate::map::load::{LoadedMap, MapKind};
use crate::simulate::filters::Methods;
use crate::simulate::localization::StartArg;
use crate::simulate::report::{log_of, report, rows_of};

/// `simulate`'s options for a run derived from a lidar run's scans.
#[derive(Args, Clone, Debug)]
pub struct ScansArgs {
    /// Derive the ring's readings from a lidar run (a CARMEN log, plain or
    /// gzip, or a ROS 2 bag with LaserScan) instead of simulating a world: real geometry and clutter
    /// (docs/real-buildings.md). --distance-m, --inconsistent, --kidnap and
    /// --scenario do not apply.
    #[arg(long = "from-scans", value_name = "RUN")]
    pub from_scans: Option<PathBuf>,
    /// The part of the run to drive, FROM:TO in scan indices.
    #[arg(long, default_value = ":", requires = "from_scans")]
    pub pass: String,
    /// Where the readings come from (the ladder's rungs): predicted, map,
    /// mapped-laser or laser.
    #[arg(long, value_enum, default_value = "laser", requires = "from_scans")]
    pub readings: Readings,
    /// Every rung of the ladder, printed as a table (--json: one JSON array).
    #[arg(long, requires = "from_scans", conflicts_with_all = ["readings"])]
    pub ladder: bool,
    /// When the ring fires: along-path (every 0.6 s, the driver's schedule)
    /// or at-scans (the whole ring once per scan, as sparse real logs keep it).
    #[arg(long, value_enum, default_value = "along-path", requires = "from_scans")]
    pub fire: super::Fire,
    /// The derived sonar's physics: the widest incidence at which a smooth
    /// face is heard at 1 m, degrees (DESIGN §4.9: about 10; the lobe
    /// narrows with range). Not the map's --face-lobe-deg, which is what
    /// echoloc predicts with.
    #[arg(long = "heard-face-deg", default_value_t = super::FACE_HEARD_AT_1M_DEG, requires = "from_scans")]
    pub heard_face_deg: f64,
    /// Readings of transducers the laser did not cover (their main lobe
    /// less than 90 % seen): drop (left out of the run) or keep (what the
    /// seen rays heard; unseen space taken as empty). A board's scenario
    /// needs every transducer every cycle: keep.
    #[arg(long, value_enum, default_value = "drop", requires = "from_scans")]
    pub uncovered: super::Uncovered,
    /// Writes one CSV row per reading: the range, echoloc's prediction at
    /// the true pose (range, κ, θ, δ, case) and what made the echo.
    #[arg(long = "at-truth-csv", requires = "from_scans")]
    pub at_truth_csv: Option<PathBuf>,
    /// Draws one firing over the laser's returns (with --cone-at).
    #[arg(long = "cone-plot", requires = "cone_at")]
    pub cone_plot: Option<PathBuf>,
    /// The firing: T_s:TRANSDUCER, the transducer's first reading from T_s on.
    #[arg(long = "cone-at", requires = "cone_plot")]
    pub cone_at: Option<String>,
    /// Two-bounce echoes: a face mirrors the ping onto another face, which
    /// sends it back the same way (off: first bounces only).
    #[arg(long, value_enum, default_value = "on", requires = "from_scans")]
    pub multipath: OnOff,
    /// The sonar that hears the scans: nominal (DESIGN §4.9) or harsh (a
    /// less sensitive receiver, lossless mirrors, neighbours' crosstalk and
    /// furniture the laser missed: docs/real-buildings.md, "A harsher sonar").
    #[arg(long, value_enum, default_value = "nominal", requires = "from_scans")]
    pub sonar: super::harsh::Sonar,
    /// Leaves a part of the harsh sonar out (repeatable): threshold, mirror,
    /// crosstalk or furniture.
    #[arg(long = "harsh-without", value_enum, requires = "from_scans")]
    pub harsh_without: Vec<super::harsh::Part>,
    /// The wheel odometry's errors: calibrated (UMBmark's correction: a
    /// tenth of the systematic errors) or uncalibrated (the simulator's).
    #[arg(long, value_enum, default_value = "calibrated", requires = "from_scans")]
    pub odometry: OdometryKind,
    /// A ROS 2 bag's topics and frames (a CARMEN log has none).
    #[command(flatten, next_help_heading = "A lidar bag (--from-scans)")]
    pub bag: crate::lidar::bag::LaserBagArgs,
}

/// A switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

/// Which wheel odometry the derived run has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OdometryKind {
    /// After UMBmark's calibration.
    Calibrated,
    /// The simulator's default: systematic errors as Borenstein and Feng found before calibration.
    Uncalibrated,
}

/// What `simulate` passes on.
pub struct Common<'a> {
    pub map: &'a std::path::Path,
    pub seed: u64,
    pub mounts: Vec<echoloc::predict::Mount>,
    pub loaded: &'a LoadedMap,
    pub json: bool,
    pub start: Option<StartArg>,
    pub log: Option<PathBuf>,
    pub plot: Option<PathBuf>,
    pub trace: Option<PathBuf>,
    pub mcap: Option<PathBuf>,
    /// A ROS 2 bag directory to write the run to.
    pub bag: Option<PathBuf>,
    /// One CSV row per reading (the filters' view).
    pub readings_csv: Option<PathBuf>,
    /// `--no-robust`, `--bank` and the other switches of the filters.
    pub switches: crate::simulate::filters::Switches,
}

/// The lidar run's scans, read and cut to `--pass`, once every option that
/// does not need the map has been checked: a refusal comes before the map's
/// compilation (seconds on a real building), not after it.
pub fn prepare(a: &ScansArgs, c: &Files<'_>) -> Result<crate::lidar::LidarRun, LabError> {
    let Some(path) = &a.from_scans else { return Err(LabError("--from-scans: give a run".into())) };
    let files = [c.log, c.plot, c.trace, c.mcap, c.bag, c.readings_csv, &a.at_truth_csv, &a.cone_plot];
    if a.ladder && files.iter().any(|f| f.is_some()) {
        return Err(LabError("--ladder writes no files: give one rung (--readings) to write a run's files".into()));
    }
    if a.sonar == super::harsh::Sonar::Nominal && !a.harsh_without.is_empty() {
        return Err(LabError("--harsh-without leaves out a part of --sonar harsh; the nominal sonar has none".into()));
    }
    let pass = crate::lidar::Pass::parse(&a.pass)?;
    Ok(crate::lidar::read_with(path, &a.bag.options())?.pass(pass)?)
}

/// The files a run writes, as [`prepare`] checks them.
pub struct Files<'a> {
    pub log: &'a Option<PathBuf>,
    pub plot: &'a Option<PathBuf>,
    pub trace: &'a Option<PathBuf>,
    pub mcap: &'a Option<PathBuf>,
    pub bag: &'a Option<PathBuf>,
    pub readings_csv: &'a Option<PathBuf>,
}

/// Runs one rung, or the ladder, on the scans [`prepare`] gave.
pub fn run(c: &Common<'_>, a: &ScansArgs, scans: &crate::lidar::LidarRun) -> Result<String, LabError> {
    let Some(path) = &a.from_scans else { return Err(LabError("--from-scans: give a run".into())) };
    let view = c.loaded.view()?;
    let grid = match c.loaded.kind() {
        MapKind::RosMapServer => Some(crate::map::ros::load(c.map)?),
        _ => None,
    };
    let inputs = MapInputs { view: &view, grid: grid.as_ref() };
    let rungs: Vec<Readings> = if a.ladder { Readings::ALL.to_vec() } else { vec![a.readings] };
    let mut reports = Vec::new();
    let mut outputs: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let mut bag_rows: Option<Vec<crate::log::Row>> = None;
    for &rung in &rungs {
        let opt = super::DeriveOptions {
            seed: c.seed,
            fire: a.fire,
            face_heard_at_1m_deg: a.heard_face_deg,
            uncovered: a.uncovered,
            multipath: a.multipath == OnOff::On,
            harsh: super::harsh::Harsh::of(a.sonar, &a.harsh_without),
            odometry: match a.odometry {
                OdometryKind::Calibrated => crate::simulate::world::OdometryModel::calibrated(),
                OdometryKind::Uncalibrated => crate::simulate::world::OdometryModel::default(),
            },
        };
        let d =
            derive(scans, rung, &inputs, &c.mounts, &opt).map_err(|e| LabError(format!("{}: {e}", path.display())))?;
        let how = |s: &mut crate::simulate::filters::Start| {
            s.seed = c.seed;
            s.switches = c.switches;
            crate::simulate::report::apply_start(s, c.start);
        };
        let (trace, steps, kept) = run_filters(&d, &view, view.field(), &c.mounts, c.loaded.crc(), how)
            .map_err(|e| LabError(format!("{}: {e}", path.display())))?;
        let mut r = report(&trace, None);
        if let Some(o) = r.as_object_mut() {
            o.insert("localization".into(), crate::simulate::localization::report(&trace, &[]));
            let mut s = summary(&d, scans, rung);
            if let (Some(g), Some(so)) = (&grid, s.as_object_mut()) {
                so.insert("map_covers_path".into(), json!((map_covers(g, &d.readings) * 1e4).round() / 1e4));
            }
            o.insert("from_scans".into(), s);
            let mut csv = String::new();
            o.insert("at_truth".into(), at_truth(&view, &c.mounts, &kept, Some(&mut csv)));
            if let (Some(p), false) = (&a.at_truth_csv, a.ladder) {
                outputs.push((p.clone(), csv.into_bytes()));
            }
            if let (Some(p), Some(at), false) = (&a.cone_plot, &a.cone_at, a.ladder) {
                let at = super::cone::parse_at(at).map_err(LabError)?;
                let png = super::cone::draw(
                    &view,
                    &c.mounts,
                    scans,
                    &d.path.scan_times,
                    &kept,
                    at,
                    crate::figure::Format::of(p),
                )
                .map_err(LabError)?;
                outputs.push((p.clone(), png));
            }
        }
        // Files are written for one rung only (the last with --ladder would overwrite the others).
        if !a.ladder {
            if let Some(p) = &c.log {
                outputs.push((p.clone(), log_of(&kept, &steps).into_bytes()));
            }
            if c.bag.is_some() {
                bag_rows = Some(rows_of(&kept, &steps));
            }
            if let Some(p) = &c.readings_csv {
                outputs.push((p.clone(), trace.readings_csv(&steps).into_bytes()));
            }
            if let Some(p) = &c.trace {
                outputs.push((p.clone(), crate::simulate::localization::trace_csv(&trace).into_bytes()));
            }
            if let Some(p) = &c.plot {
                let (paths, errors) =
                    crate::simulate::figures::draw_as(&view, &[], &trace, crate::figure::Format::of(p))
                        .map_err(LabError)?;
                outputs.push((p.clone(), paths));
                outputs.push((error_plot_path(p), errors));
            }
            if let Some(p) = &c.mcap {
                let rec = crate::foxglove::record(&view, &c.mounts, &steps, &trace, &[])
                    .map_err(|e| LabError(format!("--mcap: {e}")))?;
                outputs.push((p.clone(), rec.finish().map_err(|e| LabError(format!("--mcap: {e}")))?));
            }
        }
        reports.push((rung, r, trace));
    }
    // The bag is a directory, written whole or not at all; it goes first
    // and is taken back if a file fails.
    if let (Some(b), Some(rows)) = (&c.bag, &bag_rows) {
        crate::bag::write::write_bag(b, rows, &c.mounts, &Default::default())
            .map_err(|e| LabError(format!("--bag {e}")))?;
    }
    if let Err(e) = write_all(&outputs) {
        if let Some(b) = &c.bag {
            let _ = std::fs::remove_dir_all(b);
        }
        return Err(e);
    }
    if !a.ladder {
        let r = &reports[0].1;
        return Ok(if c.json { r.to_string() } else { serde_json::to_string_pretty(r).unwrap_or_default() });
    }
    if c.json {
        return Ok(Value::Array(reports.into_iter().map(|(_, r, _)| r).collect()).to_string());
    }
    Ok(table(&reports))
}

/// The ladder as a Markdown table.
fn table(reports: &[(Readings, Value, crate::simulate::filters::Trace)]) -> String {
    let mut out = String::from(
        "| readings | kept | confirmed | confirmed at truth | EKF position RMSE (m) | heading RMSE (°) | max error (m) | cycles > 0.5 m off | of those tracking |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for (rung, r, trace) in reports {
        let e = trace.errors(Methods::Ekf);
        let pct = |v: &Value| v.as_f64().map_or("–".into(), |x| format!("{:.1} %", 100.0 * x));
        let loc = &r["localization"];
        let tracking_off = loc["off_cycles_known"].as_f64().map(|k| 1.0 - k);
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            rung.name(),
            r["readings"],
            pct(&r["verdicts"]["confirmed_fraction"]),
            pct(&r["at_truth"]["confirmed_fraction"]),
            e.map_or("–".into(), |e| format!("{:.3}", e.position_rmse_m)),
            e.map_or("–".into(), |e| format!("{:.2}", e.heading_rmse_deg)),
            e.map_or("–".into(), |e| format!("{:.2}", e.max_position_m)),
            pct(&loc["off_fraction"]),
            tracking_off.map_or("–".into(), |x| format!("{:.1} %", 100.0 * x)),
        ));
    }
    out
}
