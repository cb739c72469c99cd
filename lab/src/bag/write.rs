//! ROS 2 bags out: a sonar run (the plain log's rows and its ring) written
//! as a rosbag2 directory with MCAP storage, the way `ros2 bag record`
//! writes one, so ROS tools play it and [`super::read`] reads it back
//! (`docs/bags.md`, "ROS 2 bags out").
//!
//! | topic | type | what |
//! |---|---|---|
//! | `/sonar/<k>` | `sensor_msgs/msg/Range` | every row of transducer *k* at its time, frame `sonar_<k>`, range in metres, no echo `+Inf` (REP 117) |
//! | `/tf_static` | `tf2_msgs/msg/TFMessage` | one message: `base_link` → `sonar_<k>` for every mount; offered transient-local, as static broadcasters do |
//! | `/odom` | `nav_msgs/msg/Odometry` | the odometry, `odom` → `base_link`, one message per distinct row time |
//! | `/tf` | `tf2_msgs/msg/TFMessage` | the same pose as `odom` → `base_link`, so RViz can place the robot ([`WriteOptions::tf`]) |
//! | `/ground_truth` | `nav_msgs/msg/Odometry` | the reference, `map` → `base_link`, when rows have one |
//!
//! The types are ROS 2 Jazzy's (Range has `variance`, written 0: unknown),
//! each with its `ros2msg` schema (the definition and its dependencies in
//! `MSG:` blocks) and its RIHS01 type hash; messages are little-endian CDR
//! encoded by `cdr-encoding` from the serde types of [`super::msgs`].
//! `metadata.yaml` is rosbag2's version 8 (Iron's; Jazzy reads it), and the
//! MCAP carries the same metadata in its `rosbag2` record, as rosbag2's
//! MCAP plugin writes it.
//!
//! Everything is checked before anything is written; the bag is written
//! into a hidden sibling directory and renamed into place, so a refusal or
//! a failure leaves nothing behind.

use std::collections::BTreeMap;
use std::fmt;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use echoloc::predict::Mount;
use serde::Serialize;

use super::msgs::{self, header, mount_pose, odometry, transform, types, RangeMsg, TfMessage, ULTRASOUND};
use crate::log::{Row, MAX_RANGE_MM};

/// The robot's frame.
pub const BASE_FRAME: &str = "base_link";
/// The odometry's frame.
pub const ODOM_FRAME: &str = "odom";
/// The reference's frame.
pub const MAP_FRAME: &str = "map";
/// The odometry's topic.
pub const ODOM_TOPIC: &str = "/odom";
/// The reference's topic: its name says ground truth, which is how
/// [`super::read`] takes an Odometry topic as the reference.
pub const REFERENCE_TOPIC: &str = "/ground_truth";
/// The sonar mounts' topic.
pub const TF_STATIC_TOPIC: &str = "/tf_static";
/// The odometry as a transform.
pub const TF_TOPIC: &str = "/tf";

/// Transducer `k`'s Range topic, `/sonar/<k>`.
pub fn range_topic(k: usize) -> String {
    format!("/sonar/{k}")
}

/// Transducer `k`'s frame, `sonar_<k>` (the reader orders frames by their
/// trailing number, so the ring comes back in this order).
pub fn sonar_frame(k: usize) -> String {
    format!("sonar_{k}")
}

/// The Polaroid 6500's beam, rad: its main lobe, ±15° (first null at
/// 12.7°, `docs/credence.md`).
pub const POLAROID_FIELD_OF_VIEW_RAD: f64 = 30.0 * std::f64::consts::PI / 180.0;
/// The shortest range the Polaroid module reports, m: its 2.38 ms blanking
/// (the simulator's shortest range, 408 mm).
pub const POLAROID_MIN_RANGE_M: f64 = 0.408;
/// The longest, m: the end of its listening window.
pub const POLAROID_MAX_RANGE_M: f64 = 5.5;

