//! ROS 2 bags in (#28 item 1), checked against an independent writer:
//! `scripts/fixture-bag.py` writes rosbag2 MCAP bags of a simulated depot run
//! with PyPI's `rosbags` (its own message definitions and CDR serializer) and,
//! beside each, the plain log that ROS's documented semantics make of it
//! (REP 117's range limits, RosAria's 5 m no-echo point). Replaying the bag
//! must give the very figures of replaying that log, every JSON key; every
//! malformed bag of docs/bags.md's table is refused with its message, and
//! nothing is written.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use common::{lab, root, run_json, s, shared_map, tmp};
use serde_json::Value;

/// A simulated depot run's log (true pose as reference), made once.
fn run_log() -> &'static PathBuf {
    static LOG: OnceLock<PathBuf> = OnceLock::new();
    LOG.get_or_init(|| {
        let log = tmp("bag", "depot-run.csv");
        let map = shared_map("depot.yaml");
        run_json(&["simulate", "--json", "--map", s(&map), "--seed", "3", "--distance-m", "20", "--log", s(&log)]);
        log
    })
}

/// Runs the independent writer; `brk` makes a malformed bag.
fn write_bag(name: &str, form: &str, brk: Option<&str>) -> (PathBuf, PathBuf) {
    write_bag_with(name, form, brk, &[])
}

