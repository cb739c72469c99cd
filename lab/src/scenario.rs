//! `echoloc-lab scenario`: scenario files (docs/scenario.md) on the host.
//! `replay` runs one through the very filters `simulate` ran (the same
//! records, the same core code), so its figures are the simulate run's.
//! `--from-log` converts a robot's log (docs/log.md) into one, so a board
//! replays a real robot's log through its driver as it replays a simulated
//! run.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use echoloc::predict::Mount;
use echoloc::scenario::{self, Header, Record, Scenario};
use serde_json::json;

use crate::log::{Log, Row};
use crate::map::{write_atomically, LabError};
use crate::predict::{load_map_with_field, ring_mounts};
use crate::replay::{cycles, parse_pose, start};
use crate::simulate::world::FiringPlan;
use crate::simulate::{check_writable, filters, motion_f64, report, start_of, BOUNDS};

/// `scenario`: a subcommand, or `--from-log`.
#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct ScenarioArgs {
    #[command(subcommand)]
    pub cmd: Option<ScenarioCmd>,
    /// Converts this log (CSV, docs/log.md) into a scenario (needs --map and -o).
    #[arg(long = "from-log", requires_all = ["map", "out"])]
    pub from_log: Option<PathBuf>,
    /// The map the log was recorded in: a blob (.map), a ROS map_server .yaml or a .geojson.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// The ring: pioneer16, or a JSON file of [x_m, y_m, heading_deg] per transducer.
    #[arg(long, default_value = "pioneer16")]
    pub ring: String,
    /// The scenario to write.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// Where the robot starts in the map, x_m,y_m,θ_deg (default: the first
    /// reference pose, else the first odometry pose).
    #[arg(long = "initial-pose", allow_hyphen_values = true)]
    pub initial_pose: Option<String>,
    /// C-space buffer for a .yaml or .geojson map, mm.
    #[arg(long = "buffer-mm", default_value_t = 100)]
    pub buffer_mm: u32,
    /// The board's pass bounds, position RMSE m,heading RMSE deg (default
    /// with a reference pose on every row: 0.05,1; without: none).
    #[arg(long)]
    pub bounds: Option<String>,
    /// Readings the board's driver could not report (inside its blanking,
    /// beyond its listening window).
    #[command(flatten)]
    pub unreportable: DriverArgs,
}

/// What to do with a log's readings the board's driver could not have
/// reported (a log from another driver or another simulator).
#[derive(Args, Clone, Debug, Default)]
pub struct DriverArgs {
    /// The blanking of the driver the board emulates, mm: a reading nearer
    /// is given to it as no echo (default: the Polaroid 6500's own 2.38 ms,
    /// 408 mm; only longer ones can be emulated, the QEMU bench drives no
    /// BINH).
    #[arg(long = "blanking-mm")]
    pub blanking_mm: Option<u32>,
    /// Refuse such a log instead (as before: the board cannot reproduce it).
    #[arg(long = "refuse-unreportable")]
    pub refuse: bool,
}

/// How many of a log's readings were given to the board as its driver
/// would report them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Unreportable {
    /// Readings nearer than the blanking, given as no echo.
    pub inside_blanking: usize,
    /// Readings beyond the listening window, given as no echo (the driver
    /// reports an echo after its window as none).
    pub beyond_window: usize,
    /// The blanking used, mm.
    pub blanking_mm: u32,
    /// The farthest range the driver reports, mm.
    pub window_mm: u32,
}

impl Unreportable {
    /// The JSON the commands print.
    pub fn json(&self) -> serde_json::Value {
        json!({
            "inside_blanking": self.inside_blanking,
            "beyond_window": self.beyond_window,
            "given_as": "no echo",
            "blanking_mm": self.blanking_mm,
            "window_mm": self.window_mm,
        })
    }
}