/// MCAP chunk compression.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Compression {
    /// Uncompressed chunks, as `ros2 bag record` writes by default.
    #[default]
    None,
    /// zstd chunks (rosbag2's `zstd_fast`/`zstd_small` presets).
    Zstd,
}

/// How to write the bag.
#[derive(Clone, Debug, PartialEq)]
pub struct WriteOptions {
    /// Range's `field_of_view`, rad.
    pub field_of_view_rad: f64,
    /// Range's `min_range`, m: a row's range below it is refused (a reader
    /// would take it for no echo, REP 117).
    pub min_range_m: f64,
    /// Range's `max_range`, m: a row's range above it is refused likewise.
    pub max_range_m: f64,
    /// MCAP chunk compression.
    pub compression: Compression,
    /// Also publish the odometry on `/tf` (`odom` → `base_link`), as a
    /// robot's bag has it: RViz places the robot and its ranges by it.
    pub tf: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        Self {
            field_of_view_rad: POLAROID_FIELD_OF_VIEW_RAD,
            min_range_m: POLAROID_MIN_RANGE_M,
            max_range_m: POLAROID_MAX_RANGE_M,
            compression: Compression::None,
            tf: true,
        }
    }
}

/// What was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// The bag directory.
    pub dir: PathBuf,
    /// Its MCAP file.
    pub mcap: PathBuf,
    /// Every topic: name, type and message count, in the bag's order.
    pub topics: Vec<(String, String, usize)>,
    /// All messages.
    pub messages: usize,
}

/// What is wrong with one row.
#[derive(Clone, Debug, PartialEq)]
pub enum RowProblem {
    /// Its transducer is not one of the ring's.
    TransducerBeyondRing { transducer: u8, ring: usize },
    /// A time no ROS stamp holds: negative, not finite, or past 2038.
    BadTime(f64),
    /// Earlier than the row before it.
    TimeBackwards { time_s: f64, previous_s: f64 },
    /// A pose with a number that is not finite.
    NotFinite(&'static str),
    /// A range outside the Range's limits: a reader would take it for no echo.
    OutsideLimits { range_mm: u32, min_m: f64, max_m: f64 },
    /// Rows with one stamp but different poses: one message per stamp cannot say both.
    Conflict { what: &'static str, time_s: f64 },
}

impl fmt::Display for RowProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TransducerBeyondRing { transducer, ring } => {
                write!(f, "transducer {transducer}: the ring has {ring} (0 to {})", ring.saturating_sub(1))
            }
            Self::BadTime(t) => write!(f, "time {t} s: a stamp must be finite, ≥ 0 and within a 32-bit second count"),
            Self::TimeBackwards { time_s, previous_s } => {
                write!(
                    f,
                    "time {time_s} s is earlier than the row before it ({previous_s} s): rows must be in time order"
                )
            }
            Self::NotFinite(what) => write!(f, "the {what} pose has a number that is not finite"),
            Self::OutsideLimits { range_mm, min_m, max_m } => write!(
                f,
                "range {range_mm} mm is outside the Range limits [{min_m} m, {max_m} m]: a reader would take it for \
                 no echo (REP 117); widen the limits"
            ),
            Self::Conflict { what, time_s } => {
                write!(f, "another row at {time_s} s has another {what} pose: one message per stamp cannot say both")
            }
        }
    }
}