/// [`write_bag`] with more of the writer's options.
fn write_bag_with(name: &str, form: &str, brk: Option<&str>, extra: &[&str]) -> (PathBuf, PathBuf) {
    let out = tmp("bag", name);
    let expected = tmp("bag", &format!("{name}.csv"));
    let mut c = Command::new("python3");
    c.arg(root().join("scripts/fixture-bag.py")).arg(run_log()).arg(&out).args(["--form", form]);
    c.arg("--expected").arg(&expected);
    if let Some(b) = brk {
        c.args(["--break", b]);
    }
    c.args(extra);
    let o = c.output().expect("python3 runs");
    assert!(
        o.status.success(),
        "scripts/fixture-bag.py failed (it needs PyPI's rosbags: `bash scripts/setup.sh` installs it): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    (out, expected)
}

fn flatten(v: &Value, at: String, out: &mut Vec<(String, Value)>) {
    match v {
        Value::Object(m) => m.iter().for_each(|(k, x)| flatten(x, format!("{at}.{k}"), out)),
        _ => out.push((at, v.clone())),
    }
}

/// The bag replays to the figures of the oracle's log, every key.
fn same_as_oracle(form: &str, bag_arg: impl Fn(&Path) -> PathBuf, rmse_m: f64) -> Value {
    same_as_oracle_with(form, form, &[], bag_arg, rmse_m)
}

fn same_as_oracle_with(
    name: &str,
    form: &str,
    extra: &[&str],
    bag_arg: impl Fn(&Path) -> PathBuf,
    rmse_m: f64,
) -> Value {
    let (bag, expected) = write_bag_with(name, form, None, extra);
    let map = shared_map("depot.yaml");
    let mut args = vec!["replay", "--json", "--map", s(&map)];
    // The oracle's cloud log has every point at the stamp: read it so (the
    // firing times rebuilt are checked against the run's own below).
    if form == "cloud" {
        args.extend(["--ring-stamp", "one-instant"]);
    }
    let bag_path = bag_arg(&bag);
    args.extend(["--bag", s(&bag_path)]);
    let by_bag = run_json(&args);
    let by_log = run_json(&["replay", "--json", "--map", s(&map), "--log", s(&expected)]);
    let mut keys = Vec::new();
    flatten(&by_log, String::new(), &mut keys);
    assert!(keys.len() > 40, "{by_log}");
    for (k, v) in &keys {
        let got = k.split('.').skip(1).fold(&by_bag, |x, p| &x[p]);
        assert_eq!(got, v, "{form}: {k} differs between the bag and the oracle's log");
    }
    // The figures are a run's: the EKF tracked, readings were judged.
    assert!(by_bag["ekf"]["position_rmse_m"].as_f64().unwrap() < rmse_m, "{by_bag}");
    assert!(by_bag["verdicts"]["confirmed"].as_u64().unwrap() > 100, "{by_bag}");
    by_bag
}

#[test]
fn range_per_transducer_with_tf_static_odometry_and_ground_truth() {
    let v = same_as_oracle("range", Path::to_path_buf, 0.1);
    let t = &v["bag"]["topics"];
    assert_eq!(t["odometry"], "/odom");
    assert_eq!(t["reference"], "/ground_truth");
    assert_eq!(t["ring"], "/tf_static");
    assert_eq!(t["ranges"].as_array().unwrap().len(), 16);
    // The mounts followed base_link -> sonar_ring -> sonar_N back to the Pioneer ring.
    let tr = &v["bag"]["transducers"];
    assert_eq!(tr[0]["frame"], "sonar_0");
    assert_eq!(tr[10]["frame"], "sonar_10", "frames in number order, not name order");
    assert_eq!(tr[10]["mount"], serde_json::json!([-0.23, -0.08, -150.0]));
    // REP 117: ranges beyond max_range (5 m) and below min_range (0.45 m) were no echo.
    assert!(v["bag"]["no_echo"]["beyond_max_range"].as_u64().unwrap() > 0, "{v}");
    assert!(v["bag"]["no_echo"]["below_min_range"].as_u64().unwrap() > 0, "{v}");
}

#[test]
fn one_range_topic_by_frame_tf_odometry_amcl_reference_bare_mcap() {
    // The bare .mcap inside the directory, without its metadata.yaml.
    let v = same_as_oracle("frame", |dir| dir.join("frame.mcap"), 0.1);
    let t = &v["bag"]["topics"];
    assert_eq!(t["ranges"], serde_json::json!(["/sonar_ranges"]));
    assert_eq!(t["odometry"], "/tf (odom -> base_link)");
    assert_eq!(t["reference"], "/amcl_pose");
}

#[test]
fn rosaria_point_cloud() {
    // The whole ring at its cycle's first firing, as RosAria stamps it: the
    // robot moves up to 0.6 s within a cycle, so the EKF tracks less well.
    let v = same_as_oracle("cloud", Path::to_path_buf, 0.2);
    assert_eq!(v["bag"]["topics"]["ranges_type"], "sensor_msgs/msg/PointCloud");
    assert!(v["bag"]["no_echo"]["beyond_max_range"].as_u64().unwrap() > 0, "the 5 m points are no echo: {v}");
}

/// RosAria's whole-ring stamp (#37 item 4): the cloud's firing times are
/// rebuilt from the ring's order and period, stamped at the ring's start or
/// its end. The order, slot and period are read off the run's own log (the
/// transducers of its first cycle in firing order; the median spacings),
/// not from the simulator; the rebuilt times lie within 16 ms of the true
/// ones (the simulator's EERUF alternates slots of 37.4 and 38.4 ms, which
/// one slot length misses by 1 ms a slot: 15 ms at the last), and
/// the run tracks within 1.5 times the Range form's RMSE plus 1 cm.
#[test]
fn rosaria_cloud_firing_times_rebuilt_from_the_rings_order_and_period() {
    let truth = echoloc_lab::log::read(&std::fs::read_to_string(run_log()).unwrap(), 16).unwrap();
    // Cycles: a cycle ends before a transducer fires again.
    let mut cycles: Vec<Vec<&echoloc_lab::log::Row>> = vec![vec![]];
    for r in &truth.rows {
        if cycles.last().unwrap().iter().any(|c| c.transducer == r.transducer) {
            cycles.push(vec![]);
        }
        cycles.last_mut().unwrap().push(r);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let order: Vec<u8> = cycles[0].iter().map(|r| r.transducer).collect();
    assert_eq!(order.len(), 16);
    let period = median(cycles.windows(2).map(|w| w[1][0].time_s - w[0][0].time_s).collect());
    let slot = median(cycles.iter().flat_map(|c| c.windows(2).map(|w| w[1].time_s - w[0].time_s)).collect());
    let ring = tmp("bag", "timed-ring.json");
    let mounts: Vec<[f64; 3]> = echoloc::predict::PIONEER16
        .iter()
        .map(|m| [f64::from(m.x_mm) / 1e3, f64::from(m.y_mm) / 1e3, f64::from(m.heading_mdeg) / 1e3])
        .collect();
    let file = serde_json::json!({"transducers": mounts, "order": order, "period_s": period, "slot_s": slot});
    std::fs::write(&ring, file.to_string()).unwrap();

    let map = shared_map("depot.yaml");
    let range = run_json(&["replay", "--json", "--map", s(&map), "--log", s(run_log())]);
    let range_rmse = range["ekf"]["position_rmse_m"].as_f64().unwrap();
    for stamp in ["start", "end"] {
        let (bag, _) = write_bag_with(&format!("cloud-{stamp}"), "cloud", None, &["--cloud-stamp", stamp]);
        let out = tmp("bag", &format!("cloud-{stamp}.csv"));
        let args = ["--ring", s(&ring), "--ring-stamp", stamp];
        run_json(&[&["log", "--from-bag", s(&bag), "-o", s(&out)][..], &args].concat());
        let ours = echoloc_lab::log::read(&std::fs::read_to_string(&out).unwrap(), 16).unwrap();
        // Every reading of a whole cycle, at its own firing time.
        let whole: usize = cycles.iter().filter(|c| c.len() == 16).map(Vec::len).sum();
        assert!(ours.rows.len() + 16 >= whole, "{stamp}: {} rows of {whole}", ours.rows.len());
        let mut worst: f64 = 0.0;
        for r in &ours.rows {
            let t = truth
                .rows
                .iter()
                .filter(|q| q.transducer == r.transducer)
                .map(|q| (q.time_s - r.time_s).abs())
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(t);
        }
        assert!(worst <= 0.016, "{stamp}: a rebuilt firing time {worst} s from the true one");
        let v = run_json(&[&["replay", "--json", "--map", s(&map), "--bag", s(&bag)][..], &args].concat());
        let rmse = v["ekf"]["position_rmse_m"].as_f64().unwrap();
        assert!(rmse <= 1.5 * range_rmse + 0.01, "{stamp}: cloud {rmse} m against the Range form's {range_rmse} m");
        assert!(v["bag"]["topics"]["cloud_timing"].as_str().unwrap().contains(&format!("ring's {stamp}")), "{v}");
    }
}

/// `log --from-bag` writes the oracle's log (same rows), and its ring; the
/// log converts for the board.
#[test]
fn log_from_bag_writes_the_oracles_log_and_converts_for_the_board() {
    let (bag, expected) = write_bag("logbag", "range", None);
    let out = tmp("bag", "from-bag.csv");
    let ring = tmp("bag", "from-bag-ring.json");
    let v = run_json(&["log", "--from-bag", s(&bag), "-o", s(&out), "--ring-out", s(&ring)]);
    assert_eq!(v["log"]["rows"], 1344, "{v}");
    let mounts = echoloc_lab::ring::load(s(&ring)).unwrap();
    assert_eq!(mounts, echoloc::predict::PIONEER16.to_vec());
    let ours = echoloc_lab::log::read(&std::fs::read_to_string(&out).unwrap(), 16).unwrap();
    let oracle = echoloc_lab::log::read(&std::fs::read_to_string(&expected).unwrap(), 16).unwrap();
    assert_eq!(ours.rows.len(), oracle.rows.len());
    // Times, transducers, ranges and positions exactly; headings through a
    // quaternion and back (sin/cos, then atan2) within 1e-12 rad.
    let close = |p: [f64; 3], q: [f64; 3]| p[0] == q[0] && p[1] == q[1] && (p[2] - q[2]).abs() < 1e-12;
    for (a, b) in ours.rows.iter().zip(&oracle.rows) {
        assert_eq!((a.time_s, a.transducer, a.range_mm), (b.time_s, b.transducer, b.range_mm));
        assert!(close(a.odometry, b.odometry) && close(a.reference.unwrap(), b.reference.unwrap()), "{a:?} {b:?}");
    }
    let scn = tmp("bag", "from-bag.scn");
    let map = root().join("boards/qemu-mps2-an386/depot.map");
    run_json(&["scenario", "--from-log", s(&out), "--map", s(&map), "--ring", s(&ring), "-o", s(&scn)]);
    assert!(std::fs::metadata(&scn).unwrap().len() > 1000);
}

/// A malformed bag: refused by replay and log with `message`; nothing written.
fn refused(name: &str, form: &str, brk: &str, message: &str) {
    let (bag, _) = write_bag(name, form, Some(brk));
    let map = shared_map("depot.yaml");
    let plot = tmp("bag", &format!("{name}.png"));
    let o = lab().args(["replay", "--map", s(&map), "--bag", s(&bag), "--plot", s(&plot)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains(message), "{brk}: expected {message:?}, got {err}");
    assert!(!plot.exists(), "{brk}: a plot was written");
    let out = tmp("bag", &format!("{name}.csv.out"));
    let o = lab().args(["log", "--from-bag", s(&bag), "-o", s(&out)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains(message), "{brk}: log: expected {message:?}, got {err}");
    assert!(!out.exists(), "{brk}: a log was written");
}

#[test]
fn no_range_topic() {
    refused("b-norange", "range", "no-range", "no range topic: no sensor_msgs/msg/Range nor sensor_msgs/msg/PointCloud topic in the bag (topics: /ground_truth (nav_msgs/msg/Odometry), /odom");
}

#[test]
fn a_frame_without_a_transform() {
    refused(
        "b-notf",
        "range",
        "no-transform",
        "topic /sonar/5: frame \"sonar_5\" has no transform from \"base_link\" in /tf_static",
    );
}

#[test]
fn negative_range() {
    refused("b-neg", "range", "negative", "topic /sonar/3, message 7 (stamp 4.340426 s): range -0.3 m is negative");
}

#[test]
fn nan_range() {
    refused("b-nan", "range", "nan", "topic /sonar/3, message 7 (stamp 4.340426 s): range is NaN");
}

#[test]
fn ranges_in_millimetres() {
    refused("b-mm", "range", "mm", "topic /sonar/0, message 0 (stamp 0.000000 s): 5000 m is beyond any sonar (100 m): the unit is not metres (millimetres?)");
}

#[test]
fn limits_no_sonar_has() {
    refused(
        "b-limits",
        "range",
        "bad-limits",
        "topic /sonar/3, message 7 (stamp 4.340426 s): min_range 5 m, max_range 0.45 m",
    );
}

#[test]
fn time_going_backwards() {
    refused("b-back", "range", "backwards", "topic /sonar/3, message 20: header.stamp 11.326042 s is earlier than the message before it (11.713610 s): time goes backwards");
}

#[test]
fn no_odometry() {
    refused(
        "b-noodom",
        "range",
        "no-odom",
        "no odometry: no nav_msgs/msg/Odometry topic and no odom -> base_link transform in /tf",
    );
}

#[test]
fn a_truncated_message() {
    refused(
        "b-trunc",
        "range",
        "truncated-message",
        "topic /odom, message 3: not a nav_msgs/msg/Odometry: unexpected end of input",
    );
}

#[test]
fn an_unreadable_chunk() {
    refused(
        "b-chunk",
        "range",
        "chunk",
        "b-chunk.mcap: unreadable MCAP: chunk at byte 1071520: the record at byte 1071569 runs past the chunk's end",
    );
}

#[test]
fn a_truncated_file() {
    refused(
        "b-cut",
        "range",
        "truncated-file",
        "b-cut.mcap: unreadable MCAP: the chunk record at byte 1071520 claims 1048649 bytes, past the file's end (a truncated file?)",
    );
}

#[test]
fn a_cloud_with_another_point_count() {
    refused(
        "b-cc",
        "cloud",
        "cloud-count",
        "topic /sonar, message 0 (stamp 0.000000 s): 8 points, the ring has 16 transducers",
    );
}

/// Named topics that are not there, or not of the type, are refused by name.
#[test]
fn named_topics_are_checked() {
    let (bag, _) = write_bag("named", "range", None);
    let map = shared_map("depot.yaml");
    for (args, message) in [
        (vec!["--odom", "/wheel_odom"], "--odom /wheel_odom: the bag has no such topic (topics: /ground_truth"),
        (
            vec!["--odom", "/sonar/1"],
            "--odom /sonar/1: its type is sensor_msgs/msg/Range, expected nav_msgs/msg/Odometry",
        ),
        (vec!["--reference", "/tf_static"], "--reference /tf_static: its type is tf2_msgs/msg/TFMessage"),
    ] {
        let mut a = vec!["replay", "--map", s(&map), "--bag", s(&bag)];
        a.extend(args);
        let o = lab().args(&a).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(message), "expected {message:?}, got {err}");
    }
    // The ground truth named as the odometry: a run on perfect odometry.
    let v = run_json(&[
        "replay",
        "--json",
        "--map",
        s(&map),
        "--bag",
        s(&bag),
        "--odom",
        "/ground_truth",
        "--reference",
        "/ground_truth",
        "--ranges",
        "/sonar/0,/sonar/3",
    ]);
    assert_eq!(v["bag"]["topics"]["odometry"], "/ground_truth");
    assert_eq!(v["bag"]["transducers"].as_array().unwrap().len(), 2);
    assert!(v["dead_reckoning"]["max_position_error_m"].as_f64().unwrap() < 1e-3, "{v}");
}

/// Paths that are not bags are named, with what is wrong.
#[test]
fn paths_that_are_not_bags() {
    let map = shared_map("depot.yaml");
    let dir = tmp("bag", "not-a-bag-dir");
    std::fs::create_dir_all(&dir).unwrap();
    let text = tmp("bag", "notes.mcap");
    std::fs::write(&text, "these are notes, not a recording").unwrap();
    for (bag, message) in [
        (tmp("bag", "missing"), "missing: no such file or directory".to_string()),
        (dir.clone(), format!("{}: No such file or directory", dir.join("metadata.yaml").display())),
        (text.clone(), "notes.mcap: unreadable MCAP: not an MCAP file (no magic bytes)".to_string()),
    ] {
        let o = lab().args(["replay", "--map", s(&map), "--bag", s(&bag)]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(&message), "expected {message:?}, got {err}");
    }
    // --log and --bag together, or neither, are refused by the command line.
    let o = lab().args(["replay", "--map", s(&map), "--bag", s(&text), "--log", s(&text)]).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot be used with"));
    let o = lab().args(["replay", "--map", s(&map)]).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("--log <LOG>"));
}

/// Chunks compressed as rosbag2's storage presets write them (zstd) and with
/// lz4, with chunk CRCs, by PyPI's mcap writer: the same figures.
#[test]
fn compressed_chunks_zstd_and_lz4() {
    same_as_oracle_with("zstd", "range", &["--chunks", "zstd"], Path::to_path_buf, 0.1);
    same_as_oracle_with("lz4", "cloud", &["--chunks", "lz4"], Path::to_path_buf, 0.2);
}

#[test]
fn a_damaged_compressed_chunk() {
    let (bag, _) = write_bag_with("b-crc", "range", Some("chunk-crc"), &["--chunks", "zstd"]);
    let map = shared_map("depot.yaml");
    let o = lab().args(["replay", "--map", s(&map), "--bag", s(&bag)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("b-crc.mcap: unreadable MCAP: Error during decompression"), "{err}");
}

/// `replay --ros2` (#50): a bag of an 80 m depot run replayed from no pose
/// and published beside an independent ROS 2 node (Cyclone DDS, Python, in
/// `unshare -n`): it receives one `/particlecloud` (as many poses in `map`
/// as the trace says the cycle weighed) per cycle the run's trace (`--trace`) says ended with particles, stamped
/// at those cycles' times (searching or lost), none while tracking, and one `/amcl_pose` per
/// reading the replay's JSON counts.
#[test]
fn replay_ros2_publishes_the_particles_while_searching() {
    let log = tmp("bag", "depot-80m.csv");
    run_json(&[
        "simulate",
        "--json",
        "--map",
        s(&shared_map("depot.yaml")),
        "--seed",
        "3",
        "--distance-m",
        "80",
        "--log",
        s(&log),
    ]);
    let bag = tmp("bag", "depot-80m");
    let o = Command::new("python3").arg(root().join("scripts/fixture-bag.py")).arg(&log).arg(&bag).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let trace = tmp("bag", "depot-80m-trace.csv");
    let args: Vec<String> = ["replay", "--json", "--map", s(&shared_map("depot.yaml")), "--bag", s(&bag)]
        .into_iter()
        .chain(["--initial-pose", "unknown", "--speed", "60", "--trace", s(&trace)])
        .map(String::from)
        .collect();
    let (o, peers) = common::beside_ros2_peers(&args, &[&[]]);
    let report: Value = serde_json::from_slice(&o.stdout).unwrap();
    let csv = std::fs::read_to_string(&trace).unwrap();
    let mut lines = csv.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (mode, particles, time) = (col("mode"), col("particles"), col("time_s"));
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(String::from).collect()).collect();
    let with_particles: Vec<&Vec<String>> = rows.iter().filter(|r| r[particles] != "0").collect();
    assert!(rows.iter().any(|r| r[mode] == "tracking"), "the run found itself: not only searching");
    // The particles are awake while searching and while lost (the cycle the
    // EKF's monitor fires wakes them around its estimate, DESIGN §4.8).
    assert!(with_particles.iter().all(|r| r[mode] == "searching" || r[mode] == "lost"));
    assert!(with_particles.iter().any(|r| r[mode] == "searching"));
    let clouds = peers[0]["particle_clouds"].as_array().unwrap();
    assert_eq!(clouds.len(), with_particles.len(), "one cloud per cycle that ended with particles");
    assert!(clouds.iter().all(|c| c["frame"] == "map"));
    // Stamped at their cycles' times: the steps between clouds are the trace's.
    let t0: f64 = with_particles[0][time].parse().unwrap();
    let s0 = clouds[0]["stamp_ns"].as_i64().unwrap();
    for (c, r) in clouds.iter().zip(&with_particles) {
        let dt = (c["stamp_ns"].as_i64().unwrap() - s0) as f64 * 1e-9;
        let want = r[time].parse::<f64>().unwrap() - t0;
        assert!((dt - want).abs() < 1e-6, "{dt} s against {want} s");
        assert_eq!(c["particles"].to_string(), r[particles], "the cloud holds the cycle's particles");
    }
    let poses = peers[0]["poses"].as_array().unwrap().len() as u64;
    assert_eq!(poses, report["ros2"]["poses"].as_u64().unwrap());
    assert_eq!(poses, report["readings"].as_u64().unwrap());
}
