//! rosbag2's sqlite3 storage (`.db3`, ROS 2 Humble's default; #37 item 6),
//! checked against an independent writer: `scripts/fixture-bag.py` writes
//! each fixture bag of `bag_replay.rs` with PyPI's `rosbags` in both its
//! storage plugins, MCAP and sqlite3, from the same simulated depot run.
//! Replayed, the two give the same JSON, every key; every refusal the MCAP
//! bag gets, the `.db3` gets word for word; a `.db3` with a table missing or
//! a message cut short is refused with the table, or the topic and the
//! message, and nothing is written.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use common::{lab, root, run_json, s, shared_map, tmp};
use serde_json::Value;

/// A simulated depot run's log (true pose as reference), made once.
fn run_log() -> &'static PathBuf {
    static LOG: OnceLock<PathBuf> = OnceLock::new();
    LOG.get_or_init(|| {
        let log = tmp("bagsq", "depot-run.csv");
        let map = shared_map("depot.yaml");
        run_json(&["simulate", "--json", "--map", s(&map), "--seed", "3", "--distance-m", "20", "--log", s(&log)]);
        log
    })
}

/// Runs the independent writer for one storage; `brk` makes a malformed bag.
fn write_bag(name: &str, form: &str, storage: &str, brk: Option<&str>) -> PathBuf {
    let out = tmp("bagsq", name);
    let mut c = Command::new("python3");
    c.arg(root().join("scripts/fixture-bag.py")).arg(run_log()).arg(&out);
    c.args(["--form", form, "--storage", storage]);
    if let Some(b) = brk {
        c.args(["--break", b]);
    }
    let o = c.output().expect("python3 runs");
    assert!(
        o.status.success(),
        "scripts/fixture-bag.py failed (it needs PyPI's rosbags: `bash scripts/setup.sh` installs it): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // The writer wrote the storage asked for: metadata.yaml says so, and the
    // file is SQLite's or MCAP's by its magic bytes.
    let meta = std::fs::read_to_string(out.join("metadata.yaml")).unwrap();
    assert!(meta.contains(&format!("storage_identifier: {storage}")), "{meta}");
    let ext = if storage == "sqlite3" { "db3" } else { "mcap" };
    let file = out.join(format!("{name}.{ext}"));
    let head = std::fs::read(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let magic: &[u8] = if storage == "sqlite3" { b"SQLite format 3\0" } else { b"\x89MCAP0\r\n" };
    assert!(head.starts_with(magic), "{} is not {storage}", file.display());
    out
}

/// `replay --json` of a bag (a directory, or the storage file inside it).
/// The fixture's cloud is stamped at each ring's first firing, and read so
/// (every point at its stamp: bag_replay.rs checks the rebuilt times).
fn replay(bag: &Path, form: &str) -> Value {
    let map = shared_map("depot.yaml");
    let stamp: &[&str] = if form == "cloud" { &["--ring-stamp", "one-instant"] } else { &[] };
    run_json(&[&["replay", "--json", "--map", s(&map), "--bag", s(bag)][..], stamp].concat())
}

fn flatten(v: &Value, at: String, out: &mut Vec<(String, Value)>) {
    match v {
        Value::Object(m) => m.iter().for_each(|(k, x)| flatten(x, format!("{at}.{k}"), out)),
        _ => out.push((at, v.clone())),
    }
}

/// One form written in both storages replays to the same JSON, every key.
/// (`replay --json` names no input path, so nothing is left out of the
/// comparison; the test checks that no value holds either bag's path.)
fn same_in_both(form: &str, file: bool) -> Value {
    let mcap = write_bag(&format!("{form}-m"), form, "mcap", None);
    let db3 = write_bag(&format!("{form}-s"), form, "sqlite3", None);
    let (a, b) = if file {
        (mcap.join(format!("{form}-m.mcap")), db3.join(format!("{form}-s.db3")))
    } else {
        (mcap.clone(), db3.clone())
    };
    let by_mcap = replay(&a, form);
    let by_db3 = replay(&b, form);
    let mut keys = Vec::new();
    flatten(&by_mcap, String::new(), &mut keys);
    assert!(keys.len() > 40, "{by_mcap}");
    let text = by_db3.to_string();
    assert!(!text.contains(s(&db3)) && !by_mcap.to_string().contains(s(&mcap)), "a path in the JSON: {text}");
    for (k, v) in &keys {
        let got = k.split('.').skip(1).fold(&by_db3, |x, p| &x[p]);
        assert_eq!(got, v, "{form}: {k} differs between the .db3 and the MCAP");
    }
    // Every key, both ways: the whole documents are equal.
    assert_eq!(by_db3, by_mcap, "{form}");
    // And they are a run's figures: readings judged, the EKF tracked.
    assert_eq!(by_db3["bag"]["readings"], 1344, "{by_db3}");
    assert!(by_db3["verdicts"]["confirmed"].as_u64().unwrap() > 100, "{by_db3}");
    by_db3
}

#[test]
fn range_per_transducer_humble_types_db3_as_mcap() {
    let v = same_in_both("range", false);
    let t = &v["bag"]["topics"];
    assert_eq!(t["ring"], "/tf_static");
    assert_eq!(t["odometry"], "/odom");
    assert_eq!(t["reference"], "/ground_truth");
    assert_eq!(t["ranges"].as_array().unwrap().len(), 16);
    assert!(v["ekf"]["position_rmse_m"].as_f64().unwrap() < 0.1, "{v}");
}

#[test]
fn one_range_topic_by_frame_tf_odometry_bare_db3_as_bare_mcap() {
    // The bare storage files, without their metadata.yaml.
    let v = same_in_both("frame", true);
    assert_eq!(v["bag"]["topics"]["odometry"], "/tf (odom -> base_link)");
    assert_eq!(v["bag"]["topics"]["reference"], "/amcl_pose");
}

#[test]
fn rosaria_point_cloud_db3_as_mcap() {
    let v = same_in_both("cloud", false);
    assert_eq!(v["bag"]["topics"]["ranges_type"], "sensor_msgs/msg/PointCloud");
}

/// `log --from-bag` writes the same log and ring from either storage.
#[test]
fn log_from_bag_the_same_from_either_storage() {
    let mcap = write_bag("log-m", "range", "mcap", None);
    let db3 = write_bag("log-s", "range", "sqlite3", None);
    let mut outs = Vec::new();
    for (bag, tag) in [(&mcap, "m"), (&db3, "s")] {
        let out = tmp("bagsq", &format!("log-{tag}.csv"));
        let ring = tmp("bagsq", &format!("log-{tag}-ring.json"));
        let v = run_json(&["log", "--from-bag", s(bag), "-o", s(&out), "--ring-out", s(&ring)]);
        assert_eq!(v["log"]["rows"], 1344, "{v}");
        outs.push((std::fs::read(&out).unwrap(), std::fs::read(&ring).unwrap()));
    }
    assert!(outs[0] == outs[1], "log --from-bag: the .db3's log or ring differs from the MCAP's");
}

/// Runs `replay` on `bag` asking for every output file, and `log --from-bag`:
/// both must fail; returns replay's stderr after checking nothing was written.
fn refused(name: &str, bag: &Path) -> String {
    let map = shared_map("depot.yaml");
    let outs: Vec<PathBuf> = ["png", "mcap", "trace.csv", "readings.csv", "log.csv"]
        .iter()
        .map(|ext| tmp("bagsq", &format!("{name}-out.{ext}")))
        .collect();
    let o: Output = lab()
        .args(["replay", "--json", "--map", s(&map), "--bag", s(bag)])
        .args(["--plot", s(&outs[0]), "--mcap", s(&outs[1]), "--trace", s(&outs[2])])
        .args(["--readings-csv", s(&outs[3])])
        .output()
        .unwrap();
    assert!(!o.status.success(), "{name}: replay succeeded");
    assert!(o.stdout.is_empty(), "{name}: replay printed {}", String::from_utf8_lossy(&o.stdout));
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let l = lab().args(["log", "--from-bag", s(bag), "-o", s(&outs[4])]).output().unwrap();
    assert!(!l.status.success(), "{name}: log --from-bag succeeded");
    // The same refusal from log --from-bag (its first line carries it too).
    let lerr = String::from_utf8_lossy(&l.stderr);
    let first = err.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    let core = first.split_once("error: ").map_or(first, |(_, c)| c);
    assert!(lerr.contains(core.trim()), "{name}: log says {lerr}, replay {err}");
    for p in &outs {
        assert!(!p.exists(), "{name}: {} was written", p.display());
    }
    err
}

/// The refusal lines of a stderr, with the bag's own directory name taken
/// out (the two storages' bags live in directories of different names).
fn refusal(err: &str, dir: &str) -> String {
    err.lines().filter(|l| !l.trim().is_empty()).collect::<Vec<_>>().join("\n").replace(dir, "BAG")
}

/// Every malformed bag of docs/bags.md's table that either storage can
/// carry: the `.db3` is refused with the MCAP's very words.
#[test]
fn the_same_refusals_word_for_word() {
    for (brk, form, message) in [
        ("no-range", "range", "no range topic: no sensor_msgs/msg/Range nor sensor_msgs/msg/PointCloud topic"),
        ("no-transform", "range", "topic /sonar/5: frame \"sonar_5\" has no transform from \"base_link\""),
        ("negative", "range", "topic /sonar/3, message 7 (stamp 4.340426 s): range -0.3 m is negative"),
        ("nan", "range", "topic /sonar/3, message 7 (stamp 4.340426 s): range is NaN"),
        ("mm", "range", "topic /sonar/0, message 0 (stamp 0.000000 s): 5000 m is beyond any sonar (100 m)"),
        ("bad-limits", "range", "topic /sonar/3, message 7 (stamp 4.340426 s): min_range 5 m, max_range 0.45 m"),
        // The message 1 s back is refused where it was recorded: the .db3
        // is read in its rows' order (the recorder's), as MCAP in file order.
        ("backwards", "range", "topic /sonar/3, message 20: header.stamp 11.326042 s is earlier than the message"),
        ("no-odom", "range", "no odometry: no nav_msgs/msg/Odometry topic and no odom -> base_link transform"),
        ("truncated-message", "range", "topic /odom, message 3: not a nav_msgs/msg/Odometry: unexpected end of input"),
        ("cloud-count", "cloud", "topic /sonar, message 0 (stamp 0.000000 s): 8 points, the ring has 16"),
    ] {
        let m = write_bag(&format!("b-{brk}-m"), form, "mcap", Some(brk));
        let d = write_bag(&format!("b-{brk}-s"), form, "sqlite3", Some(brk));
        let by_mcap = refused(&format!("{brk}-m"), &m);
        let by_db3 = refused(&format!("{brk}-s"), &d);
        assert!(by_db3.contains(message), "{brk}: expected {message:?}, got {by_db3}");
        assert_eq!(refusal(&by_db3, s(&d)), refusal(&by_mcap, s(&m)), "{brk}: the storages refuse differently");
    }
}

/// A `.db3` with its `messages` or `topics` table dropped (by python's
/// sqlite3 after `rosbags` wrote it) is refused naming the table.
#[test]
fn a_missing_table() {
    for (brk, table) in [("no-messages-table", "messages"), ("no-topics-table", "topics")] {
        let bag = write_bag(&format!("b-{brk}"), "range", "sqlite3", Some(brk));
        let err = refused(brk, &bag);
        let db3 = bag.join(format!("b-{brk}.db3"));
        let message = format!(
            "{}: unreadable sqlite3 bag: no table \"{table}\" (rosbag2's sqlite3 storage keeps its topics and \
             messages in tables \"topics\" and \"messages\"; tables: ",
            db3.display()
        );
        assert!(err.contains(&message), "{brk}: expected {message:?}, got {err}");
    }
}

/// The third message's blob cut to 10 bytes (the range form's first
/// /ground_truth) is refused with its topic and its index on the topic.
#[test]
fn a_truncated_blob() {
    let bag = write_bag("b-blob", "range", "sqlite3", Some("truncated-blob"));
    let err = refused("truncated-blob", &bag);
    let message = "topic /ground_truth, message 0: not a nav_msgs/msg/Odometry: unexpected end of input";
    assert!(err.contains(message), "expected {message:?}, got {err}");
}

/// A file named `.db3` that is not SQLite, and a `metadata.yaml` naming a
/// storage echoloc does not read.
#[test]
fn files_that_are_not_sqlite_bags() {
    let notes = tmp("bagsq", "notes.db3");
    std::fs::write(&notes, "these are notes, not a recording; long enough for SQLite to read a header of 100 bytes")
        .unwrap();
    let err = refused("notes", &notes);
    assert!(err.contains("notes.db3: unreadable sqlite3 bag: not a SQLite database"), "{err}");
    // A db3 bag cut to half its length.
    let bag = write_bag("b-cut", "range", "sqlite3", None);
    let f = bag.join("b-cut.db3");
    let whole = std::fs::read(&f).unwrap();
    std::fs::write(&f, &whole[..whole.len() / 2]).unwrap();
    let err = refused("cut", &bag);
    assert!(err.contains("b-cut.db3: unreadable sqlite3 bag: a damaged SQLite database"), "{err}");
    // Another storage plugin.
    let dir = tmp("bagsq", "b-other");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  storage_identifier: rosbag_v2\n  relative_file_paths: [x.bag]\n",
    )
    .unwrap();
    let err = refused("other", &dir);
    assert!(
        err.contains("metadata.yaml: storage_identifier \"rosbag_v2\": echoloc reads rosbag2's mcap (the default since Iron) and sqlite3 (Humble's) storages"),
        "{err}"
    );
}