/// Why a bag was not written.
#[derive(Clone, Debug, PartialEq)]
pub enum WriteError {
    /// The bag directory exists already (rosbag2 never writes into one).
    Exists(PathBuf),
    /// A path a bag cannot be written at.
    BadPath { path: PathBuf, problem: String },
    /// Writing failed.
    Io { path: PathBuf, problem: String },
    /// An option no Range can carry.
    BadOption { option: &'static str, problem: String },
    /// No rows.
    NoRows,
    /// No transducers.
    EmptyRing,
    /// More transducers than a log's index (and the reader) takes.
    TooManyTransducers(usize),
    /// A row that cannot be written; `index` counts from 0, `line` is the
    /// log's line when the row came from a file.
    Row { index: usize, line: u64, problem: RowProblem },
    /// A message the CDR encoder refused.
    Encode { topic: String, problem: String },
    /// The MCAP writer failed.
    Mcap(String),
}

impl fmt::Display for WriteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Exists(p) => {
                write!(f, "{}: exists already; a bag is written into a new directory", p.display())
            }
            Self::BadPath { path, problem } | Self::Io { path, problem } => write!(f, "{}: {problem}", path.display()),
            Self::BadOption { option, problem } => write!(f, "{option}: {problem}"),
            Self::NoRows => write!(f, "no rows: a bag needs at least one reading"),
            Self::EmptyRing => write!(f, "the ring has no transducers"),
            Self::TooManyTransducers(n) => write!(f, "{n} transducers: at most 255"),
            Self::Row { index, line, problem } => {
                write!(f, "row {index}")?;
                if *line > 0 {
                    write!(f, " (line {line})")?;
                }
                write!(f, ": {problem}")
            }
            Self::Encode { topic, problem } => write!(f, "topic {topic}: CDR: {problem}"),
            Self::Mcap(e) => write!(f, "MCAP: {e}"),
        }
    }
}

impl std::error::Error for WriteError {}

// The message definitions as rosbag2 stores them (`ros2msg`: the type's
// fields, then each dependency once in an `MSG:` block), ROS 2 Jazzy's.
const SEPARATOR: &str = "================================================================================\n";
const HEADER_DEFS: &str = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n";
const TIME_DEFS: &str = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
const QUATERNION_DEFS: &str = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";
const VECTOR3_DEFS: &str = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";

/// `sensor_msgs/msg/Range`'s schema.
pub fn range_schema() -> String {
    [
        "uint8 ULTRASOUND=0\nuint8 INFRARED=1\nstd_msgs/Header header\nuint8 radiation_type\nfloat32 field_of_view\n\
         float32 min_range\nfloat32 max_range\nfloat32 range\nfloat32 variance\n",
        HEADER_DEFS,
        TIME_DEFS,
    ]
    .join(SEPARATOR)
}

/// `tf2_msgs/msg/TFMessage`'s schema.
pub fn tf_schema() -> String {
    [
        "geometry_msgs/TransformStamped[] transforms\n",
        "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n\
         geometry_msgs/Transform transform\n",
        HEADER_DEFS,
        TIME_DEFS,
        "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
        VECTOR3_DEFS,
        QUATERNION_DEFS,
    ]
    .join(SEPARATOR)
}

/// `nav_msgs/msg/Odometry`'s schema.
pub fn odometry_schema() -> String {
    [
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n\
         geometry_msgs/TwistWithCovariance twist\n",
        HEADER_DEFS,
        TIME_DEFS,
        "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n",
        "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
        "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n",
        QUATERNION_DEFS,
        "MSG: geometry_msgs/TwistWithCovariance\ngeometry_msgs/Twist twist\nfloat64[36] covariance\n",
        "MSG: geometry_msgs/Twist\ngeometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
        VECTOR3_DEFS,
    ]
    .join(SEPARATOR)
}

/// The RIHS01 type hash (REP 2011) of each type written, Jazzy's, as
/// rosbag2 records it in `type_description_hash`.
pub fn type_hash(ty: &str) -> &'static str {
    match ty {
        types::RANGE => "RIHS01_b42b62562e93cbfe9d42b82fe5994dfa3d63d7d5c90a317981703f7388adff3a",
        types::TF => "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
        types::ODOMETRY => "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
        _ => "",
    }
}

fn schema(ty: &str) -> String {
    match ty {
        types::RANGE => range_schema(),
        types::TF => tf_schema(),
        _ => odometry_schema(),
    }
}

