//! ROS 2 bags out (`echoloc_lab::bag::write`, docs/bags.md "ROS 2 bags
//! out"): a simulated depot run written as a rosbag2 bag reads back through
//! echoloc's own bag reader as the very rows it was written from, and PyPI's
//! `rosbags` (an independent reader, `scripts/bag-check.py`) reads the same
//! bag: its schemas, type hashes, QoS and every message's CDR. `simulate
//! --bag` and `log --to-bag` write it; bad rows and an existing directory
//! are refused, and nothing is left behind.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use common::{lab, root, run_json, s, shared_map, tmp};
use echoloc::predict::{Mount, PIONEER16};
use echoloc_lab::bag::write::{write_bag, Compression, RowProblem, WriteError, WriteOptions};
use echoloc_lab::bag::{read, Options};
use echoloc_lab::log::Row;
use serde_json::Value;

/// A simulated depot run's log (the true pose as reference), made once.
fn run_log() -> &'static PathBuf {
    static LOG: OnceLock<PathBuf> = OnceLock::new();
    LOG.get_or_init(|| {
        let log = tmp("bagw", "depot-run.csv");
        let map = shared_map("depot.yaml");
        run_json(&["simulate", "--json", "--map", s(&map), "--seed", "3", "--distance-m", "20", "--log", s(&log)]);
        log
    })
}

