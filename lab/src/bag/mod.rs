//! ROS 2 bags in: a rosbag2 recording in MCAP or sqlite3 (Humble's
//! default) storage (a bag directory with its `metadata.yaml`, or a bare
//! `.mcap` or `.db3`) read as the plain log
//! ([`crate::log`]) that `replay` and `scenario --from-log` take
//! (`docs/bags.md`).
//!
//! | what | topics (found by type when not named) |
//! |---|---|
//! | ranges | `sensor_msgs/msg/Range`, one topic per transducer or one topic whose `header.frame_id` names it; or RosAria's `sensor_msgs/msg/PointCloud` on `/sonar` (the whole ring, one point per transducer in the robot's frame, no echo as a point at the 5 m maximum) |
//! | the ring | `/tf_static`: `base_link` → each Range's frame (chains are followed); or `--ring` |
//! | odometry | `nav_msgs/msg/Odometry`, or `/tf` `odom` → `base_link` |
//! | reference (optional) | `geometry_msgs/msg/PoseWithCovarianceStamped` (`/amcl_pose`), or an `Odometry` topic of a simulator's ground truth |
//!
//! Every reading becomes a [`Row`] at its `header.stamp`,
//! with the odometry (and the reference) interpolated to that time. Ranges
//! follow REP 117: `+Inf`, `-Inf` and values outside
//! `[min_range, max_range]` are no echo; a negative or NaN range, or limits
//! no sonar has, refuse the bag with a [`BagError`] naming the topic and the
//! message.
//!
//! ```no_run
//! use echoloc_lab::bag::{read, Options};
//! let bag = read("run.bag".as_ref(), &Options::default())?;
//! println!("{} readings from {:?}", bag.rows.len(), bag.used.ranges);
//! std::fs::write("run.csv", echoloc_lab::log::write(&bag.rows, bag.has_reference()))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod cli;
pub mod msgs;
mod ranges;
pub mod source;
mod sqlite;
pub mod stored;
pub mod write;

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use echoloc::predict::Mount;

use crate::log::{turn_too_fast, Row, MAX_RANGE_MM};
use msgs::{decode, types};
use source::{Messages, Stored};

/// What to read from the bag; empty fields are found by type.
#[derive(Clone, Debug)]
pub struct Options {
    /// The range topics (Range, or one PointCloud); empty: every Range topic,
    /// else the PointCloud topic.
    pub ranges: Vec<String>,
    /// The odometry topic (`nav_msgs/msg/Odometry`); `None`: the one
    /// Odometry topic named `odom` (or the only one that is not a ground
    /// truth), else `/tf`.
    pub odom: Option<String>,
    /// The reference topic; `None`: `/amcl_pose`-like PoseWithCovarianceStamped,
    /// else an Odometry topic whose name says ground truth; else none.
    pub reference: Option<String>,
    /// The ring, when given (`--ring`); `None`: from `/tf_static` for Range
    /// topics, the Pioneer ring for a PointCloud.
    pub ring: Option<Vec<Mount>>,
    /// The robot's frame.
    pub base_frame: String,
    /// The odometry's frame (for `/tf`).
    pub odom_frame: String,
    /// A PointCloud point at this range or beyond is no echo, m (RosAria: 5).
    pub cloud_max_m: f64,
    /// When a PointCloud's points were fired, given its one stamp.
    pub cloud_timing: CloudTiming,
}

/// When a ring stamped once (a RosAria PointCloud) fired each transducer.
#[derive(Clone, Debug, PartialEq)]
pub enum CloudTiming {
    /// Every point at the stamp.
    AtStamp,
    /// The ring fires slot by slot, `slot_ns` apart (a slot may fire
    /// several transducers at once: a Pioneer's two arrays); the stamp is
    /// the ring's start (its first slot) or its end (one period after).
    Rebuilt {
        /// Each transducer's slot.
        slot_of: Vec<u32>,
        /// Slots in a ring cycle.
        slots: u32,
        /// One slot, ns (at most `period_ns / slots`).
        slot_ns: i64,
        /// One ring cycle, ns.
        period_ns: i64,
        /// What the stamp marks.
        stamp: RingStamp,
    },
}

/// What a whole-ring message's stamp marks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RingStamp {
    /// The ring's first firing.
    Start,
    /// The ring's end, one period after its first firing (RosAria stamps
    /// the cloud when it publishes it, after the newest reading).
    End,
}