/// Gives `log`'s readings that the board's driver (a ring of `n`, the
/// standard [`FiringPlan`]) could not report as it would report them: an
/// echo inside its blanking is not heard, one after its listening window
/// ends the ping as no echo. Nothing is known of what a later echo would
/// have been, so both become no echo, the same for the host's replay and
/// the board's. `blanking_mm` lengthens the blanking (a driver that ignores
/// near echoes); one shorter than the module's own is refused, since the
/// board's driver ends blanking only by BINH, which the replay bench does
/// not drive. With `refuse`, any such reading refuses the log (naming its
/// line).
pub fn as_the_driver_reports(log: &mut Log, n: usize, a: &DriverArgs) -> Result<Unreportable, String> {
    let plan = FiringPlan::new(n, None).map_err(|e| format!("ring of {n}: {e}"))?;
    let own_mm = plan.range_mm(plan.min_echo_us());
    let window_mm = plan.range_mm(plan.window_us()) - 1;
    let blanking_mm = match a.blanking_mm {
        Some(b) if b < own_mm => {
            return Err(format!(
                "--blanking-mm {b}: the board's driver (a Polaroid 6500 without BINH) hears nothing nearer than                  {own_mm} mm; a shorter blanking needs BINH, which the QEMU replay bench does not drive"
            ))
        }
        Some(b) if b > window_mm => {
            return Err(format!("--blanking-mm {b}: beyond the driver's listening window ({window_mm} mm)"))
        }
        Some(b) => b,
        None => own_mm,
    };
    let mut u = Unreportable { blanking_mm, window_mm, ..Unreportable::default() };
    for r in &mut log.rows {
        let Some(mm) = r.range_mm else { continue };
        let near = mm < blanking_mm;
        if !near && mm <= window_mm {
            continue;
        }
        if a.refuse {
            return Err(if near {
                format!("line {}: range {mm} mm is inside the driver's blanking (it reports nothing nearer than {blanking_mm} mm)", r.line)
            } else {
                format!(
                    "line {}: range {mm} mm is beyond the driver's listening window (at most {window_mm} mm)",
                    r.line
                )
            });
        }
        if near {
            u.inside_blanking += 1;
        } else {
            u.beyond_window += 1;
        }
        r.range_mm = None;
    }
    Ok(u)
}

/// `scenario …` subcommands.
#[derive(Subcommand)]
pub enum ScenarioCmd {
    /// Checks a scenario against its map and runs it through the dead
    /// reckoning, threshold method and EKF: the same JSON as `simulate`,
    /// without the simulator's truth about clutter.
    Replay(ReplayArgs),
}

/// `scenario replay`.
#[derive(Args)]
pub struct ReplayArgs {
    /// The scenario file.
    scenario: PathBuf,
    /// The map it was made on: a blob (.map), a ROS map_server .yaml or a .geojson.
    #[arg(long)]
    map: PathBuf,
    /// C-space buffer for a .yaml or .geojson map, mm (as `simulate` used).
    #[arg(long = "buffer-mm", default_value_t = 100)]
    buffer_mm: u32,
    /// One JSON object (the default prints the same, indented).
    #[arg(long)]
    json: bool,
}

pub fn run(a: ScenarioArgs) -> Result<String, LabError> {
    match (&a.cmd, &a.from_log, &a.map, &a.out) {
        (Some(ScenarioCmd::Replay(r)), _, _, _) => replay(r),
        (None, Some(log), Some(map), Some(out)) => convert(&a, log, map, out),
        _ => Err(LabError("scenario: give a subcommand (replay) or --from-log LOG --map MAP -o OUT".into())),
    }
}

fn replay(a: &ReplayArgs) -> Result<String, LabError> {
    let bytes = std::fs::read(&a.scenario).map_err(|e| LabError(format!("{}: {e}", a.scenario.display())))?;
    let s = Scenario::parse(&bytes)
        .map_err(|e| LabError(format!("{}: not a valid scenario: {e}", a.scenario.display())))?;
    let loaded = load_map_with_field(&a.map, a.buffer_mm)?;
    let map = loaded.view()?;
    s.check_map(loaded.crc()).map_err(|e| {
        LabError(format!("{}: made on another map than {} (MapMismatch): {e}", a.scenario.display(), a.map.display()))
    })?;
    let mounts: Vec<Mount> = (0..s.transducers()).filter_map(|i| s.mount(i)).collect();
    let records: Vec<Record> = s.records().collect();
    let steps = filters::steps_of_records(s.header(), &records).map_err(LabError)?;
    let trace = filters::run(&map, map.field(), &mounts, &start_of(s.header()), &steps, &mut |_| {})
        .map_err(|e| LabError(format!("{}: {e}", a.scenario.display())))?;
    let mut r = report(&trace, None);
    if let Some(o) = r.as_object_mut() {
        o.insert("localization".into(), crate::simulate::localization::report(&trace, &[]));
    }
    Ok(if a.json { r.to_string() } else { serde_json::to_string_pretty(&r).unwrap_or_default() })
}

