//! The command line's side of bags: the options `replay --bag` and
//! `log --from-bag` share, and `echoloc-lab log`.

use std::path::PathBuf;

use clap::Args;
use serde_json::{json, Value};

use super::{read, Bag, CloudTiming, Options, RingStamp};
use crate::error::LabError;
use crate::files::{check_writable, write_all};

/// Which topics of a bag to read (each found by type when not named).
#[derive(Args, Clone, Debug, Default)]
pub struct BagTopics {
    /// Range topics (sensor_msgs/msg/Range, repeat or comma-separate), or one
    /// PointCloud topic; default: every Range topic, else the PointCloud.
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    pub ranges: Vec<String>,
    /// The odometry topic (nav_msgs/msg/Odometry); default: the one named
    /// odom, else /tf odom -> base_link.
    #[arg(long)]
    pub odom: Option<String>,
    /// The reference topic (geometry_msgs/msg/PoseWithCovarianceStamped or
    /// a ground truth's nav_msgs/msg/Odometry); default: /amcl_pose, else a
    /// topic named ground truth, else none.
    #[arg(long)]
    pub reference: Option<String>,
    /// The robot's frame, whose transforms to the sonar frames /tf_static gives.
    #[arg(long = "base-frame", default_value = "base_link")]
    pub base_frame: String,
    /// The odometry's frame, for odometry from /tf.
    #[arg(long = "odom-frame", default_value = "odom")]
    pub odom_frame: String,
    /// A whole-ring PointCloud's ring cycle, s: its points' firing times
    /// are rebuilt from it and the ring's firing order (the --ring file's
    /// `order`; the Pioneer's two arrays at once, 0–7, by default). Default:
    /// the --ring file's `period_s`, else RosAria's Pioneer, 0.32 s (ARCOS'
    /// 40 ms SonarCycle, 8 slots).
    #[arg(long = "ring-period")]
    pub ring_period_s: Option<f64>,
    /// What a whole-ring PointCloud's stamp marks: the ring's end (RosAria:
    /// stamped when published, after the newest reading), its start, or
    /// every point at the stamp (one instant: no rebuilding).
    #[arg(long = "ring-stamp", value_enum, default_value = "end")]
    pub ring_stamp: CloudStamp,
}

/// What a whole-ring message's stamp marks, on the command line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum CloudStamp {
    /// The ring's end.
    #[default]
    End,
    /// Its first firing.
    Start,
    /// Every point at the stamp.
    OneInstant,
}

impl BagTopics {
    /// The reader's options, with the ring when one was given.
    pub fn options(&self, ring: Option<Vec<echoloc::predict::Mount>>) -> Options {
        Options {
            ranges: self.ranges.clone(),
            odom: self.odom.clone(),
            reference: self.reference.clone(),
            ring,
            base_frame: self.base_frame.clone(),
            odom_frame: self.odom_frame.clone(),
            ..Options::default()
        }
    }

    /// When a whole-ring PointCloud's points fired, on a ring of `n` that
    /// fires as `firing` says.
    pub fn cloud_timing(&self, firing: &crate::ring::Firing, n: usize) -> Result<CloudTiming, LabError> {
        let stamp = match self.ring_stamp {
            CloudStamp::OneInstant => return Ok(CloudTiming::AtStamp),
            CloudStamp::End => RingStamp::End,
            CloudStamp::Start => RingStamp::Start,
        };
        let pioneer = n == 16 && firing.order.is_none();
        let order = match &firing.order {
            Some(o) => o.clone(),
            None if pioneer => super::pioneer_order(),
            None => (0..n).map(|k| vec![k as u8]).collect(),
        };
        let period_s = match (self.ring_period_s, firing.period_s) {
            (Some(p), _) | (None, Some(p)) => p,
            (None, None) if pioneer => super::PIONEER_RING_PERIOD_NS as f64 / 1e9,
            (None, None) => return Ok(CloudTiming::AtStamp),
        };
        if !(period_s.is_finite() && period_s > 0.0 && period_s <= 60.0) {
            return Err(LabError(format!("--ring-period {period_s}: a ring cycle is more than 0 and at most 60 s")));
        }
        let slot_ns = firing.slot_s.map(|s| (s * 1e9).round() as i64);
        CloudTiming::rebuilt(&order, n, (period_s * 1e9).round() as i64, slot_ns, stamp)
            .map_err(|e| LabError(format!("--ring: {e}")))
    }
}

