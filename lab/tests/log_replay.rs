//! Bring your own robot (#16): the plain log (docs/log.md) replayed through
//! the filters. Logs written by `simulate --log` replay to the simulate
//! run's figures; a hand-made log (`lab/tests/data/depot-hand.csv`, written
//! by `scripts/fixture-log.py` with its own ray casting on the depot grid)
//! replays on the host and, converted by `scenario --from-log`, on the QEMU
//! board to the same final pose; every malformed log of docs/log.md's table
//! is refused with its line and nothing is written.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{board_binary, lab, root, run_json, s, shared_map, tmp};

/// The figures `replay` shares with `simulate`.
const SHARED: [&str; 8] =
    ["dead_reckoning", "threshold", "ekf", "verdicts", "lost", "readings", "distance_m", "duration_s"];

fn simulate_then_replay(map: &str, seed: &str) {
    let map = shared_map(map);
    let log = tmp("logrep", &format!("{}-{seed}.csv", map.file_stem().unwrap().to_str().unwrap()));
    let sim =
        run_json(&["simulate", "--json", "--map", s(&map), "--seed", seed, "--distance-m", "25", "--log", s(&log)]);
    let rep = run_json(&["replay", "--json", "--map", s(&map), "--log", s(&log)]);
    for k in SHARED {
        assert_eq!(sim[k], rep[k], "{}: {k} differs between simulate and replay of its log", map.display());
    }
    // And the figures are real ones: the EKF tracked, dead reckoning drifted.
    assert!(rep["ekf"]["position_rmse_m"].as_f64().unwrap() < 0.1, "{rep}");
    assert_eq!(rep["log"]["rows"], rep["readings"]);
}

#[test]
fn replaying_a_simulate_log_gives_the_simulate_figures_depot() {
    simulate_then_replay("depot.yaml", "3");
}

#[test]
fn replaying_a_simulate_log_gives_the_simulate_figures_tb3_sandbox() {
    simulate_then_replay("tb3_sandbox.yaml", "2");
}

fn fixture() -> PathBuf {
    root().join("lab/tests/data/depot-hand.csv")
}

fn depot_blob() -> PathBuf {
    root().join("boards/qemu-mps2-an386/depot.map")
}

#[test]
fn the_fixture_is_what_its_script_writes() {
    let o = Command::new("python3")
        .arg(root().join("scripts/fixture-log.py"))
        .arg(shared_map("depot.pgm"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.stdout == std::fs::read(fixture()).unwrap(), "stale fixture: re-run scripts/fixture-log.py");
}

#[test]
fn the_hand_made_log_is_corrected_on_the_host() {
    let plot = tmp("logrep", "hand.png");
    let v = run_json(&["replay", "--json", "--map", s(&depot_blob()), "--log", s(&fixture()), "--plot", s(&plot)]);
    assert_eq!((v["log"]["rows"].as_u64(), v["log"]["cycles"].as_u64()), (Some(400), Some(25)));
    for p in [plot.clone(), plot.with_file_name("hand-error.png")] {
        let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 1000, "{}", p.display());
    }
    let ekf = v["ekf"]["final_position_error_m"].as_f64().unwrap();
    let dr = v["dead_reckoning"]["final_position_error_m"].as_f64().unwrap();
    // The script's odometry drifts 17 cm over 4 m; the map pulls the EKF back.
    assert!(dr > 0.15 && ekf < dr / 2.0, "EKF {ekf} m against dead reckoning {dr} m");
    assert!(v["ekf"]["accepted"].as_u64().unwrap() > 10, "{v}");
}

/// The board's replay firmware on a scenario file; its output.
fn qemu_replay(scn: &Path) -> String {
    let elf = board_binary("replay");
    let o = Command::new("timeout")
        .args(["300", "qemu-system-arm", "-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic"])
        .args(["-monitor", "none", "-serial", "none", "-icount", "shift=0"])
        .args(["-semihosting-config", "enable=on,target=native", "-device"])
        .arg(format!("loader,file={},addr=0x00300000", s(scn)))
        .arg("-kernel")
        .arg(&elf)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "the board's replay failed:\n{out}");
    out
}

