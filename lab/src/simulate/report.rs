//! What a run through the filters becomes: the JSON report (the errors
//! of each estimate, verdicts, lost counts, detection against the
//! simulator's truth), a run's readings as the plain log's rows, its
//! records as the board's scenario holds them, and where the filters start.
//! Shared by `simulate`, `replay`, `scenario`, `board` and a lidar run's
//! derived sonar (`crate::from_scans`).

use echoloc::referencing::Motion;
use echoloc::scenario::{Header, Record};
use serde_json::{json, Value};

use super::filters::{self, Methods, Trace};
use super::localization;
use super::world::{self, EchoSource, SimReading, SimRun};
use crate::map::LabError;

/// The filter starts at the true pose with these standard deviations (m, m, rad).
pub const START_SIGMA: [f32; 3] = [0.05, 0.05, 0.0349];

/// The pass bounds, written into a scenario: 5 cm and 1° RMSE.
pub const BOUNDS: (f32, f32) = (0.05, 1.0);

/// What `--start` (or `--initial-pose`) makes of the filters' start:
/// unknown, a pose to track from (with the default σ), or one to search
/// around. The dead reckoning and the threshold method start at the given
/// pose, or, for `unknown`, where they would have.
pub fn apply_start(start: &mut filters::Start, arg: Option<localization::StartArg>) {
    use localization::StartArg;
    match arg {
        None => {}
        Some(StartArg::Unknown) => start.mode = filters::StartMode::Unknown,
        Some(StartArg::At(p)) => {
            start.pose = p.map(|v| v as f32);
            start.mode = filters::StartMode::Known;
        }
        Some(StartArg::Around(p, s)) => {
            start.pose = p.map(|v| v as f32);
            start.sigma = [s[0] as f32, s[0] as f32, s[1] as f32];
            start.mode = filters::StartMode::Around;
        }
    }
}

/// Where a scenario's filters start.
pub fn start_of(h: &Header) -> filters::Start {
    filters::Start::with_everything(h.start, h.start_sigma)
}

/// The run as a plain log: each step's time, transducer and range (what the
/// filters read), the cumulative odometry the increments came from, and the
/// true pose as the reference.
pub fn log_of(readings: &[SimReading], steps: &[filters::Step]) -> String {
    crate::log::write(&rows_of(readings, steps), true)
}

/// The rows [`log_of`] writes (and `--bag` writes as a ROS 2 bag).
pub fn rows_of(readings: &[SimReading], steps: &[filters::Step]) -> Vec<crate::log::Row> {
    readings
        .iter()
        .zip(steps)
        .map(|(r, s)| crate::log::Row {
            time_s: s.time_s,
            transducer: s.transducer,
            range_mm: match s.reading {
                echoloc::referencing::Reading::Echo { range_mm } => Some(range_mm),
                _ => None,
            },
            odometry: [r.odometry.0, r.odometry.1, r.odometry.2],
            reference: Some([r.truth.0, r.truth.1, r.truth.2]),
            line: 0,
        })
        .collect()
}

/// The run as the firmware would see it: odometry increments in `f32` (what
/// the scenario stores, so a replay uses the very same numbers) and echo
/// times.
pub fn to_records(readings: &[SimReading]) -> Result<Vec<Record>, LabError> {
    let mut prev = readings.first().map(|r| r.odometry);
    readings
        .iter()
        .map(|r| {
            let (a, b) = (prev.unwrap_or(r.odometry), r.odometry);
            prev = Some(b);
            if ![b.0, b.1, b.2, r.truth.0, r.truth.1, r.truth.2].iter().all(|v| v.is_finite()) {
                return Err(LabError(format!("cycle {}: non-finite odometry or pose", r.cycle)));
            }
            let u = motion_f64(a, b);
            Ok(Record {
                time_us: ((r.time_s * 1e6).round() as u64 & 0xFFFF_FFFF) as u32,
                cycle: r.cycle,
                transducer: r.transducer,
                slot: r.slot,
                echo_us: r.echo_us.filter(|&t| t > 0),
                odometry: [u.dx, u.dy, u.dphi],
                truth: [r.truth.0 as f32, r.truth.1 as f32, r.truth.2 as f32],
            })
        })
        .collect()
}

/// The odometry increment from `a` to `b` in `a`'s frame, computed in `f64`
/// (cumulative poses far from the origin lose the increment in `f32`).
pub fn motion_f64(a: (f64, f64, f64), b: (f64, f64, f64)) -> Motion {
    let (s, c) = a.2.sin_cos();
    let (gx, gy) = (b.0 - a.0, b.1 - a.1);
    Motion { dx: (c * gx + s * gy) as f32, dy: (-s * gx + c * gy) as f32, dphi: world::wrap(b.2 - a.2) as f32 }
}

fn ratio(n: u64, d: u64) -> Value {
    if d == 0 {
        Value::Null
    } else {
        json!(round4(n as f64 / d as f64))
    }
}

