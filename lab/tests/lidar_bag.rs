//! A lidar run from a ROS 2 bag (`echoloc_lab::lidar::bag`), checked against
//! an independent writer: `scripts/fixture-lidar-bag.py` writes rosbag2 MCAP
//! bags with PyPI's `rosbags` (its own message definitions and CDR
//! serializer) of a laser driven round a square 6 m room, its ranges computed
//! there from the geometry, and beside each the poses ROS's semantics give
//! each scan (interpolated there). Every return must lie on the room's walls;
//! the poses must be the oracle's; malformed bags are refused naming the
//! topic and the message; `map from-scans` maps the walls.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::{lab, root, run_json, s, tmp};
use echoloc_lab::bag::BagError;
use echoloc_lab::lidar::bag::{self, Options, ScanProblem};
use echoloc_lab::lidar::{self, LidarError, LidarRun};

/// The room: walls x = 0, x = ROOM, y = 0, y = ROOM (m), as the writer has it.
const ROOM: f64 = 6.0;
/// The laser on the robot as the writer's /tf_static chain composes it:
/// (0.15, 0.05, 0.1 rad) then (0.08, -0.02, 0.25 rad).
fn mount() -> [f64; 3] {
    let (a, b) = ([0.15, 0.05, 0.1f64], [0.08, -0.02, 0.25]);
    let (s, c) = a[2].sin_cos();
    [a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]]
}

/// Runs the independent writer into a fresh directory; returns the bag and
/// its oracle.
fn write_bag(name: &str, args: &[&str]) -> (PathBuf, PathBuf) {
    let out = tmp("lidar-bag", name);
    let expected = tmp("lidar-bag", &format!("{name}.csv"));
    let o = Command::new("python3")
        .arg(root().join("scripts/fixture-lidar-bag.py"))
        .arg(&out)
        .arg("--expected")
        .arg(&expected)
        .args(args)
        .output()
        .expect("python3 runs");
    assert!(
        o.status.success(),
        "scripts/fixture-lidar-bag.py failed (it needs PyPI's rosbags: `bash scripts/setup.sh` installs it): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    (out, expected)
}

/// One scan as the writer's oracle has it.
#[derive(Debug)]
struct Expected {
    index: u64,
    stamp_ns: i64,
    in_pose: bool,
    straddles: bool,
    returns: usize,
    robot: Option<[f64; 3]>,
    laser: Option<[f64; 3]>,
    odom: Option<[f64; 3]>,
}

fn read_expected(path: &Path) -> Vec<Expected> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let keys: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            let row: BTreeMap<&str, &str> = keys.iter().copied().zip(l.split(',')).collect();
            let pose = |p: &str| -> Option<[f64; 3]> {
                let v: Vec<&str> = ["x", "y", "th"].iter().map(|a| row[format!("{p}_{a}").as_str()]).collect();
                (!v[0].is_empty()).then(|| [v[0].parse().unwrap(), v[1].parse().unwrap(), v[2].parse().unwrap()])
            };
            Expected {
                index: row["index"].parse().unwrap(),
                stamp_ns: row["stamp_ns"].parse().unwrap(),
                in_pose: row["in_pose"] == "1",
                straddles: row["straddles"] == "1",
                returns: row["returns"].parse().unwrap(),
                robot: pose("robot"),
                laser: pose("laser"),
                odom: pose("odom"),
            }
        })
        .collect()
}

/// Distance from `p` to the room's boundary (its four walls), m.
fn off_the_walls(p: (f64, f64)) -> f64 {
    let inside = (-0.001..=ROOM + 0.001).contains(&p.0) && (-0.001..=ROOM + 0.001).contains(&p.1);
    if !inside {
        return f64::INFINITY;
    }
    [p.0.abs(), (p.0 - ROOM).abs(), p.1.abs(), (p.1 - ROOM).abs()].into_iter().fold(f64::INFINITY, f64::min)
}

fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d)
}

fn assert_pose(what: &str, index: u64, got: [f64; 3], want: [f64; 3], tol: f64) {
    let ok = (got[0] - want[0]).abs() < tol && (got[1] - want[1]).abs() < tol && angle_diff(got[2], want[2]) < tol;
    assert!(ok, "scan {index}: {what} {got:?}, the oracle has {want:?}");
}

