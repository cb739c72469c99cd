//! A lidar run from a ROS 2 bag (rosbag2's MCAP storage, a bag directory or
//! a bare `.mcap`): the scans of one `sensor_msgs/msg/LaserScan` topic at
//! the robot's poses (`docs/lidar-bags.md`). The bag is opened and decoded
//! by the sonar's reader ([`crate::bag::source`], [`crate::bag::msgs`]);
//! only the choice of topics and the scans' meaning are here.
//!
//! | what | from (found by type when not named) |
//! |---|---|
//! | scans | the `LaserScan` topic (`--scans` when there are several) |
//! | the robot's pose in the map | a `geometry_msgs/msg/PoseStamped` or `PoseWithCovarianceStamped` topic, else an `nav_msgs/msg/Odometry` topic, else `/tf` `map` → `base_link` (or `map` → `odom` → `base_link`); `--pose` |
//! | the laser on the robot | `/tf_static` `base_link` → the scan's `header.frame_id`, chains followed; or `--laser-mount` |
//! | odometry (optional) | an `Odometry` topic other than the pose's (`--odom`) |
//!
//! Each scan is taken at its `header.stamp`, the poses interpolated to it
//! (linearly, the heading the short way); scans outside the pose's time are
//! left out and counted. Ranges follow REP 117: `±Inf`, NaN and values
//! outside `[range_min, range_max]` are no return; a negative range, or
//! limits no laser has, refuse the bag naming the topic and the message.
//!
//! ```no_run
//! use echoloc_lab::lidar::bag::{read, Options};
//! let bag = read("run/".as_ref(), &Options { scans: Some("/scan".into()), ..Options::default() })?;
//! println!("{} scans, pose from {}", bag.run.scans.len(), bag.used.pose);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::Path;

use clap::Args;

use super::{LidarRun, Scan};
use crate::bag::msgs::{self, types};
use crate::bag::source::{self, Messages};
use crate::bag::{
    chain, compose, decoded, leaf, named, of_type, pose_track, says_truth, static_transforms, stored, strip, tf_track,
    topics_of, wrap, BagError, Pose2, Track,
};

/// The message types a lidar run is read from (the other topics are only counted).
pub const LIDAR_TYPES: &[&str] = &[types::LASER_SCAN, types::POSE_STAMPED, types::POSE_COV, types::ODOMETRY, types::TF];

/// `--pose` naming this takes the pose from `/tf` even when pose topics exist.
pub const POSE_FROM_TF: &str = "/tf";

/// Most beams in one scan (a 0.1° laser over 360° has 3 600; more is not a
/// planar laser's scan but a cloud flattened into one).
pub const MAX_BEAMS: usize = 65_536;

/// What to read from the bag; `None`s are found by type.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The `LaserScan` topic; `None`: the only one.
    pub scans: Option<String>,
    /// The pose topic (`PoseStamped`, `PoseWithCovarianceStamped` or
    /// `Odometry`), or [`POSE_FROM_TF`]; `None`: found by type.
    pub pose: Option<String>,
    /// The odometry topic (`Odometry`); `None`: the one other than the
    /// pose's that is not a ground truth (`odom` if several), else none.
    pub odom: Option<String>,
    /// The map's frame (for `/tf`).
    pub map_frame: String,
    /// The odometry's frame (for `/tf`).
    pub odom_frame: String,
    /// The robot's frame: the pose's, and the laser mount's parent.
    pub base_frame: String,
    /// The laser's pose on the robot (x m, y m, yaw rad) instead of `/tf_static`'s.
    pub laser_mount: Option<[f64; 3]>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            scans: None,
            pose: None,
            odom: None,
            map_frame: "map".into(),
            odom_frame: "odom".into(),
            base_frame: "base_link".into(),
            laser_mount: None,
        }
    }
}

