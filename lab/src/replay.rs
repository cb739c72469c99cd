//! `echoloc-lab replay`: a robot's log (`docs/log.md`) through the very
//! filters `simulate` runs ([`crate::simulate::filters`]): prediction with
//! the quantised credence, verdicts, the threshold method and the EKF, in
//! the core's code. The JSON has `simulate --json`'s keys; the error
//! figures are against the log's reference pose, and null without one.

use std::path::PathBuf;

use clap::Args;
use echoloc::referencing::Reading;
use serde_json::json;

pub use crate::log::cycles;
use crate::log::Log;
use crate::map::LabError;
use crate::simulate::filters::{self, Start, Step};
use crate::simulate::{check_writable, error_plot_path, figures, motion_f64, report, write_all, START_SIGMA};

/// `replay`.
#[derive(Args)]
pub struct ReplayArgs {
    /// The run and its map.
    #[command(flatten)]
    pub input: crate::run_input::RunInput,
    /// Writes one CSV row per ring cycle: the mode, the estimate, its σ and
    /// the reference where the log has one (docs/localization.md).
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Writes one CSV row per reading: the reading, the prediction at the
    /// estimate, the verdict, what the EKF did, the estimate and the reference.
    #[arg(long = "readings-csv")]
    pub readings_csv: Option<PathBuf>,
    /// Seed of the particles' draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// One JSON object (the default prints the same, indented).
    #[arg(long)]
    pub json: bool,
    /// Writes the run as a Foxglove recording (MCAP, docs/foxglove.md).
    #[arg(long)]
    pub mcap: Option<PathBuf>,
    #[command(flatten)]
    pub live: crate::foxglove::live::LiveArgs,
    /// --live's and --ros2's pace: the run's seconds per wall-clock second.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    #[command(flatten)]
    pub ros2: crate::ros2::Ros2Args,
    /// Writes the map with the paths to OUT.png and the error over time to
    /// OUT-error.png (SVG for OUT.svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// The log as the filters' steps: odometry increments from the cumulative
/// poses (in `f64`, as `simulate` makes them), ranges as logged, cycles by
/// [`cycles`].
pub fn steps_of_log(log: &Log) -> Vec<Step> {
    let mut prev: Option<[f64; 3]> = None;
    let mut out = Vec::with_capacity(log.rows.len());
    for (c, cycle) in cycles(&log.rows).into_iter().enumerate() {
        for r in cycle {
            let a = prev.unwrap_or(r.odometry);
            prev = Some(r.odometry);
            out.push(Step {
                time_s: r.time_s,
                cycle: c as u32,
                transducer: r.transducer,
                odometry: motion_f64((a[0], a[1], a[2]), (r.odometry[0], r.odometry[1], r.odometry[2])),
                reading: match r.range_mm {
                    Some(range_mm) => Reading::Echo { range_mm },
                    None => Reading::NoEcho,
                },
                truth: r.reference.map(|v| v.map(|x| x as f32)),
            });
        }
    }
    out
}

/// `x_m,y_m,θ_deg` as a pose (m, m, rad).
pub fn parse_pose(s: &str, what: &str) -> Result<[f64; 3], LabError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| LabError(format!("{what} {s:?}: expected x_m,y_m,θ_deg")))?;
    match v[..] {
        [x, y, d] if x.is_finite() && y.is_finite() && d.is_finite() && x.abs() <= 1e6 && y.abs() <= 1e6 => {
            Ok([x, y, d.to_radians()])
        }
        [_, _, _] => Err(LabError(format!("{what} {s:?}: numbers must be finite, positions within ±1000 km"))),
        _ => Err(LabError(format!("{what} {s:?}: expected three numbers x_m,y_m,θ_deg"))),
    }
}

/// Where the filters start: `given` (m, m, rad), else the first reference
/// pose, else the first odometry pose; with [`START_SIGMA`].
pub fn start(log: &Log, given: Option<[f64; 3]>) -> Start {
    let pose = given
        .or_else(|| log.rows.iter().find_map(|r| r.reference))
        .or_else(|| log.rows.first().map(|r| r.odometry))
        .unwrap_or_default();
    Start::with_everything(pose.map(|v| v as f32), START_SIGMA)
}