/// RosAria's Pioneer: each 8-transducer array fires one transducer every
/// 40 ms in the sequence 0–7, the two arrays at once (ARCOS' default
/// `SonarCycle` and polling sequence), so a ring cycle is 320 ms, ns.
pub const PIONEER_RING_PERIOD_NS: i64 = 320_000_000;

/// The Pioneer's firing order as ARCOS fires it by default: slot j fires
/// transducer j of the front array and j + 8 of the rear.
pub fn pioneer_order() -> Vec<Vec<u8>> {
    (0..8).map(|j| vec![j, j + 8]).collect()
}

impl fmt::Display for CloudTiming {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::AtStamp => write!(f, "every point at the stamp"),
            Self::Rebuilt { slots, slot_ns, period_ns, stamp, .. } => write!(
                f,
                "rebuilt: {slots} slots {} s apart in a {} s cycle, the stamp at the ring's {}",
                *slot_ns as f64 / 1e9,
                *period_ns as f64 / 1e9,
                match stamp {
                    RingStamp::Start => "start",
                    RingStamp::End => "end",
                }
            ),
        }
    }
}

impl CloudTiming {
    /// A ring firing `order` (slots, each the transducers it fires) on a
    /// ring of `n`, one slot every `slot_ns` (default: the period spread
    /// evenly); every transducer must fire exactly once.
    pub fn rebuilt(
        order: &[Vec<u8>],
        n: usize,
        period_ns: i64,
        slot_ns: Option<i64>,
        stamp: RingStamp,
    ) -> Result<Self, String> {
        let mut slot_of = vec![u32::MAX; n];
        for (s, slot) in order.iter().enumerate() {
            for &t in slot {
                let k = usize::from(t);
                match slot_of.get_mut(k) {
                    None => return Err(format!("the firing order names transducer {t}: the ring has {n}")),
                    Some(v) if *v != u32::MAX => return Err(format!("the firing order fires transducer {t} twice")),
                    Some(v) => *v = s as u32,
                }
            }
        }
        if let Some(k) = slot_of.iter().position(|&s| s == u32::MAX) {
            return Err(format!("the firing order never fires transducer {k}"));
        }
        let slots = order.len() as i64;
        let slot_ns = slot_ns.unwrap_or(period_ns / slots.max(1));
        if period_ns <= 0 || slot_ns <= 0 || slot_ns * slots > period_ns {
            return Err(format!(
                "{slots} slots of {} s do not fit a ring cycle of {} s",
                slot_ns as f64 / 1e9,
                period_ns as f64 / 1e9
            ));
        }
        Ok(Self::Rebuilt { slot_of, slots: slots as u32, slot_ns, period_ns, stamp })
    }

    /// RosAria's Pioneer ring of 16 (see [`PIONEER_RING_PERIOD_NS`]),
    /// stamped at its end.
    pub fn pioneer() -> Self {
        Self::rebuilt(&pioneer_order(), 16, PIONEER_RING_PERIOD_NS, None, RingStamp::End).unwrap_or(Self::AtStamp)
    }

    /// Point `k`'s firing time after the stamp (negative: before), ns.
    pub fn offset_ns(&self, k: usize) -> i64 {
        match self {
            Self::AtStamp => 0,
            Self::Rebuilt { slot_of, slot_ns, period_ns, stamp, .. } => {
                let at = i64::from(slot_of.get(k).copied().unwrap_or(0)) * slot_ns;
                match stamp {
                    RingStamp::Start => at,
                    RingStamp::End => at - period_ns,
                }
            }
        }
    }
}

impl Default for Options {
    fn default() -> Self {
        Self {
            ranges: Vec::new(),
            odom: None,
            reference: None,
            ring: None,
            base_frame: "base_link".into(),
            odom_frame: "odom".into(),
            cloud_max_m: 5.0,
            cloud_timing: CloudTiming::pioneer(),
        }
    }
}

/// The topics a bag was read from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Used {
    /// The range topics.
    pub ranges: Vec<String>,
    /// Their type.
    pub ranges_type: String,
    /// The odometry: a topic, or `/tf (odom -> base_link)`.
    pub odometry: String,
    /// The reference, if any.
    pub reference: Option<String>,
    /// Where the ring came from: `/tf_static`, or `--ring`.
    pub ring: String,
    /// For a whole-ring PointCloud, how its points' firing times were taken.
    pub cloud_timing: Option<String>,
}