fn run_rows() -> Vec<Row> {
    echoloc_lab::log::read_file(run_log(), 16).unwrap().rows
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

fn ns(t: f64) -> i64 {
    (t * 1e9).round() as i64
}

/// Equal poses: positions to 1e-9 m, headings to 1e-9 rad modulo a turn
/// (a quaternion gives the heading back wrapped).
fn same_pose(a: [f64; 3], b: [f64; 3], what: &str) {
    assert!((a[0] - b[0]).abs() <= 1e-9 && (a[1] - b[1]).abs() <= 1e-9, "{what}: {a:?} vs {b:?}");
    assert!(wrap(a[2] - b[2]).abs() <= 1e-9, "{what}: heading {a:?} vs {b:?}");
}

/// The rows read back are the rows written: times to the ns, every range
/// to the mm, poses as [`same_pose`].
fn same_rows(written: &[Row], read: &[Row]) {
    assert_eq!(written.len(), read.len());
    for (i, (w, r)) in written.iter().zip(read).enumerate() {
        assert_eq!(ns(w.time_s), ns(r.time_s), "row {i}: time");
        assert_eq!((w.transducer, w.range_mm), (r.transducer, r.range_mm), "row {i}");
        same_pose(w.odometry, r.odometry, &format!("row {i} odometry"));
        match (w.reference, r.reference) {
            (Some(a), Some(b)) => same_pose(a, b, &format!("row {i} reference")),
            (a, b) => assert_eq!(a.is_some(), b.is_some(), "row {i}: reference"),
        }
    }
}

/// Nothing of a refused bag is left: neither it nor a hidden partial sibling.
fn nothing_left(dir: &Path) {
    let parent = dir.parent().unwrap();
    let name = dir.file_name().unwrap().to_str().unwrap();
    let partial = std::fs::read_dir(parent)
        .unwrap()
        .filter_map(|e| e.ok())
        .any(|e| e.file_name().to_str().is_some_and(|n| n.starts_with(&format!(".{name}."))));
    assert!(!partial, "a partial {name} is left in {}", parent.display());
}

#[test]
fn a_simulated_run_reads_back_as_its_rows_and_ring() {
    let rows = run_rows();
    assert_eq!(rows.len(), 1344);
    for (name, compression) in [("rt", Compression::None), ("rt-zstd", Compression::Zstd)] {
        let dir = tmp("bagw", name);
        let opt = WriteOptions { compression, ..WriteOptions::default() };
        let w = write_bag(&dir, &rows, &PIONEER16, &opt).unwrap();
        assert_eq!(w.mcap, dir.join(format!("{name}_0.mcap")));
        assert!(dir.join("metadata.yaml").is_file() && w.mcap.is_file());
        nothing_left(&dir);
        // 16 Range topics, /tf_static, /odom, /tf and /ground_truth; one
        // odometry per distinct time (here every row's).
        assert_eq!(w.topics.len(), 20);
        assert_eq!(w.messages, 1 + 1344 * 4);

        let bag = read(&dir, &Options::default()).unwrap();
        same_rows(&rows, &bag.rows);
        assert_eq!(bag.ring, PIONEER16.to_vec());
        assert_eq!(bag.outside_odometry, 0);
        let u = &bag.used;
        assert_eq!(
            (u.odometry.as_str(), u.reference.as_deref(), u.ring.as_str()),
            ("/odom", Some("/ground_truth"), "/tf_static")
        );
        assert_eq!(bag.transducers[10].frame, "sonar_10");
        // REP 117: no echo is +Inf, and only that.
        let silent = rows.iter().filter(|r| r.range_mm.is_none()).count() as u32;
        assert!(silent > 0);
        assert_eq!(bag.no_echo, echoloc_lab::bag::NoEcho { infinite: silent, ..Default::default() });
    }
}

/// Rows of a whole-ring reading share one time (and one odometry message);
/// a transducer that never reads has no Range, and a ring read from the
/// Range frames closes up without it, each row keeping its own mount.
#[test]
fn whole_ring_readings_and_a_silent_transducer() {
    let mut rows = Vec::new();
    for cycle in 0..3 {
        let t = 10.0 + 0.7 * f64::from(cycle);
        let odom = [1.0 + 0.1 * f64::from(cycle), -2.0, 3.0 + 0.05 * f64::from(cycle)];
        for k in (0..16u8).filter(|&k| k != 9) {
            let range_mm = (k % 5 != 0).then_some(500 + 100 * u32::from(k) + cycle);
            rows.push(Row { time_s: t, transducer: k, range_mm, odometry: odom, reference: None, line: 0 });
        }
    }
    let dir = tmp("bagw", "ring");
    let w = write_bag(&dir, &rows, &PIONEER16, &WriteOptions { tf: false, ..WriteOptions::default() }).unwrap();
    assert_eq!(w.messages, 1 + 3 + rows.len(), "one /odom per time, no /tf, no /ground_truth");
    assert!(w.topics.iter().any(|(t, _, n)| t == "/sonar/9" && *n == 0), "{:?}", w.topics);
    let bag = read(&dir, &Options::default()).unwrap();
    assert_eq!(bag.ring.len(), 15);
    assert!(!bag.has_reference());
    // Ties come back in the reader's order; each row with its own mount.
    let key = |r: &Row, ring: &[Mount]| (ns(r.time_s), ring[usize::from(r.transducer)], r.range_mm);
    let mut want: Vec<_> = rows.iter().map(|r| key(r, &PIONEER16)).collect();
    let mut got: Vec<_> = bag.rows.iter().map(|r| key(r, &bag.ring)).collect();
    let order = |a: &(i64, Mount, Option<u32>), b: &(i64, Mount, Option<u32>)| {
        (a.0, a.1.heading_mdeg, a.1.x_mm, a.1.y_mm).cmp(&(b.0, b.1.heading_mdeg, b.1.x_mm, b.1.y_mm))
    };
    want.sort_by(order);
    got.sort_by(order);
    assert_eq!(want, got);
    for r in &bag.rows {
        let cycle = ((r.time_s - 10.0) / 0.7).round();
        same_pose(r.odometry, [1.0 + 0.1 * cycle, -2.0, 3.0 + 0.05 * cycle], "odometry");
    }
}

/// `scripts/bag-check.py` runs PyPI's rosbags on the bag; skipped only
/// when python3 or rosbags is missing (`scripts/setup.sh` installs it).
fn independent_reader(dir: &Path) -> Option<Value> {
    let probe = Command::new("python3").args(["-c", "import rosbags"]).output();
    if !probe.is_ok_and(|o| o.status.success()) {
        eprintln!(
            "SKIPPED the independent reader: python3 with PyPI's rosbags is not installed (bash scripts/setup.sh)"
        );
        return None;
    }
    let o = Command::new("python3").arg(root().join("scripts/bag-check.py")).arg(dir).output().unwrap();
    assert!(o.status.success(), "scripts/bag-check.py: {}", String::from_utf8_lossy(&o.stderr));
    Some(serde_json::from_slice(&o.stdout).unwrap())
}

#[test]
fn rosbags_reads_what_was_written() {
    let rows = run_rows();
    let dir = tmp("bagw", "indep");
    write_bag(&dir, &rows, &PIONEER16, &WriteOptions::default()).unwrap();
    let Some(v) = independent_reader(&dir) else { return };

    let m = &v["metadata"];
    assert_eq!((m["version"].as_u64(), m["ros_distro"].as_str()), (Some(8), Some("jazzy")), "{m}");
    assert_eq!(m["message_count"], 1 + 4 * 1344);
    assert_eq!(m["files"], serde_json::json!(["indep_0.mcap"]));
    // Counts per topic, and the durability each offers.
    let t = &v["topics"];
    for k in 0..16u8 {
        let n = rows.iter().filter(|r| r.transducer == k).count();
        assert_eq!(t[format!("/sonar/{k}")]["count"], n, "{t}");
        assert_eq!(t[format!("/sonar/{k}")]["durability"], "volatile");
    }
    assert_eq!(t["/tf_static"]["count"], 1);
    assert_eq!(t["/tf_static"]["durability"], "transient_local");
    for topic in ["/odom", "/tf", "/ground_truth"] {
        assert_eq!(t[topic]["count"], 1344, "{topic}: one per distinct time");
    }
    // The first and last Range: topic, frame, stamp, range (f32 metres, +Inf no echo).
    let r = &v["ranges"];
    assert_eq!(r["count"], 1344);
    assert_eq!(r["infinite"], rows.iter().filter(|r| r.range_mm.is_none()).count());
    for (which, row) in [("first", &rows[0]), ("last", &rows[rows.len() - 1])] {
        let x = &r[which];
        assert_eq!(x["topic"], format!("/sonar/{}", row.transducer), "{which}: {x}");
        assert_eq!(x["frame"], format!("sonar_{}", row.transducer));
        assert_eq!(x["stamp_ns"].as_i64(), Some(ns(row.time_s)), "{which}: {x}");
        assert_eq!(x["radiation_type"], 0, "ULTRASOUND");
        let want = match row.range_mm {
            Some(mm) => serde_json::json!(f64::from((f64::from(mm) / 1000.0) as f32)),
            None => serde_json::json!("inf"),
        };
        assert_eq!(x["range"], want, "{which}: {x}");
    }
    // One set of limits on every Range: min, max, field of view (f32).
    let limits = r["limits"].as_array().unwrap();
    assert_eq!(limits.len(), 1, "{r}");
    for (got, want) in limits[0].as_array().unwrap().iter().zip([0.408f32, 5.5, 30f32.to_radians()]) {
        assert!((got.as_f64().unwrap() - f64::from(want)).abs() < 1e-7, "{limits:?}");
    }
    // /tf_static: base_link -> sonar_k at each mount.
    let tf = v["tf_static"].as_array().unwrap();
    assert_eq!(tf.len(), 16);
    for (k, (x, mount)) in tf.iter().zip(PIONEER16.iter()).enumerate() {
        assert_eq!((x["parent"].as_str(), x["child"].as_str()), (Some("base_link"), Some(&*format!("sonar_{k}"))));
        assert!((x["x"].as_f64().unwrap() - f64::from(mount.x_mm) / 1000.0).abs() < 1e-12, "{x}");
        assert!((x["y"].as_f64().unwrap() - f64::from(mount.y_mm) / 1000.0).abs() < 1e-12, "{x}");
        let d = x["yaw_deg"].as_f64().unwrap() - f64::from(mount.heading_mdeg) / 1000.0;
        assert!(d.abs() < 1e-9, "{x}");
    }
    // The odometry and the reference, first and last.
    for (topic, frame, pick) in [
        ("/odom", "odom", (|r: &Row| r.odometry) as fn(&Row) -> [f64; 3]),
        ("/ground_truth", "map", |r: &Row| r.reference.unwrap()),
    ] {
        let o = &v["odometry"][topic];
        assert_eq!(o["count"], 1344);
        for (which, row) in [("first", &rows[0]), ("last", &rows[rows.len() - 1])] {
            let x = &o[which];
            assert_eq!((x["frame"].as_str(), x["child"].as_str()), (Some(frame), Some("base_link")));
            assert_eq!(x["stamp_ns"].as_i64(), Some(ns(row.time_s)));
            let got = [x["x"].as_f64().unwrap(), x["y"].as_f64().unwrap(), x["yaw"].as_f64().unwrap()];
            same_pose(pick(row), got, &format!("{topic} {which}"));
        }
    }
}

#[test]
fn simulate_bag_is_the_run_its_log_is() {
    let map = shared_map("depot.yaml");
    let (log, dir) = (tmp("bagw", "sim.csv"), tmp("bagw", "sim-bag"));
    let args = ["simulate", "--json", "--map", s(&map), "--seed", "3", "--distance-m", "20"];
    let mut all = args.to_vec();
    all.extend(["--log", s(&log), "--bag", s(&dir)]);
    run_json(&all);
    let rows = echoloc_lab::log::read_file(&log, 16).unwrap().rows;
    same_rows(&rows, &read(&dir, &Options::default()).unwrap().rows);
    // Again onto the same directory: refused before the run, nothing written.
    let log2 = tmp("bagw", "sim2.csv");
    let mut again = args.to_vec();
    again.extend(["--log", s(&log2), "--bag", s(&dir)]);
    let o = lab().args(&again).output().unwrap();
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("--bag") && e.contains("exists already"), "{e}");
    assert!(!log2.exists(), "a refused run writes nothing");
}