/// Reads a bag for the command line: errors name the bag; the topics used
/// are printed on stderr.
pub fn load(path: &std::path::Path, topics: &BagTopics, ring: Option<&str>) -> Result<Bag, LabError> {
    let firing = ring.map(crate::ring::firing).transpose()?.unwrap_or_default();
    let ring = ring.map(crate::ring::ring_mounts).transpose()?;
    let n = ring.as_ref().map_or(echoloc::predict::PIONEER16.len(), Vec::len);
    let mut o = topics.options(ring);
    o.cloud_timing = topics.cloud_timing(&firing, n)?;
    let bag = read(path, &o).map_err(|e| LabError(format!("{}: {e}", path.display())))?;
    eprintln!("{}", used_line(&bag));
    Ok(bag)
}

fn used_line(bag: &Bag) -> String {
    let u = &bag.used;
    format!(
        "bag: ranges {} ({}), ring from {}, odometry {}, reference {}",
        u.ranges.join(" "),
        u.ranges_type,
        u.ring,
        u.odometry,
        u.reference.as_deref().unwrap_or("none")
    )
}

/// What a bag was read as, for the JSON reports.
pub fn summary(bag: &Bag) -> Value {
    let u = &bag.used;
    json!({
        "topics": {
            "ranges": u.ranges,
            "ranges_type": u.ranges_type,
            "odometry": u.odometry,
            "reference": u.reference,
            "ring": u.ring,
            "cloud_timing": u.cloud_timing,
        },
        "transducers": bag.transducers.iter().map(|t| json!({
            "index": t.index,
            "frame": t.frame,
            "mount": [f64::from(t.mount.x_mm) / 1000.0, f64::from(t.mount.y_mm) / 1000.0, f64::from(t.mount.heading_mdeg) / 1000.0],
        })).collect::<Vec<_>>(),
        "readings": bag.rows.len(),
        "outside_odometry": bag.outside_odometry,
        "no_echo": {
            "infinite": bag.no_echo.infinite,
            "too_close": bag.no_echo.too_close,
            "beyond_max_range": bag.no_echo.beyond_max,
            "below_min_range": bag.no_echo.below_min,
        },
    })
}

/// The ring as the ring file's JSON (`[x_m, y_m, heading_deg]` per transducer).
pub fn ring_json(ring: &[echoloc::predict::Mount]) -> String {
    let v: Vec<[f64; 3]> = ring
        .iter()
        .map(|m| [f64::from(m.x_mm) / 1000.0, f64::from(m.y_mm) / 1000.0, f64::from(m.heading_mdeg) / 1000.0])
        .collect();
    serde_json::to_string(&v).unwrap_or_default() + "\n"
}

/// `log`.
#[derive(Args)]
pub struct LogArgs {
    /// The ROS 2 bag: a rosbag2 directory (metadata.yaml) or an .mcap file.
    #[arg(long = "from-bag", required_unless_present = "to_bag", conflicts_with = "to_bag")]
    pub from_bag: Option<PathBuf>,
    /// The other way: a plain log (CSV, docs/log.md) written as a ROS 2 bag
    /// (a new rosbag2 directory, -o), Range topics, /tf_static, /odom and the
    /// reference as /ground_truth (docs/bags.md, "ROS 2 bags out").
    #[arg(long = "to-bag", conflicts_with_all = ["ring_out", "ranges", "odom", "reference"])]
    pub to_bag: Option<PathBuf>,
    /// Where to write the log (CSV, docs/log.md); with --to-bag, the bag
    /// directory (it must not exist).
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Also write the ring the log's transducer indices refer to, as a ring
    /// file (`--ring` of replay and scenario).
    #[arg(long = "ring-out")]
    pub ring_out: Option<PathBuf>,
    /// The ring, when the bag has no /tf_static for its sonar frames
    /// (pioneer16 or a JSON file); a PointCloud's default is pioneer16.
    /// With --to-bag: the log's ring, default pioneer16.
    #[arg(long)]
    pub ring: Option<String>,
    /// With --to-bag: the Range messages' min_range, m.
    #[arg(long = "min-range-m", requires = "to_bag", default_value_t = super::write::POLAROID_MIN_RANGE_M)]
    pub min_range_m: f64,
    /// With --to-bag: the Range messages' max_range, m.
    #[arg(long = "max-range-m", requires = "to_bag", default_value_t = super::write::POLAROID_MAX_RANGE_M)]
    pub max_range_m: f64,
    /// With --to-bag: zstd-compressed MCAP chunks.
    #[arg(long, requires = "to_bag")]
    pub zstd: bool,
    #[command(flatten)]
    pub topics: BagTopics,
}