/// The command line's options for a lidar bag (to flatten into a command
/// that reads one; the error messages name these flags).
#[derive(Args, Clone, Debug)]
pub struct LaserBagArgs {
    /// The sensor_msgs/msg/LaserScan topic; default: the only one.
    #[arg(long)]
    pub scans: Option<String>,
    /// The robot's pose in the map: a PoseStamped, PoseWithCovarianceStamped
    /// or Odometry topic, or /tf; default: a pose topic, else an Odometry
    /// topic, else /tf map -> base_link.
    #[arg(long)]
    pub pose: Option<String>,
    /// The odometry topic (nav_msgs/msg/Odometry), kept with each scan;
    /// default: the Odometry topic other than the pose's, if any.
    #[arg(long)]
    pub odom: Option<String>,
    /// The map's frame, for a pose from /tf.
    #[arg(long = "map-frame", default_value = "map")]
    pub map_frame: String,
    /// The odometry's frame, for a pose from /tf.
    #[arg(long = "odom-frame", default_value = "odom")]
    pub odom_frame: String,
    /// The robot's frame: the pose's, and the laser mount's parent in /tf_static.
    #[arg(long = "base-frame", default_value = "base_link")]
    pub base_frame: String,
    /// The laser on the robot, X,Y,YAW (m, m, rad), instead of /tf_static's.
    #[arg(long = "laser-mount", value_parser = parse_mount, allow_hyphen_values = true)]
    pub laser_mount: Option<[f64; 3]>,
}

impl LaserBagArgs {
    /// The reader's options.
    pub fn options(&self) -> Options {
        Options {
            scans: self.scans.clone(),
            pose: self.pose.clone(),
            odom: self.odom.clone(),
            map_frame: self.map_frame.clone(),
            odom_frame: self.odom_frame.clone(),
            base_frame: self.base_frame.clone(),
            laser_mount: self.laser_mount,
        }
    }
}

/// `X,Y,YAW`: a laser mount, m, m, rad.
pub fn parse_mount(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{s:?}: expected X,Y,YAW (m, m, rad), e.g. 0.2,0,0"))?;
    match v[..] {
        [x, y, yaw] if v.iter().all(|a| a.is_finite()) && yaw.abs() <= 2.0 * std::f64::consts::PI => Ok([x, y, yaw]),
        [_, _, _] => Err(format!("{s:?}: X,Y,YAW must be finite, YAW in radians (|YAW| ≤ 2π)")),
        _ => Err(format!("{s:?}: expected three numbers X,Y,YAW (m, m, rad)")),
    }
}

/// What the run was read from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Used {
    /// The LaserScan topic.
    pub scans: String,
    /// The pose: a topic, or `/tf (map -> odom -> base_link)`.
    pub pose: String,
    /// The odometry topic, if any.
    pub odometry: Option<String>,
    /// Where the laser's mount came from: `/tf_static`, or `--laser-mount`.
    pub mount_from: String,
    /// Each laser frame's mount on the robot (x m, y m, yaw rad).
    pub mounts: Vec<(String, [f64; 3])>,
    /// Scans left out because the pose does not cover their stamp.
    pub outside_pose: usize,
    /// Beams with no return (REP 117's `±Inf`, NaN, out of the limits; 0).
    pub no_return: usize,
}

/// A lidar run read from a bag, and what it was read from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BagRun {
    /// The run.
    pub run: LidarRun,
    /// The topics and frames used.
    pub used: Used,
}

/// What is wrong with one LaserScan.
#[derive(Clone, Debug, PartialEq)]
pub enum ScanProblem {
    /// A negative finite range (REP 117 has none: `-Inf` is "too close").
    NegativeRange { beam: usize, range: f32 },
    /// `range_min`/`range_max` no laser has (not finite, negative, not increasing).
    BadLimits { min: f32, max: f32 },
    /// Angles that are not a laser's in radians.
    BadAngles { min: f32, increment: f32, beams: usize },
    /// More beams than [`MAX_BEAMS`].
    TooManyBeams(usize),
    /// A stamp with `nanosec` ≥ 10⁹.
    BadStamp,
    /// `header.frame_id` is empty: where is the laser?
    NoFrame,
}