/// A publisher's offered QoS as rosbag2 records it (metadata version 8:
/// a YAML string, policies as rmw's numbers): reliable, history unknown to
/// discovery, durations infinite; durability transient-local (1) or
/// volatile (2). `ros2 bag play` offers it again, so late subscribers get
/// `/tf_static`.
fn offered_qos(transient_local: bool) -> String {
    let durability = if transient_local { 1 } else { 2 };
    let inf = "\n    sec: 9223372036\n    nsec: 854775807";
    format!(
        "- history: 3\n  depth: 0\n  reliability: 1\n  durability: {durability}\n  deadline:{inf}\n  lifespan:{inf}\n  \
         liveliness: 1\n  liveliness_lease_duration:{inf}\n  avoid_ros_namespace_conventions: false"
    )
}

/// A message as rosbag2 stores it ([`msgs::encode`]), its failure named by topic.
fn encode<T: Serialize>(topic: &str, msg: &T) -> Result<Vec<u8>, WriteError> {
    msgs::encode(msg).map_err(|problem| WriteError::Encode { topic: topic.into(), problem })
}

/// The Range limits and field of view as the messages carry them (f32),
/// checked as the reader checks them.
fn limits(o: &WriteOptions) -> Result<(f32, f32, f32), WriteError> {
    let (fov, lo, hi) = (o.field_of_view_rad as f32, o.min_range_m as f32, o.max_range_m as f32);
    if !(fov.is_finite() && fov > 0.0 && f64::from(fov) <= std::f64::consts::TAU) {
        return Err(WriteError::BadOption {
            option: "field_of_view_rad",
            problem: format!("{}: must be within (0, 2π]", o.field_of_view_rad),
        });
    }
    if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo < hi) {
        return Err(WriteError::BadOption {
            option: "min_range_m, max_range_m",
            problem: format!(
                "{} m, {} m: limits must be finite, min ≥ 0 and below max (as f32)",
                o.min_range_m, o.max_range_m
            ),
        });
    }
    if f64::from(hi) * 1000.0 > MAX_RANGE_MM {
        return Err(WriteError::BadOption {
            option: "max_range_m",
            problem: format!("{} m: beyond any sonar ({} m)", o.max_range_m, MAX_RANGE_MM / 1000.0),
        });
    }
    Ok((fov, lo, hi))
}

/// A row's time as a stamp, ns.
fn stamp_ns(t: f64) -> Option<u64> {
    let ns = (t * 1e9).round();
    // The largest stamp: i32::MAX seconds and 999 999 999 ns.
    let max = f64::from(i32::MAX) * 1e9 + 999_999_999.0;
    (t.is_finite() && t >= 0.0 && ns <= max).then_some(ns as u64)
}

/// A topic of the bag.
struct Channel {
    topic: String,
    ty: &'static str,
    transient_local: bool,
    count: usize,
}

/// One message: its channel and receive time (its stamp), and its CDR.
struct Out {
    channel: usize,
    log_time: u64,
    data: Vec<u8>,
}

/// Every message of the bag, encoded, in time order.
struct Plan {
    channels: Vec<Channel>,
    messages: Vec<Out>,
}

impl Plan {
    fn push<T: Serialize>(&mut self, channel: usize, log_time: u64, msg: &T) -> Result<(), WriteError> {
        let data = encode(&self.channels[channel].topic, msg)?;
        self.channels[channel].count += 1;
        self.messages.push(Out { channel, log_time, data });
        Ok(())
    }
}

