//! The command line's side of bags: the options `replay --bag` and
//! `log --from-bag` share, and `echoloc-lab log`.

use std::path::PathBuf;

use clap::Args;
use serde_json::{json, Value};

use super::{read, Bag, Options};
use crate::map::LabError;
use crate::simulate::{check_writable, write_all};

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
}

/// Reads a bag for the command line: errors name the bag; the topics used
/// are printed on stderr.
pub fn load(path: &std::path::Path, topics: &BagTopics, ring: Option<&str>) -> Result<Bag, LabError> {
    let ring = ring.map(crate::predict::ring_mounts).transpose()?;
    let bag = read(path, &topics.options(ring)).map_err(|e| LabError(format!("{}: {e}", path.display())))?;
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
    #[arg(long = "from-bag")]
    pub from_bag: PathBuf,
    /// Where to write the log (CSV, docs/log.md).
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Also write the ring the log's transducer indices refer to, as a ring
    /// file (`--ring` of replay and scenario).
    #[arg(long = "ring-out")]
    pub ring_out: Option<PathBuf>,
    /// The ring, when the bag has no /tf_static for its sonar frames
    /// (pioneer16 or a JSON file); a PointCloud's default is pioneer16.
    #[arg(long)]
    pub ring: Option<String>,
    #[command(flatten)]
    pub topics: BagTopics,
}

/// `echoloc-lab log --from-bag`: the bag as a plain log; prints a JSON summary.
pub fn log_cmd(a: &LogArgs) -> Result<String, LabError> {
    check_writable(&a.out)?;
    if let Some(p) = &a.ring_out {
        check_writable(p)?;
    }
    let bag = load(&a.from_bag, &a.topics, a.ring.as_deref())?;
    let mut outputs = vec![(a.out.clone(), crate::log::write(&bag.rows, bag.has_reference()).into_bytes())];
    if let Some(p) = &a.ring_out {
        outputs.push((p.clone(), ring_json(&bag.ring).into_bytes()));
    }
    write_all(&outputs)?;
    let log = crate::log::Log { rows: bag.rows.clone() };
    let cycles = crate::replay::cycles(&log.rows).len();
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
