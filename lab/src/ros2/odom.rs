//! `/odom` in (`link --ros2 --ros2-odom`): the robot's own odometry node's
//! `nav_msgs/Odometry`, turned into the link's `Odometry` samples on the
//! controller's clock. No DDS here: [`super::node`] takes the messages.
//!
//! **The clock run backwards.** [`super::bridge`] stamps a reading made at
//! controller time `t` at host time `h + (t − c)`, where (`h`, `c`) is the
//! anchor: the host's time when the controller's `Hello` came and the
//! controller's time in it. An odometry stamp `s` is therefore controller
//! time `c + (s − h)`, floored to the µs: a pose published at stamp `s` and
//! the odometry stamped `s` meet at the same controller time, so nav2's
//! `map → odom` at `s` composed with `odom → base_link` at `s` is the
//! controller's estimate. A stamp that maps before the controller's clock
//! began (before 0) cannot be sent; nor can one not after the last sent (the
//! controller's odometry is a time series). Until the anchor is known the
//! samples wait, at most [`PENDING`] of them.

use std::collections::VecDeque;

use super::bridge::Sample;
use crate::bag::msgs::OdometryMsg;
use crate::bag::write::ODOM_FRAME;

/// Samples held until the controller's clock is known: a second of a
/// 50 Hz odometry, and then some.
pub const PENDING: usize = 128;

/// (host ns, controller µs unwrapped): see the module's doc.
pub type Anchor = (u64, u64);

/// What happened to the odometry that came.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct OdomCounts {
    /// Sent to the controller.
    pub taken: u32,
    /// Refused (each reason on stderr, the first ten and every thousandth).
    pub refused: u32,
    /// The first and last sent, on the controller's clock (µs, wrapped as it wraps).
    pub first_us: Option<u32>,
    pub last_us: Option<u32>,
}

/// `/odom` messages to the link's samples, in order.
pub struct OdomClock {
    /// The robot's base frame, `child_frame_id` of the odometry.
    base_frame: String,
    /// Valid samples waiting for the anchor: (stamp ns, x m, y m, θ rad).
    pending: VecDeque<(u64, [f64; 3])>,
    /// The last sent, controller µs unwrapped.
    last_us: Option<u64>,
    pub counts: OdomCounts,
}

/// `m`'s stamp (ns) and pose (x, y, θ) if it is a planar pose of
/// `base_frame` in `odom`, else why not.
pub fn odom_pose(m: &OdometryMsg, base_frame: &str) -> Result<(u64, [f64; 3]), String> {
    let frame = m.header.frame_id.trim_start_matches('/');
    if frame != ODOM_FRAME {
        return Err(format!("frame {:?}: odometry is a pose in frame \"{ODOM_FRAME}\"", m.header.frame_id));
    }
    let child = m.child_frame_id.trim_start_matches('/');
    if child != base_frame {
        return Err(format!(
            "child frame {:?}: the controller's mounts are on {base_frame:?} (--ros2-base-frame)",
            m.child_frame_id
        ));
    }
    let t = m.header.stamp;
    if t.sec < 0 || t.nanosec >= 1_000_000_000 {
        return Err(format!("stamp {}.{:09} s: not a time", t.sec, t.nanosec));
    }
    let p = m.pose.pose.position;
    if !(p.x.is_finite() && p.y.is_finite()) {
        return Err("a position that is not finite".into());
    }
    if p.x.abs() > 1e6 || p.y.abs() > 1e6 {
        return Err(format!("({}, {}) m: beyond any drive", p.x, p.y));
    }
    let Some(yaw) = m.pose.pose.orientation.yaw() else {
        return Err("an orientation that is no rotation (a zero or non-finite quaternion)".into());
    };
    Ok((t.nanos() as u64, [p.x, p.y, yaw]))
}

/// Controller time (µs, unwrapped) of host stamp `ns`, floored; `None`
/// before the controller's clock began.
pub fn controller_us((h, c): Anchor, ns: u64) -> Option<u64> {
    let dt = (i128::from(ns) - i128::from(h)).div_euclid(1000);
    u64::try_from(i128::from(c) + dt).ok()
}

