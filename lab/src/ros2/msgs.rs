//! The ROS 2 messages the node publishes and takes beyond those a bag holds
//! (`crate::bag::msgs`), in their `.msg` field order (CDR has no names:
//! order and alignment are the format), and the one layout that differs
//! between the distributions it speaks.

use serde::{Deserialize, Serialize};

use crate::bag::msgs::{Covariance, Header, Pose, PoseWithCovariance};

/// The ROS 2 distribution whose message layouts go on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Distro {
    /// Humble (2022–2027): `sensor_msgs/Range` without `variance`, which Iron added.
    Humble,
    /// Jazzy (2024–2029): Range with `variance`.
    Jazzy,
    /// Kilted (2025–2026): as Jazzy for every message here.
    Kilted,
}

impl Distro {
    /// Whether `sensor_msgs/Range` ends with `float32 variance` (every
    /// distribution after Humble).
    pub fn range_has_variance(self) -> bool {
        !matches!(self, Distro::Humble)
    }
}

/// `sensor_msgs/msg/Range` as `distro` lays it out: serialized as the
/// inner message (untagged), so one publisher serves every distribution.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum RangeOut {
    /// Humble's five fields after the header.
    Humble(RangeHumble),
    /// Jazzy's and Kilted's, with `variance`.
    Jazzy(crate::bag::msgs::RangeMsg),
}

/// `sensor_msgs/msg/Range` before Jazzy.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RangeHumble {
    pub header: Header,
    pub radiation_type: u8,
    pub field_of_view: f32,
    pub min_range: f32,
    pub max_range: f32,
    pub range: f32,
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped`, whole: what `/amcl_pose`
/// carries and rviz's *2D Pose Estimate* sends on `/initialpose`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PoseWithCovarianceStamped {
    pub header: Header,
    pub pose: PoseWithCovariance,
}

/// `geometry_msgs/msg/PoseArray`: `/particlecloud`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PoseArray {
    pub header: Header,
    pub poses: Vec<Pose>,
}

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct KeyValue {
    pub key: String,
    pub value: String,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DiagnosticStatus {
    /// `OK` 0, `WARN` 1, `ERROR` 2, `STALE` 3 (a `byte`).
    pub level: u8,
    pub name: String,
    pub message: String,
    pub hardware_id: String,
    pub values: Vec<KeyValue>,
}

/// `diagnostic_msgs/msg/DiagnosticArray`: `/diagnostics`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DiagnosticArray {
    pub header: Header,
    pub status: Vec<DiagnosticStatus>,
}

/// `std_srvs/srv/Empty`'s request and response: IDL has no empty structs,
/// so ROS 2 gives each one `uint8 structure_needs_at_least_one_member`.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Empty {
    pub structure_needs_at_least_one_member: u8,
}

/// A covariance of a planar pose (x, y, yaw) in ROS's 6×6 row-major layout
/// (x, y, z, roll, pitch, yaw): the controller's upper triangle xx, xy, xφ,
/// yy, yφ, φφ placed and mirrored; z, roll and pitch zero, as amcl leaves them.
pub fn planar_covariance(c: [f32; 6]) -> Covariance {
    let mut m = [0.0f64; 36];
    let [xx, xy, xp, yy, yp, pp] = c.map(f64::from);
    for (i, j, v) in [(0, 0, xx), (0, 1, xy), (0, 5, xp), (1, 1, yy), (1, 5, yp), (5, 5, pp)] {
        m[i * 6 + j] = v;
        m[j * 6 + i] = v;
    }
    Covariance(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::msgs::{decode, encode, header, stamp};

    /// A Humble Range laid out by hand from the CDR rules (the Jazzy one is
    /// `bag::write`'s test): header, the u8, three bytes of padding, five f32s.
    #[test]
    fn humble_range_by_hand() {
        let m = RangeOut::Humble(RangeHumble {
            header: header(7_500_000_000, "sonar_3"),
            radiation_type: 0,
            field_of_view: 0.5,
            min_range: 0.1,
            max_range: 5.0,
            range: 1.25,
        });
        let mut b = vec![0, 1, 0, 0];
        b.extend(7i32.to_le_bytes());
        b.extend(500_000_000u32.to_le_bytes());
        b.extend(8u32.to_le_bytes());
        b.extend(b"sonar_3\0");
        b.extend([0, 0, 0, 0]);
        for v in [0.5f32, 0.1, 5.0, 1.25] {
            b.extend(v.to_le_bytes());
        }
        assert_eq!(encode(&m).unwrap(), b);
    }

    /// The 6×6 covariance: the upper triangle placed at x, y and yaw and
    /// mirrored, and a pose with it round-trips through CDR (the 36 f64s
    /// a fixed array: no length).
    #[test]
    fn covariance_layout_and_round_trip() {
        let c = planar_covariance([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).0;
        assert_eq!(
            (c[0], c[1], c[6], c[5], c[30], c[7], c[11], c[31], c[35]),
            (1.0, 2.0, 2.0, 3.0, 3.0, 4.0, 5.0, 5.0, 6.0)
        );
        assert_eq!(c.iter().filter(|&&v| v != 0.0).count(), 9);
        let m = PoseWithCovarianceStamped {
            header: crate::bag::msgs::Header { stamp: stamp(1), frame_id: "map".into() },
            pose: PoseWithCovariance { pose: crate::bag::msgs::pose([1.0, 2.0, 0.5]), covariance: Covariance(c) },
        };
        let b = encode(&m).unwrap();
        // 4 header + 8 stamp + 4 + "map\0" + 7·8 pose + 36·8 covariance.
        assert_eq!(b.len(), 4 + 8 + 8 + 56 + 288);
        assert_eq!(decode::<PoseWithCovarianceStamped>(&b).unwrap(), m);
    }
}
