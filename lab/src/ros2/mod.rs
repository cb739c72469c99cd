//! `link --ros2`: the host link as a ROS 2 node that can stand where nav2's
//! amcl stands (docs/ros2.md), with no ROS installed: the controller's pose
//! on `/amcl_pose`, `map → odom` on `/tf`, each transducer's
//! `sensor_msgs/Range`, the mode on `/diagnostics`; `/initialpose` and
//! `reinitialize_global_localization` turned into the link's `SetPose` and
//! `Search`.
//!
//! - [`msgs`]: the messages beyond a bag's, and the distribution's layouts;
//! - [`bridge`]: the link's messages to those (no DDS: tested alone);
//! - [`odom`]: `/odom` in, its stamps mapped back onto the controller's clock (no DDS);
//! - [`node`]: the DDS node (ros2-client on RustDDS);
//! - [`replay`]: `replay --ros2`, a replayed run published as the link would, with its particles.

pub mod bridge;
pub mod msgs;
pub mod node;
pub mod odom;
pub mod replay;

use clap::{Args, ValueEnum};

pub use msgs::Distro;

/// How ROS 2 services map onto DDS: it depends on the robot's middleware.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ServiceMappingArg {
    /// Fast DDS (`rmw_fastrtps_cpp`, the default of Humble and Jazzy): the
    /// request id in the sample's identity.
    Enhanced,
    /// Cyclone DDS (`rmw_cyclonedds_cpp`): the request id before the request.
    Cyclone,
    /// RPC over DDS's basic mapping (Connext, untested).
    Basic,
}

/// The `--ros2` options of `link`.
#[derive(Args, Clone, Debug)]
pub struct Ros2Args {
    /// Be a ROS 2 node beside the link (docs/ros2.md): /amcl_pose, /tf map → odom, /tf_static,
    /// /sonar_K (K the transducer), /diagnostics; takes /initialpose and /reinitialize_global_localization.
    /// The domain comes from ROS_DOMAIN_ID.
    #[arg(long)]
    pub ros2: bool,
    /// Keep discovery and data on 127.0.0.1 (tests; a robot's LAN wants ordinary discovery).
    #[arg(long = "ros2-localhost", requires = "ros2")]
    pub ros2_localhost: bool,
    /// The node's name.
    #[arg(long = "ros2-node-name", default_value = "echoloc", requires = "ros2")]
    pub ros2_node_name: String,
    /// The node's namespace.
    #[arg(long = "ros2-namespace", default_value = "/", requires = "ros2")]
    pub ros2_namespace: String,
    /// The distribution whose message layouts go on the wire (sensor_msgs/Range's variance).
    #[arg(long = "ros-distro", value_enum, default_value = "jazzy", requires = "ros2")]
    pub ros_distro: Distro,
    /// The pose's topic.
    #[arg(long = "ros2-pose-topic", default_value = "/amcl_pose", requires = "ros2")]
    pub ros2_pose_topic: String,
    /// The robot's middleware, for the service (enhanced: Fast DDS; cyclone: Cyclone DDS).
    #[arg(long = "ros2-service-mapping", value_enum, default_value = "enhanced", requires = "ros2")]
    pub ros2_service_mapping: ServiceMappingArg,
    /// An /initialpose whose σ of x or y exceeds this (m) makes the controller search around it
    /// rather than track from it (rviz's 2D Pose Estimate sends 0.5).
    #[arg(long = "ros2-wide-m", default_value_t = 1.0, requires = "ros2")]
    pub ros2_wide_m: f64,
    /// Likewise for the σ of yaw, rad (rviz sends 0.26).
    #[arg(long = "ros2-wide-rad", default_value_t = 0.5, requires = "ros2")]
    pub ros2_wide_rad: f64,
    /// Before the run, wait up to this many seconds for a subscriber on every topic published per
    /// reading (tests; a robot does not wait).
    #[arg(long = "ros2-wait-s", default_value_t = 0.0, requires = "ros2")]
    pub ros2_wait_s: f64,
    /// Take the odometry from the robot's /odom (nav_msgs/Odometry, reliable) instead of --scenario's
    /// or stdin's; its stamps are mapped onto the controller's clock through the Hello (docs/ros2.md).
    #[arg(long = "ros2-odom", requires = "ros2")]
    pub ros2_odom: bool,
    /// The odometry's topic.
    #[arg(long = "ros2-odom-topic", default_value = "/odom", requires = "ros2_odom")]
    pub ros2_odom_topic: String,
    /// The robot's base frame: the mounts' parent on /tf_static and /odom's child (TurtleBots: base_footprint).
    #[arg(long = "ros2-base-frame", default_value = "base_link", requires = "ros2")]
    pub ros2_base_frame: String,
    /// Seconds the node stays up after the run, so reliable readers get the last samples.
    #[arg(long = "ros2-linger-s", default_value_t = 1.0, requires = "ros2")]
    pub ros2_linger_s: f64,
}

impl Ros2Args {
    /// The thresholds of a wide `/initialpose`: [m, rad].
    pub fn wide(&self) -> [f64; 2] {
        [self.ros2_wide_m, self.ros2_wide_rad]
    }
}