impl OdomClock {
    /// For a robot whose odometry's child frame is `base_frame`.
    pub fn new(base_frame: &str) -> Self {
        Self {
            base_frame: base_frame.trim_start_matches('/').to_string(),
            pending: VecDeque::new(),
            last_us: None,
            counts: OdomCounts::default(),
        }
    }

    /// Takes one message: `Err` with the reason when it is refused now (not
    /// a planar pose of the base in `odom`, or a sample the wait bumped).
    pub fn push(&mut self, m: &OdometryMsg) -> Result<(), String> {
        let s = odom_pose(m, &self.base_frame).inspect_err(|_| self.counts.refused += 1)?;
        self.pending.push_back(s);
        if self.pending.len() > PENDING {
            self.pending.pop_front();
            self.counts.refused += 1;
            return Err(format!(
                "more than {PENDING} samples before the controller's clock was known: the oldest dropped"
            ));
        }
        Ok(())
    }

    /// Once the anchor is known, the samples to send in order, or why one
    /// is refused; nothing before.
    pub fn drain(&mut self, anchor: Option<Anchor>) -> Vec<Result<Sample, String>> {
        let Some(a) = anchor else { return Vec::new() };
        let mut out = Vec::with_capacity(self.pending.len());
        while let Some((ns, p)) = self.pending.pop_front() {
            let r = match controller_us(a, ns) {
                None => Err(format!("stamp {ns} ns: before the controller's clock began (its Hello at {} ns)", a.0)),
                Some(t) if self.last_us.is_some_and(|l| t <= l) => {
                    Err(format!("stamp {ns} ns: not after the last odometry sent (controller time {t} µs)"))
                }
                Some(t) => {
                    self.last_us = Some(t);
                    // The controller's clock wraps at 2³² µs; so does the link's.
                    let s = (t as u32, p[0] as f32, p[1] as f32, p[2] as f32);
                    self.counts.taken += 1;
                    self.counts.first_us.get_or_insert(s.0);
                    self.counts.last_us = Some(s.0);
                    Ok(s)
                }
            };
            if r.is_err() {
                self.counts.refused += 1;
            }
            out.push(r);
        }
        out
    }