pub fn replay_cmd(a: &ReplayArgs) -> Result<String, LabError> {
    if let Some(p) = &a.plot {
        check_writable(p)?;
        check_writable(&error_plot_path(p))?;
    }
    for p in a.mcap.iter().chain(a.trace.iter()).chain(a.readings_csv.iter()) {
        check_writable(p)?;
    }
    let arg = a
        .input
        .initial_pose
        .as_deref()
        .map(|s| crate::simulate::localization::parse_start(s, "--initial-pose"))
        .transpose()
        .map_err(LabError)?;
    let given = match arg {
        Some(
            crate::simulate::localization::StartArg::At(p) | crate::simulate::localization::StartArg::Around(p, _),
        ) => Some(p),
        _ => None,
    };
    let crate::run_input::Run { mounts, log, source, bag } = a.input.read_run()?;
    let loaded = a.input.load_map()?;
    let map = loaded.view()?;
    let steps = steps_of_log(&log);
    let (hold, wait) = a.live.hold_and_wait().map_err(LabError)?;
    if (a.live.live.is_some() || a.ros2.ros2) && !(a.speed.is_finite() && a.speed > 0.0) {
        return Err(LabError(format!("--speed {} is not a positive number", a.speed)));
    }
    let mut how = start(&log, given);
    how.seed = a.seed;
    how.cycle_clouds = a.mcap.is_some() || a.live.live.is_some() || a.ros2.ros2;
    crate::simulate::apply_start(&mut how, arg);
    let trace = filters::run(&map, map.field(), &mounts, &how, &steps, &mut |_| {})
        .map_err(|e| LabError(format!("{}: {e}", source.display())))?;
    let mut r = report(&trace, None);
    if let Some(o) = r.as_object_mut() {
        o.insert("localization".into(), crate::simulate::localization::report(&trace, &[]));
        o.insert(
            "log".into(),
            json!({
                "rows": log.rows.len(),
                "reference_rows": log.rows.iter().filter(|r| r.reference.is_some()).count(),
                "cycles": steps.last().map_or(0, |s| s.cycle + 1),
            }),
        );
        if let Some(bag) = &bag {
            o.insert("bag".into(), crate::bag::cli::summary(bag));
        }
    }
    let mut outputs = Vec::new();
    if let Some(p) = &a.plot {
        let (paths, errors) = figures::draw_as(&map, &[], &trace, crate::figure::Format::of(p)).map_err(LabError)?;
        outputs.extend([(p.clone(), paths), (error_plot_path(p), errors)]);
    }
    if let Some(p) = &a.trace {
        outputs.push((p.clone(), crate::simulate::localization::trace_csv(&trace).into_bytes()));
    }
    if let Some(p) = &a.readings_csv {
        outputs.push((p.clone(), trace.readings_csv(&steps).into_bytes()));
    }
    if a.mcap.is_some() || a.live.live.is_some() {
        let mut rec = crate::foxglove::Recording::new().map_err(|e| LabError(format!("--mcap: {e}")))?;
        a.live.serve(&mut rec, crate::foxglove::live::Pace::Speed(a.speed)).map_err(LabError)?;
        if a.live.live.is_some() {
            crate::foxglove::run::advertise(&mut rec);
            if !wait.is_zero() && !rec.wait_for_viewer(wait) {
                eprintln!("live: no viewer within --live-wait-s; running without");
            }
        }
        crate::foxglove::run::record_into(&mut rec, &map, &mounts, &steps, &trace, &[]);
        let bytes = rec.finish_holding(hold).map_err(|e| LabError(format!("--mcap: {e}")))?;
        if let Some(p) = &a.mcap {
            outputs.push((p.clone(), bytes));
        }
    }
    write_all(&outputs)?;
    if a.ros2.ros2 {
        let odometry: Vec<[f64; 3]> = cycles(&log.rows).into_iter().flatten().map(|r| r.odometry).collect();
        let run =
            crate::ros2::replay::ReplayedRun { mounts: &mounts, steps: &steps, odometry: &odometry, trace: &trace };
        let counts = crate::ros2::replay::publish(&a.ros2, &run, a.speed)?;
        if let Some(o) = r.as_object_mut() {
            o.insert("ros2".into(), serde_json::to_value(counts).unwrap_or_default());
        }
    }
    Ok(if a.json { r.to_string() } else { serde_json::to_string_pretty(&r).unwrap_or_default() })
}