/// Checks every row and encodes every message.
fn plan(rows: &[Row], ring: &[Mount], o: &WriteOptions) -> Result<Plan, WriteError> {
    let (fov, lo, hi) = limits(o)?;
    if ring.is_empty() {
        return Err(WriteError::EmptyRing);
    }
    if ring.len() > 255 {
        return Err(WriteError::TooManyTransducers(ring.len()));
    }
    if rows.is_empty() {
        return Err(WriteError::NoRows);
    }
    // Every row first: a refusal names the first bad row, and writes nothing.
    let mut stamps = Vec::with_capacity(rows.len());
    for (index, r) in rows.iter().enumerate() {
        let err = |problem| WriteError::Row { index, line: r.line, problem };
        if usize::from(r.transducer) >= ring.len() {
            return Err(err(RowProblem::TransducerBeyondRing { transducer: r.transducer, ring: ring.len() }));
        }
        let ns = stamp_ns(r.time_s).ok_or_else(|| err(RowProblem::BadTime(r.time_s)))?;
        if let Some(&prev) = stamps.last() {
            if ns < prev {
                let previous_s = rows[index - 1].time_s;
                return Err(err(RowProblem::TimeBackwards { time_s: r.time_s, previous_s }));
            }
        }
        if !r.odometry.iter().all(|v| v.is_finite()) {
            return Err(err(RowProblem::NotFinite("odometry")));
        }
        if r.reference.is_some_and(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(err(RowProblem::NotFinite("reference")));
        }
        if let Some(mm) = r.range_mm {
            let v = (f64::from(mm) / 1000.0) as f32;
            if !(v > 0.0 && v >= lo && v <= hi) {
                return Err(err(RowProblem::OutsideLimits {
                    range_mm: mm,
                    min_m: o.min_range_m,
                    max_m: o.max_range_m,
                }));
            }
        }
        stamps.push(ns);
    }
    // Rows sharing a stamp (a whole-ring reading) share its poses.
    for (index, w) in rows.windows(2).enumerate() {
        if stamps[index] == stamps[index + 1] {
            let conflict = |what| WriteError::Row {
                index: index + 1,
                line: w[1].line,
                problem: RowProblem::Conflict { what, time_s: w[1].time_s },
            };
            if w[0].odometry != w[1].odometry {
                return Err(conflict("odometry"));
            }
            if w[0].reference != w[1].reference {
                return Err(conflict("reference"));
            }
        }
    }

    let with_reference = rows.iter().any(|r| r.reference.is_some());
    let channel = |topic: &str, ty, transient_local| Channel { topic: topic.into(), ty, transient_local, count: 0 };
    let mut channels = vec![channel(TF_STATIC_TOPIC, types::TF, true)];
    channels.extend((0..ring.len()).map(|k| channel(&range_topic(k), types::RANGE, false)));
    let odom_ch = channels.len();
    channels.push(channel(ODOM_TOPIC, types::ODOMETRY, false));
    let tf_ch = o.tf.then(|| {
        channels.push(channel(TF_TOPIC, types::TF, false));
        channels.len() - 1
    });
    let reference_ch = with_reference.then(|| {
        channels.push(channel(REFERENCE_TOPIC, types::ODOMETRY, false));
        channels.len() - 1
    });
    let mut p = Plan { channels, messages: Vec::with_capacity(rows.len() * 3 + 1) };

    // The mounts, once, at the first stamp (a static broadcaster's one message).
    let t0 = stamps[0];
    let statics = TfMessage {
        transforms: ring
            .iter()
            .enumerate()
            .map(|(k, m)| transform(t0, BASE_FRAME, &sonar_frame(k), mount_pose(m)))
            .collect(),
    };
    p.push(0, t0, &statics)?;
    for (i, (r, &ns)) in rows.iter().zip(&stamps).enumerate() {
        if i == 0 || stamps[i - 1] != ns {
            p.push(odom_ch, ns, &odometry(ns, ODOM_FRAME, BASE_FRAME, r.odometry))?;
            if let Some(ch) = tf_ch {
                p.push(ch, ns, &TfMessage { transforms: vec![transform(ns, ODOM_FRAME, BASE_FRAME, r.odometry)] })?;
            }
            if let (Some(ch), Some(reference)) = (reference_ch, r.reference) {
                p.push(ch, ns, &odometry(ns, MAP_FRAME, BASE_FRAME, reference))?;
            }
        }
        let k = usize::from(r.transducer);
        let range = RangeMsg {
            header: header(ns, &sonar_frame(k)),
            radiation_type: ULTRASOUND,
            field_of_view: fov,
            min_range: lo,
            max_range: hi,
            // REP 117: +Inf is "no return within the maximum range".
            range: r.range_mm.map_or(f32::INFINITY, |mm| (f64::from(mm) / 1000.0) as f32),
            variance: 0.0,
        };
        p.push(1 + k, ns, &range)?;
    }
    Ok(p)
}