impl fmt::Display for ScanProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NegativeRange { beam, range } => write!(
                f,
                "beam {beam}: range {range} m is negative: no range can be (REP 117: +Inf is no return, -Inf too close)"
            ),
            Self::BadLimits { min, max } => write!(
                f,
                "range_min {min} m, range_max {max} m: limits must be finite, range_min ≥ 0 and below range_max"
            ),
            Self::BadAngles { min, increment, beams } => write!(
                f,
                "angle_min {min}, angle_increment {increment}, {beams} beams: not a laser's angles in radians \
                 (the increment must be finite and not 0, the sweep at most a turn)"
            ),
            Self::TooManyBeams(n) => write!(f, "{n} ranges: more than a planar laser's {MAX_BEAMS}"),
            Self::BadStamp => write!(f, "header.stamp has nanosec ≥ 10⁹"),
            Self::NoFrame => write!(f, "header.frame_id is empty: where on the robot is the laser?"),
        }
    }
}

/// Why a bag was not read as a lidar run.
#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// What the shared bag reader refuses: the files, a message that does
    /// not decode, a bad pose message, time going backwards, several
    /// candidate topics, a named topic the bag lacks or of another type.
    Bag(BagError),
    /// No LaserScan topic.
    NoLaserScan { topics: Vec<(String, String)> },
    /// No pose topic and no map → base transform in `/tf`.
    NoPose { topics: Vec<(String, String)>, map_frame: String, odom_frame: String, base_frame: String },
    /// The laser's frame has no transform from the robot's in `/tf_static`.
    NoMount { topic: String, index: usize, frame: String, base: String },
    /// A LaserScan that decodes but says something impossible.
    Scan { topic: String, index: usize, stamp_s: Option<f64>, problem: ScanProblem },
    /// No scan within the pose's time.
    NoScans { topic: String, messages: usize, outside_pose: usize, pose: String },
}

impl Error {
    /// Whether the message names the file already (the bag's own I/O and format errors).
    pub fn names_file(&self) -> bool {
        matches!(
            self,
            Error::Bag(
                BagError::Io { .. } | BagError::Metadata { .. } | BagError::Unreadable { .. } | BagError::Sqlite { .. }
            )
        )
    }
}

fn list(topics: &[(String, String)]) -> String {
    if topics.is_empty() {
        return "none".into();
    }
    topics.iter().map(|(n, t)| format!("{n} ({t})")).collect::<Vec<_>>().join(", ")
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Bag(e) => e.fmt(f),
            Self::NoLaserScan { topics } => {
                write!(f, "no {} topic in the bag (topics: {})", types::LASER_SCAN, list(topics))
            }
            Self::NoPose { topics, map_frame, odom_frame, base_frame } => write!(
                f,
                "no pose for the scans: no {}, {} or {} topic, and neither {map_frame} -> {base_frame} nor \
                 {map_frame} -> {odom_frame} -> {base_frame} in /tf (topics: {}; --pose, --map-frame, --odom-frame, \
                 --base-frame)",
                types::POSE_STAMPED,
                types::POSE_COV,
                types::ODOMETRY,
                list(topics)
            ),
            Self::NoMount { topic, index, frame, base } => write!(
                f,
                "topic {topic}, message {index}: the laser's frame {frame:?} has no transform from {base:?} in \
                 /tf_static (publish it, or give the mount with --laser-mount X,Y,YAW)"
            ),
            Self::Scan { topic, index, stamp_s, problem } => {
                write!(f, "topic {topic}, message {index}")?;
                if let Some(t) = stamp_s {
                    write!(f, " (stamp {t:.6} s)")?;
                }
                write!(f, ": {problem}")
            }
            Self::NoScans { topic, messages, outside_pose, pose } => write!(
                f,
                "no scan within the pose's time: topic {topic} has {messages} messages, {outside_pose} of them \
                 outside the time of the pose ({pose})"
            ),
        }
    }
}

impl std::error::Error for Error {}

impl From<BagError> for Error {
    fn from(e: BagError) -> Self {
        Error::Bag(e)
    }
}

/// Reads the lidar run of the bag at `path` (a rosbag2 directory or a `.mcap` file).
pub fn read(path: &Path, o: &Options) -> Result<BagRun, Error> {
    let files = source::files(path)?;
    let m = source::read_types(&files, LIDAR_TYPES)?;
    from_messages(&m, o)
}