/// One transducer as the bag names it.
#[derive(Clone, Debug, PartialEq)]
pub struct Transducer {
    /// Its index in the ring (and the log's `transducer` column).
    pub index: u8,
    /// Its frame (for a PointCloud, `point N`).
    pub frame: String,
    /// Where it sits.
    pub mount: Mount,
}

/// How many readings were no echo, and why.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoEcho {
    /// `+Inf` (REP 117: nothing within range).
    pub infinite: u32,
    /// `-Inf` (REP 117: too close to measure).
    pub too_close: u32,
    /// Beyond the message's `max_range`, or a cloud point at the maximum.
    pub beyond_max: u32,
    /// Below its `min_range`.
    pub below_min: u32,
}

/// A bag read as a log.
#[derive(Clone, Debug, Default)]
pub struct Bag {
    /// The readings, in time order (ties in the bag's order).
    pub rows: Vec<Row>,
    /// The ring the rows index.
    pub ring: Vec<Mount>,
    /// The transducers, in ring order.
    pub transducers: Vec<Transducer>,
    /// The topics used.
    pub used: Used,
    /// Readings left out because no odometry covers their time (before the
    /// first odometry message or after the last).
    pub outside_odometry: usize,
    /// The no-echo readings by reason.
    pub no_echo: NoEcho,
}

impl Bag {
    /// Whether any row has a reference pose.
    pub fn has_reference(&self) -> bool {
        self.rows.iter().any(|r| r.reference.is_some())
    }
}

/// What is wrong with one message.
#[derive(Clone, Debug, PartialEq)]
pub enum MessageProblem {
    /// A negative range (REP 117 has none: `-Inf` is "too close").
    NegativeRange(f32),
    /// A NaN range.
    NanRange,
    /// Zero.
    ZeroRange,
    /// `min_range`/`max_range` no sonar has (negative, NaN, not increasing).
    BadLimits { min: f32, max: f32 },
    /// A range or `max_range` beyond any sonar: another unit (mm?).
    BeyondAnySonar { value: f64 },
    /// A stamp with `nanosec` ≥ 10⁹.
    BadStamp,
    /// A pose with a non-finite number or a zero quaternion.
    BadPose,
    /// A PointCloud with another number of points than the ring.
    PointCount { found: usize, ring: usize },
    /// A cloud point that does not lie on its transducer's axis.
    OffAxis { point: usize, degrees: f64 },
    /// A cloud point not finite.
    BadPoint { point: usize },
    /// A PointCloud in a frame other than the robot's.
    CloudFrame { frame: String, base: String },
    /// The Range's frame is empty.
    NoFrame,
    /// Its frame names no transducer of the ring.
    UnknownFrame { frame: String },
    /// The odometry turns faster than any robot between two readings ([`turn_too_fast`]).
    HeadingJump { from: f64, to: f64, dt_s: f64 },
}

impl fmt::Display for MessageProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NegativeRange(r) => {
                write!(f, "range {r} m is negative: no range can be (REP 117: +Inf is no return, -Inf too close)")
            }
            Self::NanRange => write!(f, "range is NaN: not a reading (REP 117: +Inf is no return, -Inf too close)"),
            Self::ZeroRange => write!(f, "range is 0 m: no sonar measures that (-Inf says too close)"),
            Self::BadLimits { min, max } => {
                write!(
                    f,
                    "min_range {min} m, max_range {max} m: limits must be finite, min_range ≥ 0 and below max_range"
                )
            }
            Self::BeyondAnySonar { value } => write!(
                f,
                "{value} m is beyond any sonar ({} m): the unit is not metres (millimetres?)",
                MAX_RANGE_MM / 1000.0
            ),
            Self::BadStamp => write!(f, "header.stamp has nanosec ≥ 10⁹"),
            Self::BadPose => write!(f, "the pose has a non-finite number or a zero-length quaternion"),
            Self::PointCount { found, ring } => {
                write!(f, "{found} points, the ring has {ring} transducers (one point each; --ring?)")
            }
            Self::OffAxis { point, degrees } => write!(
                f,
                "point {point} lies {degrees:.1}° off transducer {point}'s axis: the ring (--ring) is not the robot's"
            ),
            Self::BadPoint { point } => write!(f, "point {point} is not finite"),
            Self::CloudFrame { frame, base } => {
                write!(f, "frame {frame:?}: the points must be in the robot's frame {base:?} (--base-frame)")
            }
            Self::NoFrame => write!(f, "header.frame_id is empty: which transducer is it?"),
            Self::UnknownFrame { frame } => write!(f, "frame {frame:?} is not one of the ring's"),
            Self::HeadingJump { from, to, dt_s } => write!(
                f,
                "the odometry turns from {from:.4} to {to:.4} rad in {dt_s} s between two readings, faster than any \
                 robot turns (a full turn a second): not odometry (a reset?)"
            ),
        }
    }
}