/// `log --to-bag` and back; the bag replays to the log's figures, every key.
#[test]
fn log_to_bag_and_back() {
    let dir = tmp("bagw", "cli-bag");
    let v = run_json(&["log", "--to-bag", s(run_log()), "-o", s(&dir), "--ring", "pioneer16", "--zstd"]);
    assert_eq!((v["rows"].as_u64(), v["messages"].as_u64()), (Some(1344), Some(1 + 4 * 1344)), "{v}");
    assert_eq!(v["topics"]["/sonar/3"]["messages"], 84);
    let back = tmp("bagw", "cli-back.csv");
    run_json(&["log", "--from-bag", s(&dir), "-o", s(&back)]);
    same_rows(&run_rows(), &echoloc_lab::log::read_file(&back, 16).unwrap().rows);

    let map = shared_map("depot.yaml");
    let by_bag = run_json(&["replay", "--json", "--map", s(&map), "--bag", s(&dir)]);
    let by_log = run_json(&["replay", "--json", "--map", s(&map), "--log", s(run_log())]);
    let mut n = 0;
    for (k, want) in by_log.as_object().unwrap() {
        assert_eq!(&by_bag[k], want, "{k} differs between the bag and its log");
        n += 1;
    }
    assert!(n > 5 && by_bag["bag"].is_object(), "{by_bag}");

    // Onto an existing directory: refused, the directory untouched.
    let o = lab().args(["log", "--to-bag", s(run_log()), "-o", s(&dir)]).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("exists already"));
    assert!(dir.join("metadata.yaml").is_file());
}