fn convert(
    a: &ScenarioArgs,
    log_path: &std::path::Path,
    map: &std::path::Path,
    out: &std::path::Path,
) -> Result<String, LabError> {
    check_writable(out)?;
    let given = a.initial_pose.as_deref().map(|s| parse_pose(s, "--initial-pose")).transpose()?;
    let mounts = ring_mounts(&a.ring)?;
    let mut log = crate::log::read_file(log_path, mounts.len())?;
    let partial = crate::log::drop_partial_last_ring(&mut log, mounts.len());
    if let Some(p) = partial {
        eprintln!("echoloc-lab: note: {}: {}", log_path.display(), p.note(mounts.len()));
    }
    let unreportable = as_the_driver_reports(&mut log, mounts.len(), &a.unreportable)
        .map_err(|e| LabError(format!("{}: {e}", log_path.display())))?;
    let loaded = load_map_with_field(map, a.buffer_mm)?;
    let (mut header, records) =
        from_log(&log, &mounts, loaded.crc(), given).map_err(|e| LabError(format!("{}: {e}", log_path.display())))?;
    if let Some(b) = &a.bounds {
        let v: Vec<f32> = b.split(',').filter_map(|t| t.trim().parse().ok()).collect();
        match v[..] {
            [p, h] if p.is_finite() && h.is_finite() && p >= 0.0 && h >= 0.0 => {
                (header.bound_position_m, header.bound_heading_deg) = (p, h)
            }
            _ => return Err(LabError(format!("--bounds {b:?}: expected two numbers ≥ 0, position_m,heading_deg"))),
        }
    }
    let mut bytes = Vec::new();
    scenario::write(&header, &mounts, &records, |b| bytes.extend_from_slice(b))
        .map_err(|e| LabError(format!("{}: {e}", out.display())))?;
    write_atomically(out, &bytes)?;
    let reference = log.rows.iter().all(|r| r.reference.is_some());
    let bounded = header.bound_position_m < f32::MAX;
    Ok(json!({
        "out": out.display().to_string(),
        "bytes": bytes.len(),
        "records": records.len(),
        "cycles": records.last().map_or(0, |r| r.cycle + 1),
        "transducers": mounts.len(),
        "reference": reference,
        "bounds": if bounded { json!([header.bound_position_m, header.bound_heading_deg]) } else { json!(null) },
        "start": header.start,
        "unreportable": unreportable.json(),
        "partial_last_ring": partial.map(|p| p.json()),
    })
    .to_string())
}

/// The log's readings as the boards' driver takes them: each whole ring
/// cycle's rows in the driver's slot order ([`FiringPlan::order`]), as
/// [`from_log`] lays them on its slots (other cycles as they are), and
/// each range as the driver measures it back from its echo time (within
/// 1 mm of the log's). The EKF takes readings one at a time, and a gate's
/// decision can turn on a millimetre: the host replays this to compare
/// with the board reading for reading (docs/log.md, "The board and the
/// host").
pub fn as_the_board_reads(log: &Log, ring: usize) -> Result<Log, String> {
    let plan = FiringPlan::new(ring, None).map_err(|e| format!("ring of {ring}: {e}"))?;
    let mut rows = Vec::with_capacity(log.rows.len());
    for cycle in cycles(&log.rows) {
        if cycle.len() == ring {
            rows.extend(plan.order.iter().filter_map(|&t| cycle.iter().find(|r| r.transducer == t)));
        } else {
            rows.extend_from_slice(cycle);
        }
    }
    for r in &mut rows {
        r.range_mm = r.range_mm.map(|mm| plan.range_mm(echo_us(&plan, mm)));
    }
    Ok(Log { rows })
}