/// rosbag2's `metadata.yaml` (version 8), field for field.
#[derive(Serialize)]
struct MetadataFile<'a> {
    rosbag2_bagfile_information: &'a BagInfo,
}

#[derive(Serialize)]
struct BagInfo {
    version: u32,
    storage_identifier: &'static str,
    duration: Nanoseconds,
    starting_time: SinceEpoch,
    message_count: usize,
    topics_with_message_count: Vec<TopicCount>,
    compression_format: &'static str,
    compression_mode: &'static str,
    relative_file_paths: Vec<String>,
    files: Vec<FileInfo>,
    custom_data: BTreeMap<String, String>,
    ros_distro: &'static str,
}

#[derive(Serialize)]
struct Nanoseconds {
    nanoseconds: u64,
}

#[derive(Serialize)]
struct SinceEpoch {
    nanoseconds_since_epoch: u64,
}

#[derive(Serialize)]
struct TopicCount {
    topic_metadata: TopicMetadata,
    message_count: usize,
}

#[derive(Serialize)]
struct TopicMetadata {
    name: String,
    #[serde(rename = "type")]
    ty: String,
    serialization_format: &'static str,
    offered_qos_profiles: String,
    type_description_hash: &'static str,
}

#[derive(Serialize)]
struct FileInfo {
    path: String,
    starting_time: SinceEpoch,
    duration: Nanoseconds,
    message_count: usize,
}

fn bag_info(p: &Plan, file: &str) -> BagInfo {
    let start = p.messages.iter().map(|m| m.log_time).min().unwrap_or(0);
    let end = p.messages.iter().map(|m| m.log_time).max().unwrap_or(0);
    BagInfo {
        version: 8,
        storage_identifier: "mcap",
        duration: Nanoseconds { nanoseconds: end - start },
        starting_time: SinceEpoch { nanoseconds_since_epoch: start },
        message_count: p.messages.len(),
        topics_with_message_count: p
            .channels
            .iter()
            .map(|c| TopicCount {
                topic_metadata: TopicMetadata {
                    name: c.topic.clone(),
                    ty: c.ty.into(),
                    serialization_format: "cdr",
                    offered_qos_profiles: offered_qos(c.transient_local),
                    type_description_hash: type_hash(c.ty),
                },
                message_count: c.count,
            })
            .collect(),
        compression_format: "",
        compression_mode: "",
        relative_file_paths: vec![file.into()],
        files: vec![FileInfo {
            path: file.into(),
            starting_time: SinceEpoch { nanoseconds_since_epoch: start },
            duration: Nanoseconds { nanoseconds: end - start },
            message_count: p.messages.len(),
        }],
        custom_data: BTreeMap::from([("written_by".into(), format!("echoloc-lab {}", env!("CARGO_PKG_VERSION")))]),
        ros_distro: "jazzy",
    }
}

/// Checks that a bag can be written at `dir`: it does not exist, its parent
/// does, its name is UTF-8 (it names the MCAP file). Returns the name.
pub fn check_new_dir(dir: &Path) -> Result<String, WriteError> {
    let bad = |problem: &str| WriteError::BadPath { path: dir.into(), problem: problem.into() };
    if dir.symlink_metadata().is_ok() {
        return Err(WriteError::Exists(dir.into()));
    }
    let name = dir.file_name().ok_or_else(|| bad("no directory name"))?;
    let name = name.to_str().ok_or_else(|| bad("the name is not UTF-8 (it names the MCAP file)"))?;
    let parent = dir.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(bad(&format!("folder {} does not exist", parent.display())));
    }
    Ok(name.to_string())
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> WriteError + '_ {
    move |e| WriteError::Io { path: path.into(), problem: e.to_string() }
}

fn mcap_err(e: mcap::McapError) -> WriteError {
    WriteError::Mcap(e.to_string())
}

