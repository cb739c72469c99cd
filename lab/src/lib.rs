//! # echoloc-lab
//!
//! The host side of echoloc as a Rust library: everything the
//! `echoloc-lab` command line does, callable from a robot's own tools and
//! build scripts. The command line (`src/main.rs`) is a thin shell over it.
//!
//! | module | what it does |
//! |---|---|
//! | [`map`] | import ROS map_server grids ([`map::ros`]) and GeoJSON ([`map::geojson`]) into convex, buffered polygons; compile the firmware's map blob ([`map::import`], [`map::build_map`]); inspect, export, preview |
//! | [`ring`] | rings: `pioneer16` or a JSON file of transducer mounts |
//! | [`lidar`] | a lidar robot's run in (CARMEN logs, ROS 2 bags with `LaserScan`), and the occupancy grid a SLAM user would make of it |
//! | [`from_scans`] | a sonar run on real geometry: the ring's readings derived from a lidar run's scans, the ladder (`simulate --from-scans`) |
//! | [`bag`] | ROS 2 bags (rosbag2 MCAP) read as a log, and a log written as one (`bag::write`): ranges, the ring from `/tf_static`, odometry, a reference (`docs/bags.md`) |
//! | [`log`] | the plain CSV log a robot's logger writes (`docs/log.md`): read with line-numbered errors, write |
//! | [`replay`] | a log through prediction, verdicts, the threshold method and the EKF; `echoloc-lab replay` |
//! | [`scenario`] | binary scenarios for the boards (`docs/scenario.md`): replay on the host, convert a log |
//! | [`simulate`] | the independent physical simulator and the filters' run (`echoloc-lab simulate`) |
//! | [`predict`] | windows and ring predictions from the command line |
//! | [`credence`] | the credence net's data, training and quantisation |
//! | [`bench`](mod@bench) | echoloc against ray fans on grids and polygons |
//! | [`board`] | a log or bag on the emulated board end to end: map compiled, scenario converted, QEMU run, figures beside the host's |
//! | [`link`] | the host link to a controller |
//! | [`foxglove`] | a run as a Foxglove recording (MCAP, well-known Foxglove schemas; `docs/foxglove.md`) |
//! | [`figure`] | every figure, drawn with `plotters` as PNG or SVG in the shipped DejaVu Sans |
//!
//! Compile a robot's ROS map into the blob the firmware reads (a `build.rs`
//! can do this; `examples/map-at-build-time` does), then predict a ring and
//! judge readings against the predictions:
//!
//! ```no_run
//! use echoloc::credence::net::CredenceNet;
//! use echoloc::map::{MapSource, MapView};
//! use echoloc::predict::{predict_ring, Pose};
//! use echoloc::referencing::{judge, Reading, VerdictConfig};
//! use echoloc_lab::map::{import, AlignedBytes, ImportOptions};
//! use echoloc_lab::simulate::filters::predict_params;
//!
//! let (blob, _, _) = import("robot/map.yaml".as_ref(), 100, 1000, &ImportOptions::default())?;
//! let bytes = AlignedBytes::new(&blob);
//! let map = MapView::new(bytes.bytes()).map_err(|e| format!("{e:?}"))?;
//! let ring = echoloc_lab::ring::load("pioneer16")?;
//! let pose = Pose { x_mm: 2000.0, y_mm: 1500.0, heading_rad: 0.3 };
//! let mut predicted = vec![None; ring.len()];
//! predict_ring(&map, &pose, &ring, &predict_params(map.buffer_mm(), map.field()), &CredenceNet::shipped(), &mut predicted)
//!     .map_err(|e| e.to_string())?;
//! let verdict = judge(Reading::Echo { range_mm: 1234 }, predicted[0].as_ref(), &VerdictConfig::POLAROID);
//! println!("{verdict:?}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Cargo features: `tool` (default) is the whole command line; without it
//! (`default-features = false`) the library is the input readers (maps,
//! logs, bags, lidar runs), prediction, rings and the credence net, without
//! the simulator, the boards, the link, replay, Foxglove and the benchmarks
//! or their dependencies (the fuzz targets build it so).
//!
//! The small host program `examples/verdicts.rs` does this from the command
//! line: `cargo run -p echoloc-lab --example verdicts -- MAP x,y,θ R0,R1,…`.

pub mod angle;
pub mod bag;
#[cfg(feature = "tool")]
pub mod bench;
#[cfg(feature = "tool")]
pub mod board;
pub mod clock;
pub mod credence;
pub mod error;
pub mod figure;
pub mod files;
#[cfg(feature = "tool")]
pub mod foxglove;
#[cfg(feature = "tool")]
pub mod from_scans;
pub mod lidar;
#[cfg(feature = "tool")]
pub mod link;
pub mod log;
pub mod map;
pub mod predict;
#[cfg(feature = "tool")]
pub mod replay;
pub mod ring;
#[cfg(feature = "tool")]
pub mod ros2;
pub mod run_input;
#[cfg(feature = "tool")]
pub mod scenario;
#[cfg(feature = "tool")]
pub mod simulate;
#[cfg(feature = "tool")]
pub mod simulate_cmd;

pub use error::LabError;