/// Why a bag was refused.
#[derive(Clone, Debug, PartialEq)]
pub enum BagError {
    /// A file could not be read.
    Io { path: PathBuf, problem: String },
    /// `metadata.yaml` is not rosbag2's, or names a storage echoloc does not read.
    Metadata { path: PathBuf, problem: String },
    /// The MCAP file is damaged (a bad chunk, a CRC mismatch, truncated).
    Unreadable { path: PathBuf, problem: String },
    /// The sqlite3 storage file (`.db3`) is not rosbag2's: not SQLite, damaged, a table or column missing.
    Sqlite { path: PathBuf, problem: String },
    /// A topic not in CDR with a ros2msg schema.
    Encoding { topic: String, problem: String },
    /// No topic of a type echoloc takes ranges from.
    NoRangeTopic { topics: Vec<(String, String)> },
    /// Neither an Odometry topic nor `odom` → base in `/tf`.
    NoOdometry { topics: Vec<(String, String)>, odom_frame: String, base_frame: String },
    /// Several candidate topics; one must be named.
    Ambiguous { what: &'static str, option: &'static str, candidates: Vec<String> },
    /// A named topic the bag lacks.
    NoSuchTopic { option: &'static str, topic: String, topics: Vec<(String, String)> },
    /// A named topic of another type.
    WrongType { option: &'static str, topic: String, found: String, expected: String },
    /// Range and PointCloud topics mixed in `--ranges`.
    MixedRanges,
    /// A message that does not decode as its type.
    Decode { topic: String, index: usize, ty: String, problem: String },
    /// A message that decodes but says something impossible.
    Message { topic: String, index: usize, stamp_s: Option<f64>, problem: MessageProblem },
    /// A transducer frame with no transform from the robot's frame.
    NoTransform { topic: String, frame: String, base: String },
    /// `--ring` has another number of transducers than the bag's frames.
    RingSize { frames: Vec<String>, ring: usize },
    /// More than 255 transducers.
    TooManyTransducers(usize),
    /// A topic's `header.stamp` going backwards.
    TimeBackwards { topic: String, index: usize, stamp_s: f64, previous_s: f64 },
    /// No reading within the odometry's time.
    NoReadings { outside_odometry: usize },
}

fn list(topics: &[(String, String)]) -> String {
    if topics.is_empty() {
        return "none".into();
    }
    topics.iter().map(|(n, t)| format!("{n} ({t})")).collect::<Vec<_>>().join(", ")
}

impl fmt::Display for BagError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io { path, problem } => write!(f, "{}: {problem}", path.display()),
            Self::Metadata { path, problem } => write!(f, "{}: {problem}", path.display()),
            Self::Unreadable { path, problem } => write!(f, "{}: unreadable MCAP: {problem}", path.display()),
            Self::Sqlite { path, problem } => write!(f, "{}: unreadable sqlite3 bag: {problem}", path.display()),
            Self::Encoding { topic, problem } => write!(f, "topic {topic}: {problem}"),
            Self::NoRangeTopic { topics } => write!(
                f,
                "no range topic: no {} nor {} topic in the bag (topics: {})",
                types::RANGE,
                types::POINT_CLOUD,
                list(topics)
            ),
            Self::NoOdometry { topics, odom_frame, base_frame } => write!(
                f,
                "no odometry: no {} topic and no {odom_frame} -> {base_frame} transform in /tf (topics: {})",
                types::ODOMETRY,
                list(topics)
            ),
            Self::Ambiguous { what, option, candidates } => {
                write!(f, "several {what} topics ({}): name one with {option}", candidates.join(", "))
            }
            Self::NoSuchTopic { option, topic, topics } => {
                write!(f, "{option} {topic}: the bag has no such topic (topics: {})", list(topics))
            }
            Self::WrongType { option, topic, found, expected } => {
                write!(f, "{option} {topic}: its type is {found}, expected {expected}")
            }
            Self::MixedRanges => write!(f, "--ranges: Range topics or one PointCloud topic, not both"),
            Self::Decode { topic, index, ty, problem } => {
                write!(f, "topic {topic}, message {index}: not a {ty}: {problem}")
            }
            Self::Message { topic, index, stamp_s, problem } => {
                write!(f, "topic {topic}, message {index}")?;
                if let Some(t) = stamp_s {
                    write!(f, " (stamp {t:.6} s)")?;
                }
                write!(f, ": {problem}")
            }
            Self::NoTransform { topic, frame, base } => write!(
                f,
                "topic {topic}: frame {frame:?} has no transform from {base:?} in /tf_static \
                 (publish the sonar frames, or give the ring with --ring)"
            ),
            Self::RingSize { frames, ring } => write!(
                f,
                "--ring has {ring} transducers, the bag's ranges come from {} frames ({})",
                frames.len(),
                frames.join(", ")
            ),
            Self::TooManyTransducers(n) => write!(f, "{n} transducer frames: at most 255"),
            Self::TimeBackwards { topic, index, stamp_s, previous_s } => write!(
                f,
                "topic {topic}, message {index}: header.stamp {stamp_s:.6} s is earlier than the message before \
                 it ({previous_s:.6} s): time goes backwards"
            ),
            Self::NoReadings { outside_odometry } => write!(
                f,
                "no reading within the odometry's time ({outside_odometry} readings outside it, or none at all)"
            ),
        }
    }
}