/// Writes the MCAP file and `metadata.yaml` of `p` into `dir`.
fn write_files(dir: &Path, file: &str, p: &Plan, o: &WriteOptions) -> Result<(), WriteError> {
    let info = bag_info(p, file);
    let yaml_err = |e: serde_norway::Error| WriteError::Mcap(format!("metadata: {e}"));
    let metadata = serde_norway::to_string(&MetadataFile { rosbag2_bagfile_information: &info }).map_err(yaml_err)?;
    let serialized = serde_norway::to_string(&info).map_err(yaml_err)?;

    let path = dir.join(file);
    let f = std::fs::File::create_new(&path).map_err(io(&path))?;
    let compression = match o.compression {
        Compression::None => None,
        Compression::Zstd => Some(mcap::Compression::Zstd),
    };
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .library(format!("echoloc-lab {}", env!("CARGO_PKG_VERSION")))
        .compression(compression)
        .create(BufWriter::new(f))
        .map_err(mcap_err)?;
    let mut schemas: BTreeMap<&str, u16> = BTreeMap::new();
    let mut ids = Vec::with_capacity(p.channels.len());
    for c in &p.channels {
        let schema_id = match schemas.get(c.ty) {
            Some(&id) => id,
            None => {
                let id = w.add_schema(c.ty, "ros2msg", schema(c.ty).as_bytes()).map_err(mcap_err)?;
                schemas.insert(c.ty, id);
                id
            }
        };
        let meta = BTreeMap::from([
            ("offered_qos_profiles".to_string(), offered_qos(c.transient_local)),
            ("topic_type_hash".to_string(), type_hash(c.ty).to_string()),
        ]);
        ids.push(w.add_channel(schema_id, &c.topic, "cdr", &meta).map_err(mcap_err)?);
    }
    let mut sequence = vec![0u32; p.channels.len()];
    for m in &p.messages {
        sequence[m.channel] += 1;
        let h = mcap::records::MessageHeader {
            channel_id: ids[m.channel],
            sequence: sequence[m.channel],
            log_time: m.log_time,
            publish_time: m.log_time,
        };
        w.write_to_known_channel(&h, &m.data).map_err(mcap_err)?;
    }
    // rosbag2's MCAP plugin keeps the bag's metadata in the file too.
    let record = mcap::records::Metadata {
        name: "rosbag2".into(),
        metadata: BTreeMap::from([("serialized_metadata".to_string(), serialized)]),
    };
    w.write_metadata(&record).map_err(mcap_err)?;
    w.finish().map_err(mcap_err)?;
    let f = w.into_inner().into_inner().map_err(|e| WriteError::Io { path: path.clone(), problem: e.to_string() })?;
    f.sync_all().map_err(io(&path))?;

    let meta_path = dir.join("metadata.yaml");
    let mut m = std::fs::File::create_new(&meta_path).map_err(io(&meta_path))?;
    m.write_all(metadata.as_bytes()).and_then(|()| m.sync_all()).map_err(io(&meta_path))?;
    Ok(())
}

