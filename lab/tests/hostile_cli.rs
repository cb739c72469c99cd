//! Hostile command lines (issue #14 item 4): non-finite and huge poses and
//! parameters, zero and negative ranges, half-angles at and past 90°, empty
//! maps, slivers, self-intersecting polygons, 100 000-vertex polygons. Each
//! gets a clear error (exit 1, or clap's 2 for a value it cannot parse, the
//! message naming the problem) or a correct answer (checked against a hand
//! derivation), within a bounded time, never a panic, a hang or silent
//! nonsense. The table in docs/robustness.md lists the same cases.

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{root, s};

use serde_json::Value;

/// Generous: every case takes well under a second; this only catches a hang.
const LIMIT: Duration = Duration::from_secs(120);

struct Run {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

fn run(args: &[&str]) -> Run {
    let mut child = Command::new(env!("CARGO_BIN_EXE_echoloc-lab"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            panic!("{args:?}: no answer within {LIMIT:?} (a hang)");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = child.wait_with_output().unwrap();
    Run {
        code: o.status.code(),
        stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
    }
}

fn refused(args: &[&str], expect: &[&str]) {
    let r = run(args);
    assert!(matches!(r.code, Some(1 | 2)), "{args:?}: exit {:?} (a panic is 101, a signal None): {}", r.code, r.stderr);
    assert!(!r.stderr.contains("panicked"), "{args:?}: {}", r.stderr);
    assert!(r.stdout.is_empty(), "{args:?}: refused but printed {}", r.stdout);
    for e in expect {
        assert!(r.stderr.contains(e), "{args:?}: the error should say {e:?}: {}", r.stderr);
    }
}

fn answered(args: &[&str]) -> Vec<Value> {
    let r = run(args);
    assert_eq!(r.code, Some(0), "{args:?}: {}", r.stderr);
    r.stdout.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

fn office() -> String {
    root().join("boards/qemu-mps2-an386/office.map").to_str().unwrap().to_owned()
}

fn scratch(name: &str, text: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("echoloc-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn non_finite_and_huge_poses_are_refused_with_the_reason() {
    let m = office();
    for (pose, why) in [
        ("nan,4,0", "expected three finite numbers X,Y,DEG"),
        ("4,inf,0", "expected three finite numbers X,Y,DEG"),
        ("4,4,-inf", "expected three finite numbers X,Y,DEG"),
        ("1e30,4,0", "X is beyond ±1073742 m, the map's coordinate range"),
        ("4,-2e6,0", "Y is beyond ±1073742 m"),
        ("4,4,1e30", "DEG is not a heading (beyond ±1000000°)"),
        ("4,4", "expected three finite numbers X,Y,DEG"),
    ] {
        refused(&["predict", "--map", &m, "--pose", pose], &["--pose", why]);
        refused(&["predict", "--map", &m, "--sensor", pose], &["--sensor", why]);
    }
}

#[test]
fn a_heading_of_many_turns_is_the_angle_it_names() {
    // 360 360° is a thousand and one turns: the same readings as 0°.
    let m = office();
    let a = answered(&["predict", "--map", &m, "--pose", "4,4,0"]);
    let b = answered(&["predict", "--map", &m, "--pose", "4,4,360360"]);
    let c = answered(&["predict", "--map", &m, "--pose", "4,4,-720"]);
    assert_eq!(a, b);
    assert_eq!(a, c);
}

#[test]
fn bad_window_parameters_are_refused_with_the_reason() {
    let m = office();
    let bad_range = "bad range: R_min must be below R_max, R_max within 1..=100000 mm";
    let half = "bad half-angle: θ_o must lie strictly between 0° and 90°";
    for (flag, value, why) in [
        ("--rmax-mm", "0", bad_range),
        ("--rmax-mm", "4000000000", bad_range),
        ("--rmax-mm", "-5", "invalid value '-5' for '--rmax-mm <RMAX_MM>'"),
        ("--rmin-mm", "6000", bad_range),
        ("--rmin-mm", "-1", "invalid value '-1' for '--rmin-mm <RMIN_MM>'"),
        ("--half-angle-deg", "90", half),
        ("--half-angle-deg", "135", half),
        ("--half-angle-deg", "0", half),
        ("--half-angle-deg", "-3", half),
        ("--half-angle-deg", "nan", half),
        ("--half-angle-deg", "inf", half),
        ("--delta-max-deg", "nan", "bad δ_max: it must lie in [0°, 90°)"),
        ("--delta-max-deg", "90", "bad δ_max: it must lie in [0°, 90°)"),
        ("--ds-min-mm", "0", "d_s_min is 0 mm"),
        ("--tau", "nan", "--tau NaN: must be within 0..=1"),
        ("--tau", "-1", "--tau -1: must be within 0..=1"),
    ] {
        refused(&["predict", "--map", &m, "--pose", "4,4,0", flag, value], &[why]);
    }
    refused(
        &["window", "--rmax-mm", "-2400", "--half-angle-deg", "30", "--ds-min-mm", "300", "--delta-max-deg", "15"],
        &["invalid value '-2400'"],
    );
    refused(
        &["window", "--rmax-mm", "2400", "--half-angle-deg", "90", "--ds-min-mm", "300", "--delta-max-deg", "15"],
        &[half],
    );
    // A layout too fine for a window: refused in words a person can act on.
    refused(
        &["predict", "--map", &m, "--pose", "4,4,0", "--collect", "pseudo-paths", "--ds-min-mm", "20"],
        &["needs 328 paths, more than the 256", "raise d_s_min", "use the exact strategy"],
    );
}

#[test]
fn parameters_at_the_edge_of_the_valid_give_correct_answers() {
    let m = office();
    // θ_o just below 90°: every transducer answers within R_max (or nothing).
    for l in answered(&["predict", "--map", &m, "--pose", "4,4,0", "--half-angle-deg", "89.99"]) {
        if let Some(r) = l["range_m"].as_f64() {
            assert!(r > 0.0 && r <= 5.5, "{l}");
        }
    }
    // The smallest d_s_min with the exact strategy: the table's left face,
    // 1 m ahead of (1, 2.4) (hand-derived: the face is x = 2 m).
    let l = &answered(&["predict", "--map", &m, "--sensor", "1,2.4,0", "--ds-min-mm", "1", "--credence", "crisp"])[0];
    assert_eq!((l["range_m"].as_f64(), l["point"].clone()), (Some(1.0), serde_json::json!([2.0, 2.4])));
    // R_max of 1 mm: nothing within it.
    let l = &answered(&["predict", "--map", &m, "--sensor", "1,2.4,0", "--rmax-mm", "1", "--rmin-mm", "0"])[0];
    assert_eq!(l["range_m"], Value::Null);
}

#[test]
fn empty_maps_answer_nothing_and_refuse_a_route() {
    let empty = scratch("empty.geojson", r#"{"type":"FeatureCollection","features":[]}"#);
    for l in answered(&["predict", "--map", s(&empty), "--pose", "1,1,0"]) {
        assert_eq!(l["range_m"], Value::Null, "{l}");
    }
    // Compiled, it validates on load and answers the same.
    let blob = empty.with_extension("map");
    let summary = &answered(&["map", "import", s(&empty), "-o", s(&blob)])[0];
    assert_eq!(summary["convex_pieces"], 0);
    for l in answered(&["predict", "--map", s(&blob), "--pose", "1,1,0"]) {
        assert_eq!(l["range_m"], Value::Null, "{l}");
    }
    refused(&["simulate", "--map", s(&empty), "--json", "--distance-m", "10"], &["the map has no obstacles"]);
}

#[test]
fn slivers_and_self_intersecting_polygons() {
    // No area left in whole millimetres: refused as degenerate.
    let flat = scratch("flat.geojson", r#"{"type":"Polygon","coordinates":[[[0,0],[10,0],[5,0.0000001],[0,0]]]}"#);
    refused(&["predict", "--map", s(&flat), "--sensor", "5,-1,90"], &["Degenerate: the outer ring has no area"]);
    // A 10 m × 2 mm sliver: looking straight at it from 1 m below its
    // bottom edge (y = 0), the range is 1 m at (5, 0).
    let sliver = scratch("sliver.geojson", r#"{"type":"Polygon","coordinates":[[[0,0],[10,0],[5,0.002],[0,0]]]}"#);
    let l = &answered(&["predict", "--map", s(&sliver), "--sensor", "5,-1,90", "--credence", "crisp"])[0];
    assert_eq!((l["range_m"].as_f64(), l["point"].clone()), (Some(1.0), serde_json::json!([5.0, 0.0])));
    let bowtie = scratch("bowtie.geojson", r#"{"type":"Polygon","coordinates":[[[0,0],[1,1],[1,0],[0,1],[0,0]]]}"#);
    refused(&["predict", "--map", s(&bowtie), "--sensor", "5,-1,90"], &["NotSimple"]);
    let eight =
        scratch("eight.geojson", r#"{"type":"Polygon","coordinates":[[[0,0],[2,0],[1,1],[2,2],[0,2],[1,1],[0,0]]]}"#);
    refused(&["map", "import", s(&eight), "-o", s(&eight.with_extension("map"))], &["NotSimple: edges 1 and 4"]);
    assert!(!eight.with_extension("map").exists());
    let huge = scratch("huge.geojson", r#"{"type":"LineString","coordinates":[[0,0],[1e400,0]]}"#);
    refused(&["predict", "--map", s(&huge), "--sensor", "5,-1,90"], &["not JSON: number out of range"]);
}

#[test]
fn hundred_thousand_vertex_polygons_are_refused_quickly() {
    let n = 100_000;
    let ring: Vec<String> = (0..=n)
        .map(|k| {
            let a = std::f64::consts::TAU * (k % n) as f64 / n as f64;
            format!("[{},{}]", 50.0 * a.cos(), 50.0 * a.sin())
        })
        .collect();
    let circle = scratch("circle.geojson", &format!(r#"{{"type":"Polygon","coordinates":[[{}]]}}"#, ring.join(",")));
    refused(
        &["predict", "--map", s(&circle), "--sensor", "0,0,0"],
        &["TooManyVertices: more than 32768 vertices in one polygon"],
    );
    let line: Vec<String> = (0..n).map(|k| format!("[{},0]", k as f64 * 0.001)).collect();
    let wall = scratch("wall.geojson", &format!(r#"{{"type":"LineString","coordinates":[{}]}}"#, line.join(",")));
    refused(
        &["map", "import", s(&wall), "-o", s(&wall.with_extension("map"))],
        &["exceeds the compiler's capacity", "99999 convex pieces", "simplify more"],
    );
    assert!(!wall.with_extension("map").exists());
}

#[test]
fn simulator_settings_out_of_range_are_refused() {
    let m = office();
    for (flag, value, why) in [
        ("--distance-m", "nan", "--distance-m NaN: must be a positive number"),
        ("--distance-m", "-1", "--distance-m -1: must be a positive number"),
        ("--distance-m", "1e12", "expected more than 0 and at most 20000 m"),
        ("--inconsistent", "2", "--inconsistent 2: must be within 0..=1"),
        ("--inconsistent", "nan", "--inconsistent NaN: must be within 0..=1"),
    ] {
        refused(&["simulate", "--map", &m, "--json", flag, value], &[why]);
    }
}

#[test]
fn a_reader_that_stops_early_is_not_a_crash() {
    // `echoloc-lab predict … | head -1`: the closed pipe ends the run quietly.
    let mut child = Command::new(env!("CARGO_BIN_EXE_echoloc-lab"))
        .args(["predict", "--map", &office(), "--pose", "4,4,0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(o.status.code(), Some(0), "{err}");
}