impl std::error::Error for BagError {}

// The helpers below are shared with the lidar's bag reader
// (`crate::lidar::bag`): topics by type, decoding, /tf and /tf_static,
// poses interpolated in time.

/// A planar pose, m, m, rad.
pub(crate) type Pose2 = [f64; 3];

/// `b` (a pose in `a`'s frame) in the frame `a` is in.
pub(crate) fn compose(a: Pose2, b: Pose2) -> Pose2 {
    let (s, c) = a[2].sin_cos();
    [a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]]
}

pub(crate) fn wrap(a: f64) -> f64 {
    crate::angle::wrap(a)
}

/// A frame without tf1's leading slash.
pub(crate) fn strip(frame: &str) -> &str {
    frame.strip_prefix('/').unwrap_or(frame)
}

/// A pose of a message: x, y and yaw, finite.
pub(crate) fn pose2(p: &msgs::Pose) -> Option<Pose2> {
    let yaw = p.orientation.yaw()?;
    let v = [p.position.x, p.position.y, yaw];
    v.iter().all(|x| x.is_finite()).then_some(v)
}

/// A time series of poses, sorted by stamp (ns).
#[derive(Clone, Debug, Default)]
pub(crate) struct Track {
    /// The topic, named in errors.
    pub(crate) name: String,
    stamps: Vec<i64>,
    poses: Vec<Pose2>,
}

impl Track {
    /// An empty track of topic `name`.
    pub(crate) fn new(name: &str) -> Self {
        Track { name: name.into(), ..Track::default() }
    }

    /// Whether it has no pose.
    pub(crate) fn is_empty(&self) -> bool {
        self.stamps.is_empty()
    }

    /// Adds message `index`'s pose at `stamp`, refusing a bad stamp or pose
    /// and time going backwards; of two poses with one stamp the later is kept.
    pub(crate) fn push(&mut self, index: usize, stamp: msgs::Time, pose: Option<Pose2>) -> Result<(), BagError> {
        let stamp_s = stamp.seconds();
        let err = |problem| BagError::Message { topic: self.name.clone(), index, stamp_s, problem };
        stamp_s.ok_or_else(|| err(MessageProblem::BadStamp))?;
        let pose = pose.ok_or_else(|| err(MessageProblem::BadPose))?;
        let t = stamp.nanos();
        if let Some(&prev) = self.stamps.last() {
            if t < prev {
                return Err(BagError::TimeBackwards {
                    topic: self.name.clone(),
                    index,
                    stamp_s: t as f64 / 1e9,
                    previous_s: prev as f64 / 1e9,
                });
            }
            if t == prev {
                // The later of two messages with one stamp.
                self.stamps.pop();
                self.poses.pop();
            }
        }
        self.stamps.push(t);
        self.poses.push(pose);
        Ok(())
    }

