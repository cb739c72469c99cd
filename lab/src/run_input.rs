//! A robot's recorded run as a command's input, the arguments `replay` and
//! `board` share: the map it was recorded on, the run as a log or a ROS 2
//! bag (with its topics), the ring, where it starts, and how the map is
//! read.

use std::path::PathBuf;

use clap::Args;
use echoloc::predict::Mount;

use crate::bag::Bag;
use crate::error::LabError;
use crate::log::Log;
use crate::map::load::{GridArgs, LoadedMap};
use crate::predict::ring_mounts;

/// The run and its map.
#[derive(Args, Clone, Debug)]
pub struct RunInput {
    /// The map the run was recorded on: a compiled map (.map), a ROS
    /// map_server .yaml or a .geojson.
    #[arg(long)]
    pub map: PathBuf,
    /// The run as a log: CSV, one row per reading (docs/log.md).
    #[arg(long, required_unless_present = "bag", conflicts_with = "bag")]
    pub log: Option<PathBuf>,
    /// The run as a ROS 2 bag: a rosbag2 directory (metadata.yaml) or an
    /// .mcap file (docs/bags.md).
    #[arg(long)]
    pub bag: Option<PathBuf>,
    /// The bag's topics (with --bag).
    #[command(flatten)]
    pub topics: crate::bag::cli::BagTopics,
    /// The ring: pioneer16, or a JSON file of [x_m, y_m, heading_deg] per
    /// transducer (default pioneer16; with --bag, the bag's /tf_static).
    #[arg(long)]
    pub ring: Option<String>,
    /// Where the robot starts in the map: x_m,y_m,θ_deg (tracked from
    /// there); `replay` also takes x_m,y_m,θ_deg,σ_m,σ_deg (searched around
    /// there) and `unknown` (searched for over the whole map). Default: the
    /// first reference pose, else the first odometry pose, tracked.
    #[arg(long = "initial-pose", allow_hyphen_values = true)]
    pub initial_pose: Option<String>,
    /// C-space buffer for a .yaml or .geojson map, mm.
    #[arg(long = "buffer-mm", default_value_t = 100)]
    pub buffer_mm: u32,
    /// How a .yaml map's walls are drawn.
    #[command(flatten)]
    pub grid: GridArgs,
}

/// The run, read.
pub struct Run {
    /// The ring's mounts.
    pub mounts: Vec<Mount>,
    /// The readings as log rows.
    pub log: Log,
    /// The file or directory it came from, for messages.
    pub source: PathBuf,
    /// The bag, when it came from one.
    pub bag: Option<Bag>,
}

impl RunInput {
    /// Reads the log or the bag, and its ring.
    pub fn read_run(&self) -> Result<Run, LabError> {
        match (&self.log, &self.bag) {
            (_, Some(b)) => {
                let bag = crate::bag::cli::load(b, &self.topics, self.ring.as_deref())?;
                Ok(Run {
                    mounts: bag.ring.clone(),
                    log: Log { rows: bag.rows.clone() },
                    source: b.clone(),
                    bag: Some(bag),
                })
            }
            (Some(l), None) => {
                let mounts = ring_mounts(self.ring.as_deref().unwrap_or("pioneer16"))?;
                let log = crate::log::read_file(l, mounts.len())?;
                Ok(Run { mounts, log, source: l.clone(), bag: None })
            }
            (None, None) => Err(LabError("give --log or --bag".into())),
        }
    }

    /// Loads the map, compiled and read in place.
    pub fn load_map(&self) -> Result<LoadedMap, LabError> {
        crate::map::load::load(&self.map, &self.grid.options(self.buffer_mm, true))
    }
}