/// Every return of every scan within 1 mm of a wall, and as many returns
/// as the oracle counts (REP 117 applied to the float32 ranges).
fn assert_on_the_walls(run: &LidarRun, expected: &[Expected]) {
    let by_index: BTreeMap<u64, &Expected> = expected.iter().map(|e| (e.index, e)).collect();
    let mut points = 0;
    for scan in &run.scans {
        let e = by_index[&scan.line];
        assert_eq!(scan.points().count(), e.returns, "scan {}: returns", scan.line);
        for (i, p) in (0..scan.ranges.len()).filter_map(|i| scan.point(i).map(|p| (i, p))) {
            let d = off_the_walls(p);
            assert!(d < 0.001, "scan {} beam {i}: the return {p:?} is {d} m off the room's walls", scan.line);
            points += 1;
        }
    }
    assert!(points > 40_000, "{points} returns");
}

#[test]
fn scans_land_on_the_room_walls() {
    let (bag, expected) = write_bag("stamped", &[]);
    let expected = read_expected(&expected);
    let run = lidar::read(&bag).unwrap();
    assert_eq!(run.format, "ros2 bag LaserScan /scan");
    let inside: Vec<&Expected> = expected.iter().filter(|e| e.in_pose).collect();
    assert_eq!(run.scans.len(), inside.len());
    assert_eq!(
        run.scans.iter().map(|s| s.line).collect::<Vec<_>>(),
        inside.iter().map(|e| e.index).collect::<Vec<_>>()
    );
    assert_on_the_walls(&run, &expected);
    // Beams as the message says: 271 from -135°, every 1°; NaN, ±Inf and
    // below range_min (beams 5..8 of every 10th scan) are no return.
    let s0 = &run.scans[0];
    assert_eq!(s0.ranges.len(), 271);
    assert!((s0.angle_min.to_degrees() + 135.0).abs() < 1e-4 && (s0.angle_step.to_degrees() - 1.0).abs() < 1e-4);
    let tenth = run.scans.iter().find(|s| s.line % 10 == 0).unwrap();
    assert!(tenth.ranges[5..9].iter().all(|r| *r == f32::INFINITY), "{:?}", &tenth.ranges[5..9]);
    // The other topics counted by type; the scans outside the pose's time too
    // (one before the first pose, two after the last).
    let skipped: BTreeMap<&str, usize> = run.skipped.iter().map(|(k, n)| (k.as_str(), *n)).collect();
    assert_eq!(skipped.get("std_msgs/msg/String"), Some(&5), "{skipped:?}");
    assert_eq!(skipped.get("sensor_msgs/msg/LaserScan outside the pose's time"), Some(&3), "{skipped:?}");
    assert_eq!(skipped.len(), 2, "the scan, pose, odometry and /tf_static topics are read: {skipped:?}");
    // The bare .mcap reads the same.
    let bare = lidar::read(&bag.join("stamped.mcap")).unwrap();
    assert_eq!(bare.scans, run.scans);
}

#[test]
fn poses_are_interpolated_to_each_scan() {
    let (bag, expected) = write_bag("interpolated", &[]);
    let expected = read_expected(&expected);
    let b = bag::read(&bag, &Options::default()).unwrap();
    assert_eq!(b.used.pose, "/slam_pose");
    assert_eq!(b.used.odometry.as_deref(), Some("/odom"));
    assert_eq!(b.used.outside_pose, 3);
    let m = mount();
    assert_eq!(b.used.mounts.len(), 1);
    assert_eq!(b.used.mounts[0].0, "laser");
    assert_pose("mount", 0, b.used.mounts[0].1, m, 1e-12);
    let by_index: BTreeMap<u64, &Expected> = expected.iter().map(|e| (e.index, e)).collect();
    let mut between = 0;
    for s in &b.run.scans {
        let e = by_index[&s.line];
        assert!((s.time_s - e.stamp_ns as f64 / 1e9).abs() < 1e-6, "scan {}: stamp {}", s.line, s.time_s);
        assert_pose("robot", s.line, s.robot, e.robot.unwrap(), 1e-9);
        assert_pose("laser", s.line, s.laser, e.laser.unwrap(), 1e-9);
        assert_pose("odometry", s.line, s.odometry.unwrap(), e.odom.unwrap(), 1e-9);
        // Poses every 100 ms: a stamp off them is between two.
        between += usize::from(e.stamp_ns % 100_000_000 != 0);
        if e.straddles {
            // The heading the short way across ±π: near ±π, not near 0.
            assert!(s.robot[2].abs() > 3.0, "scan {}: {:?}", s.line, s.robot);
        }
    }
    // Scans every 1/7 s: six in seven between two poses, the seventh on one.
    assert!(between > 150 && between < b.run.scans.len(), "{between} scans between two pose messages");
    assert!(expected.iter().any(|e| e.in_pose && e.straddles), "the oracle has a scan across ±π");
}