#[test]
fn refusals_write_nothing() {
    let row = |time_s: f64, transducer: u8, range_mm: Option<u32>| Row {
        time_s,
        transducer,
        range_mm,
        odometry: [0.0, 0.0, 0.0],
        reference: None,
        line: 0,
    };
    let good = vec![row(0.0, 0, Some(1000)), row(0.1, 1, None)];
    let opt = WriteOptions::default();

    // The directory exists: refused, and what is in it stays.
    let dir = tmp("bagw", "exists");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("mine.txt"), "keep").unwrap();
    assert_eq!(write_bag(&dir, &good, &PIONEER16, &opt), Err(WriteError::Exists(dir.clone())));
    assert_eq!(std::fs::read_to_string(dir.join("mine.txt")).unwrap(), "keep");
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    nothing_left(&dir);

    // Bad rows: each names the row; no directory is made.
    let mut beyond = good.clone();
    beyond.push(Row { line: 4, ..row(0.2, 16, Some(900)) });
    let mut backwards = good.clone();
    backwards.push(row(0.05, 2, None));
    let mut conflict = good.clone();
    conflict.push(Row { odometry: [0.5, 0.0, 0.0], ..row(0.1, 2, None) });
    let mut too_far = good.clone();
    too_far.push(row(0.2, 3, Some(6000)));
    let mut too_near = good.clone();
    too_near.push(row(0.2, 3, Some(300)));
    let mut nan = good.clone();
    nan.push(Row { odometry: [f64::NAN, 0.0, 0.0], ..row(0.2, 3, None) });
    // A name, the rows, the ring, the options, the error's start.
    type Case = (&'static str, Vec<Row>, Vec<Mount>, WriteOptions, String);
    let cases: Vec<Case> = vec![
        (
            "beyond",
            beyond,
            PIONEER16.to_vec(),
            opt.clone(),
            "row 2 (line 4): transducer 16: the ring has 16 (0 to 15)".into(),
        ),
        (
            "small-ring",
            good.clone(),
            PIONEER16[..1].to_vec(),
            opt.clone(),
            "row 1: transducer 1: the ring has 1 (0 to 0)".into(),
        ),
        (
            "backwards",
            backwards,
            PIONEER16.to_vec(),
            opt.clone(),
            "row 2: time 0.05 s is earlier than the row before it (0.1 s): rows must be in time order".into(),
        ),
        (
            "conflict",
            conflict,
            PIONEER16.to_vec(),
            opt.clone(),
            "row 2: another row at 0.1 s has another odometry pose: one message per stamp cannot say both".into(),
        ),
        ("far", too_far, PIONEER16.to_vec(), opt.clone(), "row 2: range 6000 mm is outside the Range limits".into()),
        ("near", too_near, PIONEER16.to_vec(), opt.clone(), "row 2: range 300 mm is outside".into()),
        (
            "nan",
            nan,
            PIONEER16.to_vec(),
            opt.clone(),
            "row 2: the odometry pose has a number that is not finite".into(),
        ),
        ("negative", vec![row(-1.0, 0, None)], PIONEER16.to_vec(), opt.clone(), "row 0: time -1 s".into()),
        ("empty", vec![], PIONEER16.to_vec(), opt.clone(), "no rows".into()),
        ("no-ring", good.clone(), vec![], opt.clone(), "the ring has no transducers".into()),
        (
            "limits",
            good.clone(),
            PIONEER16.to_vec(),
            WriteOptions { min_range_m: 6.0, ..opt.clone() },
            "min_range_m, max_range_m: 6 m, 5.5 m".into(),
        ),
        (
            "mm",
            good.clone(),
            PIONEER16.to_vec(),
            WriteOptions { max_range_m: 5500.0, ..opt.clone() },
            "max_range_m: 5500 m: beyond any sonar".into(),
        ),
    ];
    for (name, rows, ring, o, want) in cases {
        let dir = tmp("bagw", &format!("refused-{name}"));
        let e = write_bag(&dir, &rows, &ring, &o).unwrap_err();
        assert!(e.to_string().starts_with(&want), "{name}: {e}");
        assert!(!dir.exists(), "{name}: a refused bag leaves no directory");
        nothing_left(&dir);
    }
    let e = write_bag(&tmp("bagw", "x"), &[row(0.0, 16, None)], &PIONEER16, &opt).unwrap_err();
    assert!(matches!(
        e,
        WriteError::Row { index: 0, problem: RowProblem::TransducerBeyondRing { transducer: 16, ring: 16 }, .. }
    ));
    // A parent that does not exist.
    let e = write_bag(&tmp("bagw", "no/such/bag"), &good, &PIONEER16, &opt).unwrap_err();
    assert!(matches!(e, WriteError::BadPath { .. }), "{e}");
}