/// One link of the chain from the map to the robot: fixed, or moving in time.
#[derive(Clone, Debug)]
enum Link {
    Fixed(Pose2),
    Moving(Track),
}

/// The robot's pose in the map: the links composed, each at the stamp.
#[derive(Clone, Debug)]
struct PoseSource {
    links: Vec<Link>,
    /// What it is, for [`Used::pose`].
    name: String,
    /// The topics it reads (left out of [`LidarRun::skipped`]).
    topics: Vec<String>,
}

impl PoseSource {
    /// The pose at `t` ns; `None` outside any moving link's time.
    fn at(&self, t: i64) -> Option<Pose2> {
        let mut p = [0.0; 3];
        for l in &self.links {
            let q = match l {
                Link::Fixed(q) => *q,
                Link::Moving(track) => track.at(t, i64::MAX)?,
            };
            p = compose(p, q);
        }
        Some([p[0], p[1], wrap(p[2])])
    }
}

/// The bag's messages as a lidar run.
pub fn from_messages(m: &Messages, o: &Options) -> Result<BagRun, Error> {
    let scan_topic = scan_topic(m, o)?;
    let pose = pose_source(m, o)?;
    let odom_topic = odometry_topic(m, o, &pose.topics)?;
    let odom = odom_topic.map(|t| pose_track(m, t)).transpose()?;
    let statics = if o.laser_mount.is_none() { static_transforms(m)? } else { BTreeMap::new() };
    let mut used = Used {
        scans: scan_topic.into(),
        pose: pose.name.clone(),
        odometry: odom_topic.map(String::from),
        mount_from: if o.laser_mount.is_some() { "--laser-mount" } else { "/tf_static" }.into(),
        ..Used::default()
    };

    let mut mounts: BTreeMap<String, Pose2> = BTreeMap::new();
    let mut scans = Vec::new();
    let mut last: Option<i64> = None;
    let messages = stored(m, scan_topic);
    for (index, s) in messages.iter().enumerate() {
        let msg: msgs::LaserScan = decoded(scan_topic, index, types::LASER_SCAN, s)?;
        let stamp_s = msg.header.stamp.seconds();
        let err = |problem| Error::Scan { topic: scan_topic.into(), index, stamp_s, problem };
        stamp_s.ok_or_else(|| err(ScanProblem::BadStamp))?;
        let t = msg.header.stamp.nanos();
        if let Some(prev) = last.filter(|&p| t < p) {
            return Err(BagError::TimeBackwards {
                topic: scan_topic.into(),
                index,
                stamp_s: t as f64 / 1e9,
                previous_s: prev as f64 / 1e9,
            }
            .into());
        }
        last = Some(t);
        let (ranges, no_return) = ranges(&msg).map_err(err)?;
        used.no_return += no_return;

        // The laser on the robot, once per frame.
        let frame = strip(&msg.header.frame_id);
        if frame.is_empty() {
            return Err(err(ScanProblem::NoFrame));
        }
        let mount = match (mounts.get(frame), o.laser_mount) {
            (Some(&p), _) => p,
            (None, given) => {
                let p = given.or_else(|| chain(&statics, &o.base_frame, frame)).ok_or_else(|| Error::NoMount {
                    topic: scan_topic.into(),
                    index,
                    frame: frame.into(),
                    base: o.base_frame.clone(),
                })?;
                mounts.insert(frame.into(), p);
                p
            }
        };

        let Some(robot) = pose.at(t) else {
            used.outside_pose += 1;
            continue;
        };
        let l = compose(robot, mount);
        scans.push(Scan {
            time_s: t as f64 / 1e9,
            robot,
            laser: [l[0], l[1], wrap(l[2])],
            odometry: odom.as_ref().and_then(|tr| tr.at(t, i64::MAX)).map(|p| [p[0], p[1], wrap(p[2])]),
            angle_min: f64::from(msg.angle_min),
            angle_step: f64::from(msg.angle_increment),
            ranges,
            line: index as u64,
        });
    }
    used.mounts = mounts.into_iter().collect();
    if scans.is_empty() {
        return Err(Error::NoScans {
            topic: scan_topic.into(),
            messages: messages.len(),
            outside_pose: used.outside_pose,
            pose: pose.name,
        });
    }

    // Every other topic's messages, by type.
    let mut read: BTreeSet<&str> = pose.topics.iter().map(String::as_str).collect();
    read.insert(scan_topic);
    read.extend(odom_topic);
    let mut skipped: Vec<(String, usize)> = Vec::new();
    for t in m.topics.values() {
        let tf_static_used = o.laser_mount.is_none() && t.ty == types::TF && leaf(&t.name) == "tf_static";
        if read.contains(t.name.as_str()) || tf_static_used {
            continue;
        }
        match skipped.iter_mut().find(|(k, _)| *k == t.ty) {
            Some((_, n)) => *n += t.count,
            None => skipped.push((t.ty.clone(), t.count)),
        }
    }
    if used.outside_pose > 0 {
        skipped.push((format!("{} outside the pose's time", types::LASER_SCAN), used.outside_pose));
    }
    let run = LidarRun { scans, format: format!("ros2 bag LaserScan {scan_topic}"), skipped, first_index: 0 };
    Ok(BagRun { run, used })
}

