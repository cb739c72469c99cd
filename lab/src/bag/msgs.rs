//! The ROS 2 messages a sonar or lidar bag carries, as far as echoloc reads them,
//! and those it writes (into bags, and as the ROS 2 node of `link --ros2`),
//! decoded from and encoded to CDR (the `cdr` message encoding of rosbag2) by the
//! `cdr-encoding` crate over serde.
//!
//! Each type is the message's leading fields in their `.msg` order (CDR has
//! no field names: order and alignment are the format). A message is read up
//! to the last field echoloc needs; what follows (an Odometry's covariance
//! and twist, the `variance` that Range gained in ROS 2 Iron) is left unread,
//! so every distribution's layout of these types decodes.
//!
//! The types that are whole messages as they stand (`Time`, `Header`, `Pose`,
//! `Transform`, `TfMessage`, …) also serialize: [`super::write`] encodes
//! them, inside the Range and Odometry it completes itself.

use echoloc::predict::Mount;
use serde::ser::SerializeTuple;
use serde::{Deserialize, Serialize};

/// The rosbag2 type names echoloc reads.
pub mod types {
    /// `sensor_msgs/msg/Range`: one transducer's reading.
    pub const RANGE: &str = "sensor_msgs/msg/Range";
    /// `sensor_msgs/msg/PointCloud`: a RosAria ring, one point per transducer.
    pub const POINT_CLOUD: &str = "sensor_msgs/msg/PointCloud";
    /// `nav_msgs/msg/Odometry`: odometry, or a simulator's ground truth.
    pub const ODOMETRY: &str = "nav_msgs/msg/Odometry";
    /// `geometry_msgs/msg/PoseWithCovarianceStamped`: e.g. `/amcl_pose`.
    pub const POSE_COV: &str = "geometry_msgs/msg/PoseWithCovarianceStamped";
    /// `tf2_msgs/msg/TFMessage`: `/tf` and `/tf_static`.
    pub const TF: &str = "tf2_msgs/msg/TFMessage";
    /// `sensor_msgs/msg/LaserScan`: one sweep of a planar laser.
    pub const LASER_SCAN: &str = "sensor_msgs/msg/LaserScan";
    /// `geometry_msgs/msg/PoseStamped`: e.g. a SLAM's or a motion capture's pose.
    pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
}

/// `builtin_interfaces/msg/Time`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// Seconds since the epoch. A nanosecond field of 10⁹ or more is not a
    /// time (`None`).
    pub fn seconds(self) -> Option<f64> {
        (self.nanosec < 1_000_000_000).then(|| f64::from(self.sec) + f64::from(self.nanosec) * 1e-9)
    }

    /// Nanoseconds since the epoch (exact, for ordering).
    pub fn nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `std_msgs/msg/Header`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `sensor_msgs/msg/Range` (the fields every distribution has).
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct Range {
    pub header: Header,
    pub radiation_type: u8,
    pub field_of_view: f32,
    pub min_range: f32,
    pub max_range: f32,
    pub range: f32,
}

/// `geometry_msgs/msg/Point32`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
pub struct Point32 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

/// `sensor_msgs/msg/PointCloud` up to its points (the channels are not read).
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct PointCloud {
    pub header: Header,
    pub points: Vec<Point32>,
}

/// `geometry_msgs/msg/Point`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Quaternion {
    /// The rotation about z (yaw), rad, as tf2's `getYaw`: the heading of a
    /// planar robot. A quaternion of zero length has none (`None`).
    pub fn yaw(self) -> Option<f64> {
        let Quaternion { x, y, z, w } = self;
        let n = x * x + y * y + z * z + w * w;
        if !(n.is_finite() && n > 1e-12) {
            return None;
        }
        Some((2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z)))
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
pub struct Pose {
    pub position: Point,
    pub orientation: Quaternion,
}