#[test]
fn pose_with_covariance_and_the_tf_chain() {
    for (name, args, pose) in
        [("cov", &["--pose", "cov"][..], "/amcl_pose"), ("tf", &["--pose", "tf"][..], "/tf (map -> odom -> base_link)")]
    {
        let (bag, expected) = write_bag(name, args);
        let expected = read_expected(&expected);
        let b = bag::read(&bag, &Options::default()).unwrap();
        assert_eq!(b.used.pose, pose);
        let by_index: BTreeMap<u64, &Expected> = expected.iter().map(|e| (e.index, e)).collect();
        for s in &b.run.scans {
            let e = by_index[&s.line];
            assert_pose("robot", s.line, s.robot, e.robot.unwrap(), 1e-9);
            assert_pose("laser", s.line, s.laser, e.laser.unwrap(), 1e-9);
            match e.odom {
                Some(o) => assert_pose("odometry", s.line, s.odometry.unwrap(), o, 1e-9),
                None => assert_eq!(s.odometry, None, "{name}: no Odometry topic but the pose's"),
            }
        }
        assert_eq!(b.run.scans.len(), expected.iter().filter(|e| e.in_pose).count(), "{name}");
        assert_on_the_walls(&b.run, &expected);
    }
}

/// The bag's error, through `lidar::read` as the command line reads it.
fn refused(bag: &Path) -> (bag::Error, String) {
    let e = lidar::read(bag).unwrap_err();
    let text = e.to_string();
    match e {
        LidarError::Bag { source, .. } => (*source, text),
        e => panic!("not a bag error: {e}"),
    }
}