/// The LaserScan topic: the one named, else the only one.
fn scan_topic<'a>(m: &'a Messages, o: &Options) -> Result<&'a str, Error> {
    if let Some(t) = &o.scans {
        return Ok(named(m, "--scans", t, &[types::LASER_SCAN])?);
    }
    match of_type(m, types::LASER_SCAN)[..] {
        [] => Err(Error::NoLaserScan { topics: topics_of(m) }),
        [one] => Ok(one),
        ref several => Err(BagError::Ambiguous {
            what: "LaserScan",
            option: "--scans",
            candidates: several.iter().map(|s| s.to_string()).collect(),
        }
        .into()),
    }
}

/// The robot's pose: the topic named, else the pose topic, else an
/// Odometry topic (a ground truth's if several), else `/tf`.
fn pose_source(m: &Messages, o: &Options) -> Result<PoseSource, Error> {
    let topic = match o.pose.as_deref() {
        Some(POSE_FROM_TF) => None,
        Some(t) => Some(named(m, "--pose", t, &[types::POSE_STAMPED, types::POSE_COV, types::ODOMETRY])?),
        None => {
            let ambiguous = |what, c: &[&str]| {
                Error::Bag(BagError::Ambiguous {
                    what,
                    option: "--pose",
                    candidates: c.iter().map(|s| s.to_string()).collect(),
                })
            };
            let mut poses = of_type(m, types::POSE_STAMPED);
            poses.extend(of_type(m, types::POSE_COV));
            let odoms = of_type(m, types::ODOMETRY);
            let truths: Vec<&str> = odoms.iter().copied().filter(|t| says_truth(t)).collect();
            match (&poses[..], &truths[..], &odoms[..]) {
                ([one], _, _) => Some(*one),
                ([_, _, ..], _, _) => return Err(ambiguous("pose", &poses)),
                ([], [truth], _) => Some(*truth),
                ([], [_, _, ..], _) => return Err(ambiguous("ground-truth Odometry", &truths)),
                ([], [], [one]) => Some(*one),
                ([], [], [_, _, ..]) => return Err(ambiguous("Odometry", &odoms)),
                ([], [], []) => None,
            }
        }
    };
    if let Some(topic) = topic {
        let track = pose_track(m, topic)?;
        return Ok(PoseSource { links: vec![Link::Moving(track)], name: topic.into(), topics: vec![topic.into()] });
    }
    // /tf: map -> base directly, else map -> odom (in /tf or /tf_static) then odom -> base.
    let (map, odom, base) = (o.map_frame.as_str(), o.odom_frame.as_str(), o.base_frame.as_str());
    let tf_topics: Vec<String> =
        m.topics.values().filter(|t| t.ty == types::TF && leaf(&t.name) == "tf").map(|t| t.name.clone()).collect();
    let direct = tf_track(m, map, base)?;
    if !direct.is_empty() {
        let name = format!("{} ({map} -> {base})", direct.name);
        return Ok(PoseSource { links: vec![Link::Moving(direct)], name, topics: tf_topics });
    }
    let odom_base = tf_track(m, odom, base)?;
    if !odom_base.is_empty() {
        let map_odom = tf_track(m, map, odom)?;
        let name = format!("{} ({map} -> {odom} -> {base})", odom_base.name);
        if !map_odom.is_empty() {
            let links = vec![Link::Moving(map_odom), Link::Moving(odom_base)];
            return Ok(PoseSource { links, name, topics: tf_topics });
        }
        if let Some(fixed) = chain(&static_transforms(m)?, map, odom) {
            let name = format!("{name}, {map} -> {odom} from /tf_static");
            return Ok(PoseSource {
                links: vec![Link::Fixed(fixed), Link::Moving(odom_base)],
                name,
                topics: tf_topics,
            });
        }
    }
    Err(Error::NoPose { topics: topics_of(m), map_frame: map.into(), odom_frame: odom.into(), base_frame: base.into() })
}