/// `echoloc-lab log --from-bag`: the bag as a plain log; `--to-bag`: a log
/// as a bag. Prints a JSON summary.
pub fn log_cmd(a: &LogArgs) -> Result<String, LabError> {
    let from_bag = match (&a.from_bag, &a.to_bag) {
        (Some(bag), None) => bag,
        (None, Some(log)) => return to_bag_cmd(a, log),
        _ => return Err(LabError("log: give --from-bag BAG or --to-bag LOG".into())),
    };
    check_writable(&a.out)?;
    if let Some(p) = &a.ring_out {
        check_writable(p)?;
    }
    let bag = load(from_bag, &a.topics, a.ring.as_deref())?;
    let mut outputs = vec![(a.out.clone(), crate::log::write(&bag.rows, bag.has_reference()).into_bytes())];
    if let Some(p) = &a.ring_out {
        outputs.push((p.clone(), ring_json(&bag.ring).into_bytes()));
    }
    write_all(&outputs)?;
    let log = crate::log::Log { rows: bag.rows.clone() };
    let cycles = crate::log::cycles(&log.rows).len();
    let mut v = summary(&bag);
    if let Some(o) = v.as_object_mut() {
        o.insert(
            "log".into(),
            json!({
                "path": a.out.display().to_string(),
                "rows": log.rows.len(),
                "reference_rows": log.rows.iter().filter(|r| r.reference.is_some()).count(),
                "cycles": cycles,
            }),
        );
    }
    Ok(serde_json::to_string_pretty(&v).unwrap_or_default())
}

/// `echoloc-lab log --to-bag LOG -o DIR`: the log on its ring as a rosbag2 bag.
fn to_bag_cmd(a: &LogArgs, log_path: &std::path::Path) -> Result<String, LabError> {
    use super::write::{check_new_dir, write_bag, Compression, WriteOptions};
    let out_err = |e: super::write::WriteError| LabError(format!("-o {}: {e}", a.out.display()));
    // Before reading the log: a bag is never written over another.
    check_new_dir(&a.out).map_err(out_err)?;
    let ring_spec = a.ring.as_deref().unwrap_or("pioneer16");
    let ring = crate::ring::ring_mounts(ring_spec)?;
    let log = crate::log::read_file(log_path, ring.len())?;
    let opt = WriteOptions {
        min_range_m: a.min_range_m,
        max_range_m: a.max_range_m,
        compression: if a.zstd { Compression::Zstd } else { Compression::None },
        ..WriteOptions::default()
    };
    let w = write_bag(&a.out, &log.rows, &ring, &opt)
        .map_err(|e| LabError(format!("{} -> {}: {e}", log_path.display(), a.out.display())))?;
    let topics: serde_json::Map<String, Value> =
        w.topics.iter().map(|(name, ty, n)| (name.clone(), json!({"type": ty, "messages": n}))).collect();
    Ok(serde_json::to_string_pretty(&json!({
        "bag": w.dir.display().to_string(),
        "mcap": w.mcap.display().to_string(),
        "rows": log.rows.len(),
        "ring": {"spec": ring_spec, "transducers": ring.len()},
        "messages": w.messages,
        "topics": topics,
    }))
    .unwrap_or_default())
}