/// Writes `rows` of a run on `ring` as a rosbag2 directory `dir` (which
/// must not exist; its parent must): `metadata.yaml` and `<name>_0.mcap`.
/// Every row is checked first; the bag is written into a hidden sibling
/// and renamed into place, so on any error nothing is left.
///
/// Rows of one time (a whole-ring reading) share the Odometry messages of
/// that stamp, and must share their poses. A transducer with no row has
/// its topic and its mount but no Range message: a reader that builds the
/// ring from the Range frames (echoloc's) leaves it out, and the indices
/// close up.
pub fn write_bag(dir: &Path, rows: &[Row], ring: &[Mount], opt: &WriteOptions) -> Result<Written, WriteError> {
    let name = check_new_dir(dir)?;
    let plan = plan(rows, ring, opt)?;
    let parent = dir.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
    std::fs::create_dir(&tmp).map_err(io(&tmp))?;
    let file = format!("{name}_0.mcap");
    let done = write_files(&tmp, &file, &plan, opt).and_then(|()| {
        // Created meanwhile? rename() would replace an empty directory.
        if dir.symlink_metadata().is_ok() {
            return Err(WriteError::Exists(dir.into()));
        }
        std::fs::rename(&tmp, dir).map_err(io(dir))
    });
    if let Err(e) = done {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    Ok(Written {
        dir: dir.into(),
        mcap: dir.join(&file),
        topics: plan.channels.iter().map(|c| (c.topic.clone(), c.ty.to_string(), c.count)).collect(),
        messages: plan.messages.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::msgs::{stamp, Time};

    /// A Range laid out by hand from the CDR rules, as the reader's test
    /// does, with Jazzy's `variance` after `range`.
    #[test]
    fn range_by_hand() {
        let m = RangeMsg {
            header: header(7_500_000_000, "sonar_3"),
            radiation_type: ULTRASOUND,
            field_of_view: 0.5,
            min_range: 0.1,
            max_range: 5.0,
            range: f32::INFINITY,
            variance: 0.0,
        };
        let mut b = vec![0, 1, 0, 0];
        b.extend(7i32.to_le_bytes());
        b.extend(500_000_000u32.to_le_bytes());
        b.extend(8u32.to_le_bytes());
        b.extend(b"sonar_3\0");
        b.push(0); // radiation_type, body offset 20
        b.extend([0, 0, 0]); // pad to 24
        for v in [0.5f32, 0.1, 5.0, f32::INFINITY, 0.0] {
            b.extend(v.to_le_bytes());
        }
        assert_eq!(encode("/sonar/3", &m).unwrap(), b);
    }

    /// An Odometry: the covariances are 36 doubles with no length, and the
    /// reader's partial Odometry decodes the pose.
    #[test]
    fn odometry_layout() {
        let o = odometry(1_000_000_001, "odom", "base_link", [1.5, -2.0, 0.3]);
        let b = encode("/odom", &o).unwrap();
        // header 4+4+(4+5) = 17 → child "base_link" at 20: 4+10 = 34 → pose at 40:
        // 7 doubles, 36 doubles, twist 6 doubles, 36 doubles.
        assert_eq!(b.len(), 4 + 40 + 8 * (7 + 36 + 6 + 36));
        let back: super::super::msgs::Odometry = super::super::msgs::decode(&b).unwrap();
        assert_eq!((back.pose.position.x, back.pose.position.y), (1.5, -2.0));
        assert!((back.pose.orientation.yaw().unwrap() - 0.3).abs() < 1e-15);
        assert_eq!(back.header.stamp, Time { sec: 1, nanosec: 1 });
    }

    /// Every range a log may hold comes back to the millimetre through the
    /// f32 metres of a Range.
    #[test]
    fn millimetres_survive_f32_metres() {
        for mm in 1..=MAX_RANGE_MM as u32 {
            let v = (f64::from(mm) / 1000.0) as f32;
            assert_eq!((f64::from(v) * 1000.0).round() as u32, mm);
        }
    }

    #[test]
    fn stamps() {
        assert_eq!(stamp_ns(0.037402), Some(37_402_000));
        assert_eq!(stamp(37_402_000), Time { sec: 0, nanosec: 37_402_000 });
        assert_eq!(stamp_ns(-1e-3), None);
        assert_eq!(stamp_ns(f64::NAN), None);
        assert_eq!(stamp_ns(3e9), None, "past 2038");
        assert!(stamp_ns(f64::from(i32::MAX)).is_some());
    }

    #[test]
    fn qos_is_the_yaml_rosbag2_records() {
        let q = offered_qos(true);
        assert!(q.starts_with("- history: 3\n  depth: 0\n  reliability: 1\n  durability: 1\n  deadline:\n"), "{q}");
        assert!(q.ends_with("avoid_ros_namespace_conventions: false"));
        assert!(offered_qos(false).contains("durability: 2\n"));
    }
}