/// The odometry kept with each scan: the topic named, else the Odometry
/// topic that is neither the pose's nor a ground truth (`odom` if several).
fn odometry_topic<'a>(m: &'a Messages, o: &Options, pose_topics: &[String]) -> Result<Option<&'a str>, Error> {
    if let Some(t) = &o.odom {
        return Ok(Some(named(m, "--odom", t, &[types::ODOMETRY])?));
    }
    let odoms: Vec<&str> = of_type(m, types::ODOMETRY)
        .into_iter()
        .filter(|t| !says_truth(t) && !pose_topics.iter().any(|p| p == t))
        .collect();
    match odoms[..] {
        [] => Ok(None),
        [one] => Ok(Some(one)),
        ref several => match several.iter().find(|t| leaf(t) == "odom") {
            Some(t) => Ok(Some(*t)),
            None => Err(BagError::Ambiguous {
                what: "odometry",
                option: "--odom",
                candidates: several.iter().map(|s| s.to_string()).collect(),
            }
            .into()),
        },
    }
}

/// The scan's ranges as REP 117 means them (`f32::INFINITY`: no return),
/// and how many had none; refuses limits and angles no laser has, and a
/// negative range.
fn ranges(msg: &msgs::LaserScan) -> Result<(Vec<f32>, usize), ScanProblem> {
    let (lo, hi) = (msg.range_min, msg.range_max);
    if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo < hi) {
        return Err(ScanProblem::BadLimits { min: lo, max: hi });
    }
    let n = msg.ranges.len();
    if n > MAX_BEAMS {
        return Err(ScanProblem::TooManyBeams(n));
    }
    // A sweep of more than a turn (and a little: drivers round) is degrees, not radians.
    let turn = 2.0 * std::f64::consts::PI * 1.01;
    let (a0, da) = (f64::from(msg.angle_min), f64::from(msg.angle_increment));
    if !(a0.is_finite()
        && da.is_finite()
        && da != 0.0
        && a0.abs() <= turn
        && da.abs() * n.saturating_sub(1) as f64 <= turn)
    {
        return Err(ScanProblem::BadAngles { min: msg.angle_min, increment: msg.angle_increment, beams: n });
    }
    let mut none = 0;
    let mut out = Vec::with_capacity(n);
    for (beam, &r) in msg.ranges.iter().enumerate() {
        if r.is_finite() && r < 0.0 {
            return Err(ScanProblem::NegativeRange { beam, range: r });
        }
        // NaN and ±Inf fail the test; 0 is some drivers' "none" even when range_min is 0.
        if r >= lo && r <= hi && r > 0.0 {
            out.push(r);
        } else {
            none += 1;
            out.push(f32::INFINITY);
        }
    }
    Ok((out, none))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(ranges: Vec<f32>) -> msgs::LaserScan {
        msgs::LaserScan {
            header: msgs::Header { stamp: msgs::Time { sec: 1, nanosec: 0 }, frame_id: "laser".into() },
            angle_min: -1.0,
            angle_max: 1.0,
            angle_increment: 0.5,
            time_increment: 0.0,
            scan_time: 0.1,
            range_min: 0.1,
            range_max: 10.0,
            ranges,
        }
    }

    #[test]
    fn rep_117_ranges() {
        let (r, none) = ranges(&scan(vec![1.0, f32::INFINITY, f32::NAN, f32::NEG_INFINITY, 0.05, 12.0, 0.0])).unwrap();
        assert_eq!(r[0], 1.0);
        assert!(r[1..].iter().all(|v| *v == f32::INFINITY), "{r:?}");
        assert_eq!(none, 6);
        // At the limits themselves: a return.
        assert_eq!(ranges(&scan(vec![0.1, 10.0])).unwrap().0, vec![0.1, 10.0]);
        assert_eq!(ranges(&scan(vec![1.0, -0.5])).unwrap_err(), ScanProblem::NegativeRange { beam: 1, range: -0.5 });
        let mut s = scan(vec![1.0]);
        s.range_min = 5.0;
        s.range_max = 1.0;
        assert_eq!(ranges(&s).unwrap_err(), ScanProblem::BadLimits { min: 5.0, max: 1.0 });
        s.range_min = f32::NAN;
        assert!(matches!(ranges(&s).unwrap_err(), ScanProblem::BadLimits { .. }));
    }

    #[test]
    fn angles_in_degrees_are_refused() {
        let mut s = scan(vec![1.0; 361]);
        s.angle_min = -90.0;
        s.angle_increment = 0.5;
        assert!(matches!(ranges(&s).unwrap_err(), ScanProblem::BadAngles { beams: 361, .. }));
        s.angle_min = -1.5;
        s.angle_increment = 0.0;
        assert!(matches!(ranges(&s).unwrap_err(), ScanProblem::BadAngles { .. }));
        // A full turn, clockwise, is a laser's.
        s.angle_min = std::f32::consts::PI;
        s.angle_increment = -std::f32::consts::TAU / 361.0;
        assert!(ranges(&s).is_ok());
    }

    #[test]
    fn mounts_parse() {
        assert_eq!(parse_mount("0.2, -0.1, 1.5").unwrap(), [0.2, -0.1, 1.5]);
        assert!(parse_mount("0.2,0").unwrap_err().contains("three numbers"));
        assert!(parse_mount("0,0,90").unwrap_err().contains("radians"));
        assert!(parse_mount("a,0,0").is_err());
    }

    #[test]
    fn chained_poses_compose_at_each_stamp() {
        let t = |s: i32| msgs::Time { sec: s, nanosec: 0 };
        let mut map_odom = Track::new("/tf");
        map_odom.push(0, t(0), Some([1.0, 0.0, 0.0])).unwrap();
        map_odom.push(1, t(10), Some([1.0, 0.0, std::f64::consts::FRAC_PI_2])).unwrap();
        let mut odom_base = Track::new("/tf");
        odom_base.push(0, t(2), Some([1.0, 0.0, 0.0])).unwrap();
        odom_base.push(1, t(6), Some([3.0, 0.0, 0.0])).unwrap();
        let p = PoseSource {
            links: vec![Link::Moving(map_odom), Link::Moving(odom_base)],
            name: String::new(),
            topics: vec![],
        };
        // At 5 s: map -> odom turned by π/4, odom -> base at x = 2.5.
        let q = p.at(5_000_000_000).unwrap();
        let c = std::f64::consts::FRAC_PI_4;
        assert!((q[0] - (1.0 + 2.5 * c.cos())).abs() < 1e-12 && (q[1] - 2.5 * c.sin()).abs() < 1e-12, "{q:?}");
        assert!((q[2] - c).abs() < 1e-12);
        // Outside either link's time: none.
        assert_eq!(p.at(1_000_000_000), None);
        assert_eq!(p.at(7_000_000_000), None);
        let fixed = PoseSource {
            links: vec![Link::Fixed([0.0, 0.0, 3.0]), Link::Fixed([0.0, 0.0, 0.5])],
            name: String::new(),
            topics: vec![],
        };
        assert!((fixed.at(0).unwrap()[2] - wrap(3.5)).abs() < 1e-12, "the heading is wrapped");
    }
}