    /// The pose at `t`: a message's own at its stamp, else interpolated
    /// linearly between the two around `t` (the heading along the shorter
    /// turn); `None` outside the track, or across a gap longer than `max_gap_ns`.
    pub(crate) fn at(&self, t: i64, max_gap_ns: i64) -> Option<Pose2> {
        let i = self.stamps.partition_point(|&s| s < t);
        if self.stamps.get(i) == Some(&t) {
            return Some(self.poses[i]);
        }
        if i == 0 || i == self.stamps.len() {
            return None;
        }
        let (ta, tb) = (self.stamps[i - 1], self.stamps[i]);
        if tb - ta > max_gap_ns {
            return None;
        }
        let f = (t - ta) as f64 / (tb - ta) as f64;
        let (a, b) = (self.poses[i - 1], self.poses[i]);
        Some([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * wrap(b[2] - a[2])])
    }
}

/// Reference poses more than this far apart in time are not interpolated
/// between (a localiser that stopped publishing), ns.
pub const REFERENCE_MAX_GAP_NS: i64 = 1_000_000_000;

pub(crate) fn topics_of(m: &Messages) -> Vec<(String, String)> {
    m.topics.values().map(|t| (t.name.clone(), t.ty.clone())).collect()
}

pub(crate) fn of_type<'a>(m: &'a Messages, ty: &str) -> Vec<&'a str> {
    m.topics.values().filter(|t| t.ty == ty).map(|t| t.name.as_str()).collect()
}

pub(crate) fn named<'a>(
    m: &'a Messages,
    option: &'static str,
    topic: &str,
    expected: &[&str],
) -> Result<&'a str, BagError> {
    let t = m.topics.get(topic).ok_or_else(|| BagError::NoSuchTopic {
        option,
        topic: topic.into(),
        topics: topics_of(m),
    })?;
    if !expected.contains(&t.ty.as_str()) {
        return Err(BagError::WrongType {
            option,
            topic: topic.into(),
            found: t.ty.clone(),
            expected: expected.join(" or "),
        });
    }
    Ok(t.name.as_str())
}

pub(crate) fn stored<'a>(m: &'a Messages, topic: &str) -> &'a [Stored] {
    m.by_topic.get(topic).map_or(&[], Vec::as_slice)
}

pub(crate) fn decoded<'de, T: serde::Deserialize<'de>>(
    topic: &str,
    index: usize,
    ty: &str,
    s: &'de Stored,
) -> Result<T, BagError> {
    decode(&s.data).map_err(|problem| BagError::Decode { topic: topic.into(), index, ty: ty.into(), problem })
}

/// Whether a topic's name says it is a ground truth.
pub(crate) fn says_truth(name: &str) -> bool {
    let n = name.to_ascii_lowercase();
    ["ground_truth", "groundtruth", "truth", "gt", "odom_gt", "base_pose_ground_truth"]
        .iter()
        .any(|k| n.split(['/', '_']).any(|p| p == *k) || n.contains("ground_truth") || n.contains("truth"))
}

/// The last path segment of a topic.
pub(crate) fn leaf(name: &str) -> &str {
    name.rsplit('/').next().unwrap_or(name)
}

/// Reads the bag at `path` (a rosbag2 directory or a `.mcap` file).
pub fn read(path: &Path, o: &Options) -> Result<Bag, BagError> {
    let files = source::files(path)?;
    let m = source::read(&files)?;
    from_messages(&m, o)
}

/// The bag's messages as a log, stage by stage: the range topics, their
/// readings (`bag::ranges`), the ring, the odometry and the reference, then
/// each reading as a row at its time.
pub fn from_messages(m: &Messages, o: &Options) -> Result<Bag, BagError> {
    let mut used = Used::default();
    let (range_topics, cloud) = ranges::topics(m, o)?;
    used.ranges = range_topics.iter().map(|s| s.to_string()).collect();
    used.ranges.sort_by_key(|t| ranges::frame_order(t));
    used.ranges_type = if cloud { types::POINT_CLOUD } else { types::RANGE }.into();
    if cloud {
        used.cloud_timing = Some(o.cloud_timing.to_string());
    }
    let cloud_ring =
        if cloud { Some(o.ring.clone().unwrap_or_else(|| echoloc::predict::PIONEER16.to_vec())) } else { None };
    let read = ranges::readings(m, o, &range_topics, cloud_ring.as_deref())?;
    let ring = ranges::ring(m, o, &range_topics, &read.frames_of, cloud_ring, &mut used)?;
    let odom = odometry(m, o, &mut used)?;
    let reference = reference(m, o, &used.odometry.clone(), &mut used)?;
    let (rows, outside) = rows(read.raws, &ring.index_of, &odom, reference.as_ref(), &used.odometry)?;
    Ok(Bag {
        rows,
        ring: ring.mounts,
        transducers: ring.transducers,
        used,
        outside_odometry: outside,
        no_echo: read.no_echo,
    })
}