/// `nav_msgs/msg/Odometry` up to its pose (the pose's covariance and the
/// twist are not read).
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct Odometry {
    pub header: Header,
    pub child_frame_id: String,
    pub pose: Pose,
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped` up to its pose.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct PoseWithCovarianceStamped {
    pub header: Header,
    pub pose: Pose,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}

/// `sensor_msgs/msg/LaserScan` up to its ranges (the intensities are not
/// read). Angles in rad, ranges in m.
#[derive(Clone, Debug, Deserialize, PartialEq)]
pub struct LaserScan {
    pub header: Header,
    pub angle_min: f32,
    pub angle_max: f32,
    pub angle_increment: f32,
    pub time_increment: f32,
    pub scan_time: f32,
    pub range_min: f32,
    pub range_max: f32,
    pub ranges: Vec<f32>,
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}

/// `geometry_msgs/msg/PoseWithCovariance`'s covariance: a CDR fixed array
/// (no length), which serde's arrays stop short of (32 elements).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Serialize for Covariance {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Elements;
        impl<'de> serde::de::Visitor<'de> for Elements {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("36 f64s")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (i, v) in c.iter_mut().enumerate() {
                    *v = seq.next_element()?.ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, Elements)
    }
}

/// `sensor_msgs/msg/Range`, Jazzy's (with `variance`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RangeMsg {
    pub header: Header,
    pub radiation_type: u8,
    pub field_of_view: f32,
    pub min_range: f32,
    pub max_range: f32,
    pub range: f32,
    pub variance: f32,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PoseWithCovariance {
    pub pose: Pose,
    pub covariance: Covariance,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Twist {
    pub linear: Vector3,
    pub angular: Vector3,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TwistWithCovariance {
    pub twist: Twist,
    pub covariance: Covariance,
}

/// `nav_msgs/msg/Odometry`, whole (what a ROS 2 node takes from `/odom`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct OdometryMsg {
    pub header: Header,
    pub child_frame_id: String,
    pub pose: PoseWithCovariance,
    pub twist: TwistWithCovariance,
}

/// `sensor_msgs/msg/Range`'s ULTRASOUND.
pub const ULTRASOUND: u8 = 0;

pub fn stamp(ns: u64) -> Time {
    // ns < 2³¹·10⁹ was checked, so both parts fit.
    Time { sec: (ns / 1_000_000_000) as i32, nanosec: (ns % 1_000_000_000) as u32 }
}

pub fn header(ns: u64, frame: &str) -> Header {
    Header { stamp: stamp(ns), frame_id: frame.into() }
}

/// A heading as a rotation about z.
pub fn yaw_quaternion(yaw: f64) -> Quaternion {
    let h = yaw / 2.0;
    Quaternion { x: 0.0, y: 0.0, z: h.sin(), w: h.cos() }
}

pub fn pose(p: [f64; 3]) -> Pose {
    Pose { position: Point { x: p[0], y: p[1], z: 0.0 }, orientation: yaw_quaternion(p[2]) }
}

/// An Odometry of `child` in `frame` at `ns`: the pose, its covariance
/// and the twist unknown (zero; a log has neither).
pub fn odometry(ns: u64, frame: &str, child: &str, p: [f64; 3]) -> OdometryMsg {
    let zero = Vector3 { x: 0.0, y: 0.0, z: 0.0 };
    OdometryMsg {
        header: header(ns, frame),
        child_frame_id: child.into(),
        pose: PoseWithCovariance { pose: pose(p), covariance: Covariance([0.0; 36]) },
        twist: TwistWithCovariance { twist: Twist { linear: zero, angular: zero }, covariance: Covariance([0.0; 36]) },
    }
}

pub fn transform(ns: u64, parent: &str, child: &str, p: [f64; 3]) -> TransformStamped {
    TransformStamped {
        header: header(ns, parent),
        child_frame_id: child.into(),
        transform: Transform { translation: Vector3 { x: p[0], y: p[1], z: 0.0 }, rotation: yaw_quaternion(p[2]) },
    }
}

/// A mount as a pose in the robot's frame (m, m, rad).
pub fn mount_pose(m: &Mount) -> [f64; 3] {
    [f64::from(m.x_mm) / 1000.0, f64::from(m.y_mm) / 1000.0, (f64::from(m.heading_mdeg) / 1000.0).to_radians()]
}

/// A message as rosbag2 stores it and DDS carries it: the CDR encapsulation
/// header (`00 01`: plain CDR, little-endian; options 0), then the body,
/// aligned from its start.
pub fn encode<T: Serialize>(msg: &T) -> Result<Vec<u8>, String> {
    let body = cdr_encoding::to_vec::<T, byteorder::LittleEndian>(msg).map_err(|e| e.to_string())?;
    let mut out = Vec::with_capacity(4 + body.len());
    out.extend_from_slice(&[0, 1, 0, 0]);
    out.extend_from_slice(&body);
    Ok(out)
}

/// Decodes a rosbag2 `cdr` message: the 4-byte encapsulation header
/// (`00 01` little-endian or `00 00` big-endian CDR, then two option bytes),
/// then `T`'s fields with CDR's alignment counted from after the header.
pub fn decode<'de, T: Deserialize<'de>>(data: &'de [u8]) -> Result<T, String> {
    let (head, body) = data.split_at_checked(4).ok_or_else(|| format!("{} bytes: too short for CDR", data.len()))?;
    let decoded = match (head[0], head[1]) {
        (0, 1) => cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(body),
        (0, 0) => cdr_encoding::from_bytes::<T, byteorder::BigEndian>(body),
        (a, b) => {
            return Err(format!(
                "encapsulation {a:02x} {b:02x}: not plain CDR (00 01 little-endian or 00 00 big-endian)"
            ))
        }
    };
    decoded.map(|(v, _)| v).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `sensor_msgs/msg/Range` laid out by hand from the CDR rules
    /// (OMG CDR: primitives aligned to their size from the body's start;
    /// strings as a u32 length counting the NUL, the bytes and the NUL).
    #[test]
    fn range_by_hand() {
        let mut b = vec![0, 1, 0, 0];
        b.extend(7i32.to_le_bytes()); // stamp.sec
        b.extend(500_000_000u32.to_le_bytes()); // stamp.nanosec
        b.extend(8u32.to_le_bytes()); // frame_id length with the NUL
        b.extend(b"sonar_3\0");
        b.push(0); // radiation_type ULTRASOUND, offset 20
        b.extend([0, 0, 0]); // pad to 24 for the f32s
        for v in [0.5f32, 0.1, 5.0, 1.25] {
            b.extend(v.to_le_bytes());
        }
        let r: Range = decode(&b).unwrap();
        assert_eq!(r.header.frame_id, "sonar_3");
        assert_eq!(r.header.stamp.seconds(), Some(7.5));
        assert_eq!((r.min_range, r.max_range, r.range), (0.1, 5.0, 1.25));
        // Big-endian CDR is CDR too.
        let mut be = vec![0, 0, 0, 0];
        be.extend(7i32.to_be_bytes());
        be.extend(0u32.to_be_bytes());
        be.extend(1u32.to_be_bytes());
        be.push(0); // the string's NUL, body offset 12
        be.push(1); // radiation_type INFRARED, offset 13
        be.extend([0, 0]); // pad to 16 for the f32s
        for v in [0.5f32, 0.2, 3.0, 2.0] {
            be.extend(v.to_be_bytes());
        }
        let r: Range = decode(&be).unwrap();
        assert_eq!((r.header.frame_id.as_str(), r.radiation_type, r.range), ("", 1, 2.0));
        assert!(decode::<Range>(&b[..20]).is_err(), "a truncated message is an error");
        assert!(decode::<Range>(&[0, 1]).is_err());
        assert!(decode::<Range>(&[1, 2, 0, 0, 0, 0, 0, 0]).unwrap_err().contains("not plain CDR"));
    }

    /// A `sensor_msgs/msg/LaserScan` laid out by hand: the header, seven
    /// f32s, then the ranges as a u32 count and f32s (the intensities after
    /// them are not read).
    #[test]
    fn laser_scan_by_hand() {
        let mut b = vec![0, 1, 0, 0];
        b.extend(3i32.to_le_bytes()); // stamp.sec
        b.extend(250_000_000u32.to_le_bytes()); // stamp.nanosec
        b.extend(6u32.to_le_bytes()); // frame_id length with the NUL
        b.extend(b"laser\0"); // body offset 12..18
        b.extend([0, 0]); // pad to 20 for the f32s
        for v in [-1.5f32, 1.5, 0.5, 0.0, 0.1, 0.05, 30.0] {
            b.extend(v.to_le_bytes());
        }
        b.extend(3u32.to_le_bytes()); // ranges: 3
        for v in [1.0f32, f32::INFINITY, 2.5] {
            b.extend(v.to_le_bytes());
        }
        b.extend(0u32.to_le_bytes()); // intensities: none
        let s: LaserScan = decode(&b).unwrap();
        assert_eq!((s.header.frame_id.as_str(), s.header.stamp.seconds()), ("laser", Some(3.25)));
        assert_eq!((s.angle_min, s.angle_increment, s.range_min, s.range_max), (-1.5, 0.5, 0.05, 30.0));
        assert_eq!(s.ranges, vec![1.0, f32::INFINITY, 2.5]);
        let cut = b.len() - 8;
        assert!(decode::<LaserScan>(&b[..cut]).is_err(), "ranges cut short are an error");
    }

    #[test]
    fn yaw_of_quaternions() {
        let q = |th: f64| Quaternion { x: 0.0, y: 0.0, z: (th / 2.0).sin(), w: (th / 2.0).cos() };
        for th in [0.0, 0.3, -2.0, 3.1] {
            assert!((q(th).yaw().unwrap() - th).abs() < 1e-12);
        }
        assert_eq!(Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 0.0 }.yaw(), None);
    }
}