fn round4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// The JSON report: errors of each method, verdicts and lost counts, and,
/// with the simulator's truth, detection scores and the clutter.
pub fn report(t: &Trace, run: Option<&SimRun>) -> Value {
    // Without a true pose the error figures are null; the final pose is always there.
    let method = |m: Methods| {
        let e = t.errors(m);
        let f = |g: fn(&filters::Errors) -> f64| e.as_ref().map(|e| round4(g(e)));
        json!({
            "position_rmse_m": f(|e| e.position_rmse_m),
            "heading_rmse_deg": f(|e| e.heading_rmse_deg),
            "max_position_error_m": f(|e| e.max_position_m),
            "final_position_error_m": f(|e| e.final_position_m),
            "final_heading_error_deg": f(|e| e.final_heading_deg),
            "final_pose": t.final_pose(m).map(|p| p.map(round6)),
            "first_pose": t.poses(m).first().map(|p| p.map(round6)),
        })
    };
    let v = &t.verdicts;
    let out = json!({
        "readings": t.times.len(),
        "distance_m": round4(t.distance_m),
        "duration_s": round4(t.duration_s),
        "dead_reckoning": method(Methods::DeadReckoning),
        "threshold": with(method(Methods::Threshold), json!({"corrections": t.threshold_corrections})),
        "ekf": with(
            method(Methods::Ekf),
            json!({
                "accepted": t.accepted,
                "gated": t.gated,
                "weak": t.weak,
                "lost_raised": t.lost_count,
                "lost_cleared": t.lost_cleared,
                "cycles_lost": t.cycles_lost,
                "recoveries": t.recoveries,
                "covariance": t.covariance.map(|r| r.map(f64::from)),
                "odometry_calibration": t.calibration.map(|b| json!({"per_rad": b.per_rad, "per_m": b.per_m})),
            })
        ),
        "verdicts": {
            "confirmed": v.confirmed,
            "unknown_obstacle": v.unknown_obstacle,
            "removed_or_missed": v.removed_or_missed,
            "unpredicted": v.unpredicted,
            "nothing_as_predicted": v.nothing_as_predicted,
            "inconclusive": v.inconclusive,
            "confirmed_fraction": ratio(u64::from(v.confirmed), u64::from(v.total())),
        },
        "lost": {"raised": t.lost_count, "cleared": t.lost_cleared, "cycles_lost": t.cycles_lost, "recoveries": t.recoveries},
    });
    let Some(run) = run else { return out };
    // Detection against the simulator's truth: an echo from an unmapped
    // object is an unknown obstacle; a prediction on a removed obstacle is a
    // removed one.
    let (mut uo_tp, mut uo_fp, mut uo_fn, mut rm_tp, mut rm_fp, mut rm_fn) = (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
    for (r, j) in run.readings.iter().zip(&t.judged) {
        let truly_unknown = r.source == EchoSource::Unmapped;
        match (j.unknown, truly_unknown) {
            (true, true) => uo_tp += 1,
            (true, false) => uo_fp += 1,
            (false, true) => uo_fn += 1,
            _ => {}
        }
        let truly_removed = j.predicted_obstacle.is_some_and(|o| run.removed_obstacles.contains(&o));
        match (j.removed, truly_removed) {
            (true, true) => rm_tp += 1,
            (true, false) => rm_fp += 1,
            (false, true) => rm_fn += 1,
            _ => {}
        }
    }
    let consistent = run.readings.iter().filter(|r| r.consistent).count();
    let extra = json!({
        "cycles": run.cycles,
        "inconsistent_fraction": round4(1.0 - consistent as f64 / run.readings.len().max(1) as f64),
        "removed_obstacles": run.removed_obstacles.len(),
        "unmapped_objects": run.unmapped.len(),
        "people": run.people.len(),
        "odometry_errors": {
            "left_scale": run.odometry_errors.left_scale,
            "right_scale": run.odometry_errors.right_scale,
            "wheelbase_scale": run.odometry_errors.wheelbase_scale,
            "heading_bias": {"per_rad": run.heading_bias.0, "per_m": run.heading_bias.1},
        },
        "detection": {
            "unknown_obstacle": {"precision": ratio(uo_tp, uo_tp + uo_fp), "recall": ratio(uo_tp, uo_tp + uo_fn),
                                  "true_positives": uo_tp, "false_positives": uo_fp, "false_negatives": uo_fn},
            "removed_obstacle": {"precision": ratio(rm_tp, rm_tp + rm_fp), "recall": ratio(rm_tp, rm_tp + rm_fn),
                                  "true_positives": rm_tp, "false_positives": rm_fp, "false_negatives": rm_fn},
        },
    });
    with(out, extra)
}

/// `a` with the keys of `b` added (both JSON objects).
fn with(mut a: Value, b: Value) -> Value {
    if let (Some(o), Value::Object(e)) = (a.as_object_mut(), b) {
        o.extend(e);
    }
    a
}