/// Each reading as a row at its time, with the odometry (and the
/// reference) there; readings no odometry covers are left out and counted.
fn rows(
    mut raws: Vec<ranges::Raw>,
    index_of: &BTreeMap<ranges::Key, u8>,
    odom: &Track,
    reference: Option<&Track>,
    odom_topic: &str,
) -> Result<(Vec<Row>, usize), BagError> {
    raws.sort_by_key(|r| r.stamp); // stable: ties keep the bag's order
    let mut rows = Vec::with_capacity(raws.len());
    let mut outside = 0;
    for r in &raws {
        let Some(odometry) = odom.at(r.stamp, i64::MAX) else {
            outside += 1;
            continue;
        };
        let reference = reference.and_then(|t| t.at(r.stamp, REFERENCE_MAX_GAP_NS));
        // A quaternion's heading is wrapped: the turn is the short way.
        if let Some((prev, t0)) = rows.last().map(|p: &Row| (p.odometry[2], p.time_s)) {
            let dt_s = r.stamp as f64 / 1e9 - t0;
            if turn_too_fast(wrap(odometry[2] - prev), dt_s) {
                return Err(BagError::Message {
                    topic: odom_topic.to_string(),
                    index: 0,
                    stamp_s: Some(r.stamp as f64 / 1e9),
                    problem: MessageProblem::HeadingJump { from: prev, to: odometry[2], dt_s },
                });
            }
        }
        rows.push(Row {
            time_s: r.stamp as f64 / 1e9,
            transducer: index_of[&r.transducer],
            range_mm: r.range_mm,
            odometry,
            reference,
            line: 0,
        });
    }
    if rows.is_empty() {
        return Err(BagError::NoReadings { outside_odometry: outside });
    }
    Ok((rows, outside))
}

/// `/tf_static`'s transforms: child → (parent, pose of child in parent).
pub(crate) fn static_transforms(m: &Messages) -> Result<BTreeMap<String, (String, Pose2)>, BagError> {
    let mut out = BTreeMap::new();
    for (name, t) in &m.topics {
        if t.ty != types::TF || leaf(name) != "tf_static" {
            continue;
        }
        for (index, s) in stored(m, name).iter().enumerate() {
            let tf: msgs::TfMessage = decoded(name, index, types::TF, s)?;
            for ts in tf.transforms {
                let tr = ts.transform;
                let pose = tr.rotation.yaw().map(|y| [tr.translation.x, tr.translation.y, y]);
                let pose = pose.filter(|p| p.iter().all(|v| v.is_finite())).ok_or(BagError::Message {
                    topic: name.clone(),
                    index,
                    stamp_s: ts.header.stamp.seconds(),
                    problem: MessageProblem::BadPose,
                })?;
                out.insert(strip(&ts.child_frame_id).to_string(), (strip(&ts.header.frame_id).to_string(), pose));
            }
        }
    }
    Ok(out)
}

/// The pose of `frame` in `base` by following parents (at most 64 links).
pub(crate) fn chain(statics: &BTreeMap<String, (String, Pose2)>, base: &str, frame: &str) -> Option<Pose2> {
    let mut pose = [0.0; 3];
    let mut at = frame.to_string();
    for _ in 0..64 {
        if at == base {
            return Some(pose);
        }
        let (parent, p) = statics.get(&at)?;
        pose = compose(*p, pose);
        at = parent.clone();
    }
    None
}