#[test]
fn the_hand_made_log_gives_the_same_final_pose_on_the_board() {
    let scn = tmp("logrep", "hand.scn");
    let conv = run_json(&[
        "scenario",
        "--from-log",
        s(&fixture()),
        "--map",
        s(&depot_blob()),
        "-o",
        s(&scn),
        "--bounds",
        "0.1,5",
    ]);
    assert_eq!((conv["records"].as_u64(), conv["reference"].as_bool()), (Some(400), Some(true)));
    let host = run_json(&["replay", "--json", "--map", s(&depot_blob()), "--log", s(&fixture())]);
    let out = qemu_replay(&scn);
    // "final estimate (x, y) m, θ rad"
    let tail = out.split("final estimate (").nth(1).unwrap_or_else(|| panic!("no final estimate in:\n{out}"));
    let nums: Vec<f64> = tail.split([',', ')', ' ']).filter_map(|t| t.parse().ok()).take(3).collect();
    let want: Vec<f64> = host["ekf"]["final_pose"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    // Tolerance: the board times each echo to the µs and converts it back,
    // within 1 mm of the logged range; the filter is the same f32 code.
    // 1 mm and 1 mrad; seen: equal to the printed 6 decimals.
    assert!((nums[0] - want[0]).abs() <= 1e-3 && (nums[1] - want[1]).abs() <= 1e-3, "{nums:?} vs {want:?}");
    assert!((nums[2] - want[2]).abs() <= 1e-3, "{nums:?} vs {want:?}");
    assert!(out.contains("0 invalid"), "every converted echo is one the driver accepts:\n{out}");
}

const HEAD: &str = "time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad";

#[test]
fn whole_ring_rows_sharing_one_time_and_logs_without_a_reference() {
    // Four cycles of a whole ring read at once, standing still at 1 m from nothing in particular.
    let mut text = format!("{HEAD}\n");
    for c in 0..4 {
        for t in 0..16 {
            text += &format!("{}.5,{t},,{},0,0\n", c, f64::from(c) * 0.1);
        }
    }
    let log = tmp("logrep", "whole.csv");
    std::fs::write(&log, &text).unwrap();
    let v = run_json(&["replay", "--json", "--map", s(&depot_blob()), "--log", s(&log), "--initial-pose", "6,5,90"]);
    assert_eq!((v["log"]["cycles"].as_u64(), v["readings"].as_u64()), (Some(4), Some(64)));
    assert!(v["ekf"]["position_rmse_m"].is_null(), "no reference, no error figures: {v}");
    let pose: Vec<f64> =
        v["dead_reckoning"]["final_pose"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    // 0.3 m forward, facing +y from (6, 5): by hand (6, 5.3, π/2).
    assert!((pose[0] - 6.0).abs() < 1e-6 && (pose[1] - 5.3).abs() < 1e-6, "{pose:?}");
    assert!((pose[2] - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
    assert!(v["ekf"]["covariance"][0][0].as_f64().unwrap() > 0.0);
    // Converted without a reference: no bounds.
    let scn = tmp("logrep", "whole.scn");
    let c = run_json(&["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn)]);
    assert!(c["bounds"].is_null() && c["reference"] == false, "{c}");
}

/// A log that must be refused: the replay's error names `line` and says
/// `says`; `--plot` wrote nothing, and neither did `scenario --from-log`.
fn refused(name: &str, body: &str, line: u64, says: &str) {
    let log = tmp("logbad", &format!("{name}.csv"));
    std::fs::write(&log, body).unwrap();
    let plot = tmp("logbad", &format!("{name}.png"));
    let o = lab().args(["replay", "--map", s(&depot_blob()), "--log", s(&log), "--plot", s(&plot)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{name}: accepted");
    let at = if line == 0 { String::new() } else { format!("line {line}: ") };
    assert!(err.contains(&at) && err.contains(says), "{name}: wanted {at:?} and {says:?}, got {err}");
    assert!(!plot.exists(), "{name}: a plot was written");
    let scn = tmp("logbad", &format!("{name}.scn"));
    let o = lab().args(["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn)]).output().unwrap();
    assert!(!o.status.success() && !scn.exists(), "{name}: converted");
}

macro_rules! malformed {
    ($($name:ident: $body:expr, $line:expr, $says:expr;)*) => {$(
        #[test]
        fn $name() {
            let body: String = $body.into();
            refused(stringify!($name), &body, $line, $says);
        }
    )*};
}

malformed! {
    rows_out_of_time_order: format!("{HEAD}\n0.2,0,,0,0,0\n0.1,1,,0,0,0\n"), 3, "earlier than the row before it";
    unknown_transducer: format!("{HEAD}\n0,0,,0,0,0\n0,16,1000,0,0,0\n"), 3, "transducer 16: the ring has 16";
    transducer_not_an_index: format!("{HEAD}\n0,1.5,,0,0,0\n"), 2, "is not an index";
    non_finite_odometry: format!("{HEAD}\n0,0,,NaN,0,0\n"), 2, "odom_x_m is not finite";
    infinite_range: format!("{HEAD}\n0,0,inf,0,0,0\n"), 2, "range_mm is not finite";
    not_a_number: format!("{HEAD}\n0,0,12x,0,0,0\n"), 2, "range_mm \"12x\" is not a number";
    missing_column_in_header: "time_s,transducer,range_mm,odom_x_m,odom_y_m\n0,0,,0,0\n", 1, "no column odom_theta_rad";
    missing_cell_in_row: format!("{HEAD}\n0,0,,0,0,0\n0,1,,0,0\n"), 3, "5 cells where the header has 6";
    empty_odometry_cell: format!("{HEAD}\n0,0,,0,,0\n"), 2, "odom_y_m is empty";
    unknown_column: format!("{HEAD},odom_th\n0,0,,0,0,0,0\n"), 1, "column \"odom_th\" is not one of";
    partial_reference_columns: format!("{HEAD},ref_x_m,ref_y_m\n0,0,,0,0,0,1,1\n"), 1, "all three columns";
    partial_reference_row: format!("{HEAD},ref_x_m,ref_y_m,ref_theta_rad\n0,0,,0,0,0,1,,0\n"), 2, "all three cells";
    heading_jump: format!("{HEAD}\n0,0,,0,0,0\n0.04,1,,0.01,0,3.0\n"), 3, "that is not odometry";
    degrees_as_radians: format!("{HEAD}\n0,0,,0,0,0\n0.04,1,,0.01,0,90\n"), 3, "degrees logged as radians";
    zero_range: format!("{HEAD}\n0,0,0,0,0,0\n"), 2, "range_mm 0: a range must be above 0";
    negative_range: format!("{HEAD}\n0,0,-300,0,0,0\n"), 2, "range_mm -300";
    negative_time: format!("{HEAD}\n-1,0,,0,0,0\n"), 2, "time_s -1 is negative";
    no_rows: format!("{HEAD}\n"), 0, "the log has no rows";
    empty_file: "", 1, "no header line";
}

#[test]
fn logs_the_driver_could_not_have_made_are_not_converted() {
    // A complete cycle but one range inside the Polaroid module's blanking (≈ 0.41 m).
    let mut text = format!("{HEAD}\n");
    for t in 0..16 {
        let r = if t == 5 { "200" } else { "" };
        text += &format!("0.{t:02},{t},{r},0,0,0\n");
    }
    let log = tmp("logbad", "blanking.csv");
    std::fs::write(&log, &text).unwrap();
    let scn = tmp("logbad", "blanking.scn");
    let o = lab()
        .args(["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn), "--refuse-unreportable"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("line 7: range 200 mm is inside the driver's blanking"), "{err}");
    assert!(!scn.exists());
    // By default (#37) it reaches the driver as the driver reports it: no echo, counted.
    let v = run_json(&["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn)]);
    assert_eq!((v["unreportable"]["inside_blanking"].as_u64(), v["records"].as_u64()), (Some(1), Some(16)), "{v}");
    let bytes = std::fs::read(&scn).unwrap();
    let sc = echoloc::scenario::Scenario::parse(&bytes).unwrap();
    assert!(sc.records().all(|r| r.echo_us.is_none()));
    std::fs::remove_file(&scn).unwrap();
    // A cycle that lacks transducers: the driver fires all of them.
    let text = format!("{HEAD}\n0,0,,0,0,0\n0.1,1,,0,0,0\n0.2,0,,0,0,0\n");
    std::fs::write(&log, text).unwrap();
    let o = lab().args(["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("line 2: the ring cycle starting here lacks transducer(s) 2, 3"),
        "{err}"
    );
    assert!(!scn.exists());
    // The host replay takes such a log: partial cycles are fine there.
    let v = run_json(&["replay", "--json", "--map", s(&depot_blob()), "--log", s(&log), "--initial-pose", "6,5,0"]);
    assert_eq!(v["log"]["cycles"].as_u64(), Some(2));
    // A log that ends mid-ring (#47): its last ring dropped, with a note,
    // the whole rings before it converted.
    let ring =
        |c: usize, ts: std::ops::Range<u32>| -> String { ts.map(|t| format!("{}.{t:02},{t},,0,0,0\n", c)).collect() };
    std::fs::write(&log, format!("{HEAD}\n{}{}{}", ring(0, 0..16), ring(1, 0..16), ring(2, 0..5))).unwrap();
    let o = lab().args(["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn)]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!((v["records"].as_u64(), v["cycles"].as_u64()), (Some(32), Some(2)), "{v}");
    assert_eq!(v["partial_last_ring"], serde_json::json!({"readings": 5, "line": 34}), "{v}");
    let note = String::from_utf8_lossy(&o.stderr);
    assert!(
        note.contains("the log ends mid-ring: its last ring cycle (line 34) has 5 of the 16 readings, dropped"),
        "{note}"
    );
    std::fs::remove_file(&scn).unwrap();
    // A whole log keeps every ring and says nothing was dropped.
    std::fs::write(&log, format!("{HEAD}\n{}{}", ring(0, 0..16), ring(1, 0..16))).unwrap();
    let v = run_json(&["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn)]);
    assert_eq!((v["records"].as_u64(), v["partial_last_ring"].is_null()), (Some(32), true), "{v}");
    std::fs::remove_file(&scn).unwrap();
    // A ring cut short in the middle (a logger that lost readings) is still refused.
    std::fs::write(&log, format!("{HEAD}\n{}{}{}", ring(0, 0..16), ring(1, 0..5), ring(2, 0..16))).unwrap();
    let o = lab().args(["scenario", "--from-log", s(&log), "--map", s(&depot_blob()), "-o", s(&scn)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("line 18: the ring cycle starting here lacks transducer(s) 5, 6"),
        "{err}"
    );
    assert!(!scn.exists());
}