/// The echo time the driver would measure for `range_mm`: the time of
/// flight whose range, converted back by the driver, is nearest, among
/// those it reports (after its blanking, inside its window). A range at
/// the blanking's edge (408 mm) is also the range of a few times inside
/// it (2 375 µs converts to 408 mm too): the earliest such time was
/// written once, and the board's driver refused it as an echo in its
/// blanking where the host took the reading (#47).
fn echo_us(plan: &FiringPlan, range_mm: u32) -> u32 {
    let um_per_s = f64::from(plan.module.sound().um_per_s());
    let guess = (2.0 * f64::from(range_mm) * 1e9 / um_per_s).round() as u32;
    let (lo, hi) = (plan.min_echo_us(), plan.window_us().saturating_sub(1));
    (guess.saturating_sub(3).max(lo)..=guess.saturating_add(3).min(hi))
        .min_by_key(|&us| (plan.range_mm(us).abs_diff(range_mm), us))
        .unwrap_or(guess.clamp(lo, hi))
}

/// A log as a scenario for the driver the boards run ([`FiringPlan`]: the
/// standard ring timing, spread firing order, 20 °C).
///
/// - Every ring cycle of the log ([`cycles`]) must give every transducer
///   once: the driver fires each once per cycle. Within a cycle the rows
///   are laid on the driver's slots (its firing order and times); each
///   record's odometry increment runs from the previous record's
///   cumulative pose, so a log in another order still gives each reading
///   its own odometry.
/// - Ranges become the echo times the driver would measure (it converts
///   them back to within 1 mm); a range inside the driver's blanking or
///   beyond its listening window is refused, since the driver could not
///   have reported it.
/// - With a reference pose on every row, it is the scenario's truth and the
///   bounds are `simulate`'s (5 cm, 1°). Without, the truth is the dead
///   reckoning from the start and the bounds are `f32::MAX` (no bound): the
///   board then reports its final pose, and its pass means only that the
///   loop ran.
pub fn from_log(
    log: &Log,
    mounts: &[Mount],
    map_crc: u32,
    initial: Option<[f64; 3]>,
) -> Result<(Header, Vec<Record>), String> {
    let n = mounts.len();
    let plan = FiringPlan::new(n, None).map_err(|e| format!("ring of {n}: {e}"))?;
    let min_mm = plan.range_mm(plan.min_echo_us());
    let max_mm = plan.range_mm(plan.window_us());
    let with_reference = log.rows.iter().all(|r| r.reference.is_some());
    let start = start(log, initial);
    let s0 = start.pose.map(f64::from);
    let mut records = Vec::with_capacity(log.rows.len());
    let mut prev: Option<&Row> = None;
    // Dead reckoning in the map frame, for a log without a reference.
    let mut dr = s0;
    for (k, cycle) in cycles(&log.rows).into_iter().enumerate() {
        if cycle.len() != n {
            let missing: Vec<String> = (0..n)
                .filter(|&i| !cycle.iter().any(|r| usize::from(r.transducer) == i))
                .map(|i| i.to_string())
                .collect();
            return Err(format!(
                "line {}: the ring cycle starting here lacks transducer(s) {}: the driver fires every transducer once a cycle",
                cycle[0].line,
                missing.join(", ")
            ));
        }
        for (slot, &t) in plan.order.iter().enumerate() {
            let Some(r) = cycle.iter().find(|r| r.transducer == t) else {
                return Err(format!("line {}: cycle without transducer {t}", cycle[0].line));
            };
            let a = prev.map_or(r.odometry, |p| p.odometry);
            prev = Some(r);
            let u = motion_f64((a[0], a[1], a[2]), (r.odometry[0], r.odometry[1], r.odometry[2]));
            let (s, c) = dr[2].sin_cos();
            let (dx, dy) = (f64::from(u.dx), f64::from(u.dy));
            dr = [dr[0] + c * dx - s * dy, dr[1] + s * dx + c * dy, crate::angle::wrap(dr[2] + f64::from(u.dphi))];
            let echo_us = match r.range_mm {
                None => None,
                Some(mm) if mm < min_mm => {
                    return Err(format!(
                        "line {}: range {mm} mm is inside the driver's blanking (it reports nothing nearer than {min_mm} mm)",
                        r.line
                    ))
                }
                Some(mm) if mm >= max_mm => {
                    return Err(format!(
                        "line {}: range {mm} mm is beyond the driver's listening window (at most {} mm)",
                        r.line,
                        max_mm - 1
                    ))
                }
                Some(mm) => Some(echo_us(&plan, mm)),
            };
            let truth = if with_reference { r.reference.unwrap_or(dr) } else { dr };
            records.push(Record {
                time_us: (plan.fire_us(k as u32, slot) & 0xFFFF_FFFF) as u32,
                cycle: k as u32,
                transducer: t,
                slot: slot as u8,
                echo_us,
                odometry: [u.dx, u.dy, u.dphi],
                truth: truth.map(|v| v as f32),
            });
        }
    }
    let (bound_position_m, bound_heading_deg) = if with_reference { BOUNDS } else { (f32::MAX, f32::MAX) };
    let header = Header {
        map_crc,
        speed_um_per_s: plan.module.sound().um_per_s(),
        period_us: plan.period_us,
        slot_us: plan.slot_us,
        start: start.pose,
        start_sigma: start.sigma,
        bound_position_m,
        bound_heading_deg,
    };
    Ok((header, records))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(ranges: &[Option<u32>]) -> Log {
        let rows = ranges
            .iter()
            .enumerate()
            .map(|(i, &range_mm)| Row {
                time_s: 0.04 * i as f64,
                transducer: (i % 16) as u8,
                range_mm,
                odometry: [0.0; 3],
                reference: None,
                line: i as u64 + 2,
            })
            .collect();
        Log { rows }
    }

    #[test]
    fn every_echo_time_written_is_one_the_driver_reports() {
        // Every range the converter takes, blanking's edge and window's
        // included, becomes a time the driver times (not in its blanking,
        // inside its window) and converts back to within 1 mm; by hand, the
        // blanking's edge: 2 380 µs at 343.2 m/s is 408.4 mm.
        let plan = FiringPlan::new(16, None).unwrap();
        let (min_mm, max_mm) = (plan.range_mm(plan.min_echo_us()), plan.range_mm(plan.window_us()));
        assert_eq!((plan.min_echo_us(), min_mm), (2_380, 408));
        for mm in min_mm..max_mm {
            let us = echo_us(&plan, mm);
            assert!(us >= plan.min_echo_us() && us < plan.window_us(), "{mm} mm: {us} µs");
            assert!(plan.range_mm(us).abs_diff(mm) <= 1, "{mm} mm: {us} µs → {} mm", plan.range_mm(us));
        }
    }

    #[test]
    fn readings_the_driver_cannot_report_are_given_as_no_echo() {
        // The 6500's blanking, 2.38 ms, at 20 °C (331.3 m/s × √(1 + 20/273.15)
        // = 343.2 m/s): 408 mm, by hand; its window, 5.5 m.
        let mut l = log(&[Some(379), Some(1000), None, Some(6000), Some(420)]);
        let u = as_the_driver_reports(&mut l, 16, &DriverArgs::default()).unwrap();
        assert!((405..=410).contains(&u.blanking_mm), "{u:?}");
        assert!((5490..=5510).contains(&u.window_mm), "{u:?}");
        assert_eq!((u.inside_blanking, u.beyond_window), (1, 1));
        let got: Vec<Option<u32>> = l.rows.iter().map(|r| r.range_mm).collect();
        assert_eq!(got, [None, Some(1000), None, None, Some(420)]);
        // A longer blanking takes the 420 mm reading too.
        let mut l = log(&[Some(379), Some(1000), Some(420)]);
        let u = as_the_driver_reports(&mut l, 16, &DriverArgs { blanking_mm: Some(500), refuse: false }).unwrap();
        assert_eq!((u.inside_blanking, u.blanking_mm), (2, 500));
        // A shorter one cannot be emulated; refusing names the line.
        let e =
            as_the_driver_reports(&mut log(&[Some(379)]), 16, &DriverArgs { blanking_mm: Some(300), refuse: false });
        assert!(e.unwrap_err().contains("BINH"));
        let e = as_the_driver_reports(
            &mut log(&[Some(1000), Some(379)]),
            16,
            &DriverArgs { blanking_mm: None, refuse: true },
        );
        assert!(e.unwrap_err().starts_with("line 3: range 379 mm is inside the driver's blanking"));
    }
}