/// The poses of a topic of Odometry, PoseWithCovarianceStamped or PoseStamped.
pub(crate) fn pose_track(m: &Messages, topic: &str) -> Result<Track, BagError> {
    let mut t = Track::new(topic);
    let ty = m.topics.get(topic).map_or("", |t| t.ty.as_str());
    for (index, s) in stored(m, topic).iter().enumerate() {
        let (stamp, pose) = match ty {
            types::POSE_COV => {
                let p: msgs::PoseWithCovarianceStamped = decoded(topic, index, types::POSE_COV, s)?;
                (p.header.stamp, pose2(&p.pose))
            }
            types::POSE_STAMPED => {
                let p: msgs::PoseStamped = decoded(topic, index, types::POSE_STAMPED, s)?;
                (p.header.stamp, pose2(&p.pose))
            }
            _ => {
                let p: msgs::Odometry = decoded(topic, index, types::ODOMETRY, s)?;
                (p.header.stamp, pose2(&p.pose))
            }
        };
        t.push(index, stamp, pose)?;
    }
    Ok(t)
}

fn odometry(m: &Messages, o: &Options, used: &mut Used) -> Result<Track, BagError> {
    let topic = match &o.odom {
        Some(t) => Some(named(m, "--odom", t, &[types::ODOMETRY])?),
        None => {
            let all = of_type(m, types::ODOMETRY);
            let odoms: Vec<&str> = all.iter().copied().filter(|t| !says_truth(t)).collect();
            match odoms[..] {
                [] => None,
                [one] => Some(one),
                _ => match odoms.iter().find(|t| leaf(t) == "odom") {
                    Some(t) => Some(*t),
                    None => {
                        return Err(BagError::Ambiguous {
                            what: "odometry",
                            option: "--odom",
                            candidates: odoms.iter().map(|s| s.to_string()).collect(),
                        })
                    }
                },
            }
        }
    };
    if let Some(topic) = topic {
        used.odometry = topic.into();
        return pose_track(m, topic);
    }
    // /tf odom -> base_link.
    let t = tf_track(m, &o.odom_frame, &o.base_frame)?;
    if t.is_empty() {
        return Err(BagError::NoOdometry {
            topics: topics_of(m),
            odom_frame: o.odom_frame.clone(),
            base_frame: o.base_frame.clone(),
        });
    }
    used.odometry = format!("{} ({} -> {})", t.name, o.odom_frame, o.base_frame);
    Ok(t)
}

/// The transforms `parent` -> `child` on `/tf` (every topic named `tf`), in
/// time; empty when there are none.
pub(crate) fn tf_track(m: &Messages, parent: &str, child: &str) -> Result<Track, BagError> {
    let mut t = Track::new("/tf");
    for (name, tt) in &m.topics {
        if tt.ty != types::TF || leaf(name) != "tf" {
            continue;
        }
        t.name = name.clone();
        for (index, s) in stored(m, name).iter().enumerate() {
            let tf: msgs::TfMessage = decoded(name, index, types::TF, s)?;
            for ts in tf.transforms {
                if strip(&ts.header.frame_id) == parent && strip(&ts.child_frame_id) == child {
                    let tr = ts.transform;
                    let pose = tr.rotation.yaw().map(|y| [tr.translation.x, tr.translation.y, y]);
                    t.push(index, ts.header.stamp, pose.filter(|p| p.iter().all(|v| v.is_finite())))?;
                }
            }
        }
    }
    Ok(t)
}

fn reference(m: &Messages, o: &Options, odom: &str, used: &mut Used) -> Result<Option<Track>, BagError> {
    let topic = match &o.reference {
        Some(t) => Some(named(m, "--reference", t, &[types::POSE_COV, types::ODOMETRY])?),
        None => {
            let poses = of_type(m, types::POSE_COV);
            let truths: Vec<&str> =
                of_type(m, types::ODOMETRY).into_iter().filter(|t| *t != odom && says_truth(t)).collect();
            let cands = if poses.is_empty() { truths } else { poses };
            match cands[..] {
                [] => None,
                [one] => Some(one),
                ref several => match several.iter().find(|t| leaf(t) == "amcl_pose") {
                    Some(t) => Some(*t),
                    None => {
                        return Err(BagError::Ambiguous {
                            what: "reference",
                            option: "--reference",
                            candidates: several.iter().map(|s| s.to_string()).collect(),
                        })
                    }
                },
            }
        }
    };
    let Some(topic) = topic else { return Ok(None) };
    used.reference = Some(topic.into());
    pose_track(m, topic).map(Some)
}