#[test]
fn malformed_bags_are_refused_naming_the_topic_and_message() {
    let (bag, _) = write_bag("negative", &["--break", "negative"]);
    let (e, text) = refused(&bag);
    assert!(
        matches!(&e, bag::Error::Scan { topic, index: 7, problem: ScanProblem::NegativeRange { beam: 30, range }, .. }
            if topic == "/scan" && *range == -0.5),
        "{e:?}"
    );
    assert!(text.starts_with(s(&bag)) && text.contains("topic /scan, message 7") && text.contains("beam 30"), "{text}");

    let (bag, _) = write_bag("bad-limits", &["--break", "bad-limits"]);
    let (e, text) = refused(&bag);
    assert!(
        matches!(&e, bag::Error::Scan { index: 5, problem: ScanProblem::BadLimits { min, max }, .. } if *min == 6.0 && *max == 0.1),
        "{e:?}"
    );
    assert!(text.contains("topic /scan, message 5") && text.contains("range_min 6"), "{text}");

    let (bag, _) = write_bag("two-scans", &["--break", "two-scans"]);
    let (e, text) = refused(&bag);
    assert_eq!(
        e,
        bag::Error::Bag(BagError::Ambiguous {
            what: "LaserScan",
            option: "--scans",
            candidates: vec!["/scan".into(), "/scan_rear".into()]
        })
    );
    assert!(text.contains("/scan, /scan_rear") && text.contains("--scans"), "{text}");
    // Named, it reads.
    let b = bag::read(&bag, &Options { scans: Some("/scan".into()), ..Options::default() }).unwrap();
    assert_eq!(b.run.format, "ros2 bag LaserScan /scan");
    assert!(b.run.skipped.contains(&("sensor_msgs/msg/LaserScan".into(), 3)), "{:?}", b.run.skipped);

    let (bag, expected) = write_bag("no-mount", &["--break", "no-mount"]);
    let (e, text) = refused(&bag);
    assert_eq!(
        e,
        bag::Error::NoMount { topic: "/scan".into(), index: 0, frame: "laser".into(), base: "base_link".into() }
    );
    assert!(
        text.contains("topic /scan, message 0") && text.contains("\"laser\"") && text.contains("/tf_static"),
        "{text}"
    );
    // The mount given instead: the returns are on the walls again.
    let b = bag::read(&bag, &Options { laser_mount: Some(mount()), ..Options::default() }).unwrap();
    assert_eq!(b.used.mount_from, "--laser-mount");
    assert_on_the_walls(&b.run, &read_expected(&expected));

    // The command line says so too, naming the bag, and writes nothing.
    let (bag, _) = write_bag("negative-cli", &["--break", "negative"]);
    let out = tmp("lidar-bag", "negative-cli-map.yaml");
    let o = lab().args(["map", "from-scans", s(&bag), "-o", s(&out)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains(s(&bag)) && err.contains("topic /scan, message 7"), "{err}");
    assert!(!out.exists());
}

#[test]
fn map_from_scans_of_a_bag_maps_the_walls() {
    let (bag, _) = write_bag("map", &[]);
    let yaml = tmp("lidar-bag", "room.yaml");
    let v = run_json(&["map", "from-scans", s(&bag), "-o", s(&yaml), "--max-range-m", "5.2"]);
    assert_eq!(v["format"], "ros2 bag LaserScan /scan", "{v}");
    assert_eq!(v["scans"], 210, "{v}");
    // The grid as map_server reads it: the YAML's origin and resolution, the PGM's rows top first.
    let y = std::fs::read_to_string(&yaml).unwrap();
    let field = |k: &str| y.lines().find_map(|l| l.strip_prefix(k)).unwrap().trim().to_string();
    let res: f64 = field("resolution:").parse().unwrap();
    let origin: Vec<f64> =
        field("origin:").trim_matches(['[', ']']).split(',').map(|t| t.trim().parse().unwrap()).collect();
    let pgm = std::fs::read(yaml.with_extension("pgm")).unwrap();
    let text_end = {
        // P5, a comment, width height, 255: four lines of header.
        let mut nl = 0;
        pgm.iter().position(|&b| {
            nl += usize::from(b == b'\n');
            nl == 4
        })
    }
    .unwrap()
        + 1;
    let header = String::from_utf8_lossy(&pgm[..text_end]);
    let dims: Vec<usize> = header.lines().nth(2).unwrap().split(' ').map(|t| t.parse().unwrap()).collect();
    let (w, h) = (dims[0], dims[1]);
    let cells = &pgm[text_end..];
    assert_eq!(cells.len(), w * h);
    let centre = |c: usize, r: usize| (origin[0] + (c as f64 + 0.5) * res, origin[1] + (r as f64 + 0.5) * res);
    let occupied = |c: usize, r: usize| cells[(h - 1 - r) * w + c] == 0;
    // Every occupied cell holds a wall: its centre within half a cell (and
    // the 1 mm the returns may be off) of one.
    let mut n = 0;
    for r in 0..h {
        for c in 0..w {
            if occupied(c, r) {
                let p = centre(c, r);
                let d = [p.0.abs(), (p.0 - ROOM).abs(), p.1.abs(), (p.1 - ROOM).abs()]
                    .into_iter()
                    .fold(f64::INFINITY, f64::min);
                let inside = p.0 > -res && p.0 < ROOM + res && p.1 > -res && p.1 < ROOM + res;
                assert!(inside && d <= res / 2.0 + 0.001, "occupied cell ({c}, {r}) at {p:?}: {d} m from the walls");
                n += 1;
            }
        }
    }
    // And the walls are mapped: along each, away from the corners, nearly every
    // cell the wall runs through is occupied.
    let cell_of =
        |p: (f64, f64)| (((p.0 - origin[0]) / res).floor() as usize, ((p.1 - origin[1]) / res).floor() as usize);
    let (mut seen, mut total) = (0, 0);
    for k in 0..=((ROOM - 1.0) / res) as usize {
        let a = 0.5 + k as f64 * res;
        for p in [(0.0, a), (ROOM, a), (a, 0.0), (a, ROOM)] {
            // A wall on a cell boundary may be drawn in the cell on either side.
            let near = [(0.0, 0.0), (-0.001, -0.001), (0.001, 0.001)].iter().any(|d| {
                let (c, r) = cell_of((p.0 + d.0, p.1 + d.1));
                c < w && r < h && occupied(c, r)
            });
            seen += usize::from(near);
            total += 1;
        }
    }
    assert!(seen * 100 >= total * 95, "{seen} of {total} wall cells occupied");
    assert!(n >= total, "{n} occupied cells");
}