    /// A new controller clock (a `Hello` after a restart): what was sent
    /// before no longer orders what comes.
    pub fn restart(&mut self) {
        self.last_us = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::msgs::{odometry, Time};

    fn msg(ns: u64, frame: &str, child: &str, p: [f64; 3]) -> OdometryMsg {
        odometry(ns, frame, child, p)
    }

    /// The anchor's inverse, by hand: Hello at host 5 s with the
    /// controller at 2 s; a stamp 1.5 s later is 3.5 s; 1.5 s before is
    /// 0.5 s; 2.5 s before is before its clock; sub-µs parts floor.
    #[test]
    fn stamps_map_back_through_the_hello_anchor() {
        let a = (5_000_000_000, 2_000_000);
        assert_eq!(controller_us(a, 6_500_000_000), Some(3_500_000));
        assert_eq!(controller_us(a, 3_500_000_000), Some(500_000));
        assert_eq!(controller_us(a, 2_999_999_999), None);
        assert_eq!(controller_us(a, 3_000_000_000), Some(0));
        assert_eq!(controller_us(a, 5_000_000_999), Some(2_000_000));
        assert_eq!(controller_us(a, 4_999_999_999), Some(1_999_999));
    }

    /// The bridge's forward stamp and this backward map are inverses: a
    /// reading's stamp maps back to the reading's time.
    #[test]
    fn the_bridges_stamp_maps_back_to_the_readings_time() {
        use super::super::bridge::Bridge;
        use super::super::Distro;
        let mut b = Bridge::new(Distro::Jazzy, &[], &[]);
        b.push(
            &echoloc::link::FromController::Hello { protocol: 2, transducers: 16, map_crc: 0, time_us: 77 },
            1_234_567_891,
        );
        let a = b.anchor().unwrap();
        for t in [77u64, 78, 1_000_077, 3_000_000_000] {
            assert_eq!(controller_us(a, b.host_ns(t)), Some(t));
        }
    }

    #[test]
    fn samples_wait_for_the_clock_then_go_in_order() {
        let mut c = OdomClock::new("/base_link");
        c.push(&msg(900_000_000, "odom", "base_link", [9.0, 0.0, 0.0])).unwrap();
        c.push(&msg(1_000_000_000, "/odom", "base_link", [1.0, 2.0, 0.5])).unwrap();
        assert!(c.drain(None).is_empty());
        let out = c.drain(Some((1_000_000_000, 0)));
        assert!(out[0].as_ref().unwrap_err().contains("before the controller's clock"), "{out:?}");
        let (t, x, y, th) = out[1].clone().unwrap();
        assert_eq!((t, x, y), (0, 1.0, 2.0));
        assert!((th - 0.5).abs() < 1e-6);
        c.push(&msg(1_000_000_000, "odom", "base_link", [1.0, 2.0, 0.5])).unwrap();
        c.push(&msg(1_020_000_500, "odom", "base_link", [1.1, 2.0, -3.0])).unwrap();
        let out = c.drain(Some((1_000_000_000, 0)));
        assert!(out[0].as_ref().unwrap_err().contains("not after the last"), "{out:?}");
        let (t, x, _, th) = out[1].clone().unwrap();
        assert_eq!((t, x), (20_000, 1.1));
        assert!((th + 3.0).abs() < 1e-6);
        assert_eq!(
            (c.counts.taken, c.counts.refused, c.counts.first_us, c.counts.last_us),
            (2, 2, Some(0), Some(20_000))
        );
        // Past the controller's 2³² µs: wrapped as its clock wraps.
        c.push(&msg(1_000_000_000 + (1u64 << 32) * 1000 + 5_000, "odom", "base_link", [0.0; 3])).unwrap();
        assert_eq!(c.drain(Some((1_000_000_000, 0)))[0], Ok((5, 0.0, 0.0, 0.0)));
    }

    #[test]
    fn what_is_no_planar_pose_of_the_base_in_odom_is_refused() {
        let mut c = OdomClock::new("base_link");
        let why = |m: OdometryMsg, c: &mut OdomClock| c.push(&m).unwrap_err();
        assert!(why(msg(1, "map", "base_link", [0.0; 3]), &mut c).contains("frame \"map\""));
        assert!(why(msg(1, "odom", "base_footprint", [0.0; 3]), &mut c).contains("--ros2-base-frame"));
        assert!(why(msg(1, "odom", "base_link", [f64::NAN, 0.0, 0.0]), &mut c).contains("not finite"));
        assert!(why(msg(1, "odom", "base_link", [2e6, 0.0, 0.0]), &mut c).contains("beyond"));
        let mut m = msg(1, "odom", "base_link", [0.0; 3]);
        m.pose.pose.orientation = crate::bag::msgs::Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 0.0 };
        assert!(why(m, &mut c).contains("orientation"));
        let mut m = msg(0, "odom", "base_link", [0.0; 3]);
        m.header.stamp = Time { sec: -1, nanosec: 0 };
        assert!(why(m, &mut c).contains("not a time"));
        assert_eq!(c.counts.refused, 6);
        assert!(OdomClock::new("base_footprint").push(&msg(1, "odom", "base_footprint", [0.0; 3])).is_ok());
    }

    #[test]
    fn a_long_wait_keeps_the_newest() {
        let mut c = OdomClock::new("base_link");
        for k in 0..PENDING as u64 {
            c.push(&msg(1_000 * k, "odom", "base_link", [k as f64, 0.0, 0.0])).unwrap();
        }
        assert!(c.push(&msg(1_000 * PENDING as u64, "odom", "base_link", [0.0; 3])).unwrap_err().contains("oldest"));
        let out = c.drain(Some((0, 0)));
        assert_eq!(out.len(), PENDING);
        assert_eq!(out[0], Ok((1, 1.0, 0.0, 0.0)));
    }
}
