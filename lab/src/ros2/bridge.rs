//! From what the controller sends over the link to the ROS 2 messages that
//! stand for amcl's (docs/ros2.md): per reading the pose on `/amcl_pose`,
//! `map → odom` on `/tf` and the transducer's `sensor_msgs/Range`; per ring
//! cycle the mode on `/diagnostics`; once, the mounts on `/tf_static`.
//! No DDS here: [`super::node`] publishes what this makes.
//!
//! **The clock.** The controller stamps readings on its own clock (µs,
//! wrapping at 2³²). The host maps it to its own: the host's time when the
//! controller's `Hello` arrived (or, joining late, its first reading) plus
//! the controller's time since then. Both clocks run at their own rate, so a
//! long run drifts by the two crystals' difference (tens of ppm: a few ms an
//! hour), and a replay under QEMU runs at the scenario's pace, not the host's.

use echoloc::link::{CycleReport, FromController, ReadingReport, ToController, WireMode, WireOutcome};
use echoloc::predict::Mount;

use super::msgs::{
    planar_covariance, DiagnosticArray, DiagnosticStatus, Distro, KeyValue, PoseArray, PoseWithCovarianceStamped,
    RangeHumble, RangeOut,
};
use crate::angle::wrap;
use crate::bag::msgs::{header, mount_pose, pose, transform, PoseWithCovariance, RangeMsg, TfMessage, ULTRASOUND};
use crate::bag::write::{sonar_frame, BASE_FRAME, MAP_FRAME, ODOM_FRAME, POLAROID_FIELD_OF_VIEW_RAD};
use crate::bag::write::{POLAROID_MAX_RANGE_M, POLAROID_MIN_RANGE_M};
use crate::clock::Unwrap;

/// An odometry sample as the link sends it: (controller µs, x m, y m, θ rad).
pub type Sample = (u32, f32, f32, f32);

/// One message to publish.
#[derive(Clone, Debug, PartialEq)]
pub enum Out {
    /// `/amcl_pose` (the topic configurable).
    Pose(Box<PoseWithCovarianceStamped>),
    /// `/tf`: `map → odom`.
    Tf(TfMessage),
    /// Transducer `k`'s reading on `/sonar_<k>`.
    Range(usize, RangeOut),
    /// `/diagnostics`: the localizer's mode.
    Diagnostics(DiagnosticArray),
    /// `/particlecloud`: the particles at a searching cycle's end (a replay's: the link carries none).
    Particles(PoseArray),
}

/// The link's messages turned into ROS 2 messages, in arrival order.
pub struct Bridge {
    distro: Distro,
    mounts: Vec<Mount>,
    /// The odometry sent, controller µs unwrapped, ascending.
    odometry: Vec<(u64, [f64; 3])>,
    /// The odometry's own unwrapping of the controller's clock.
    odometry_clock: Unwrap,
    /// (host ns, controller µs unwrapped) at the anchor.
    anchor: Option<(u64, u64)>,
    /// The readings' unwrapping of it.
    clock: Unwrap,
    /// The last reading's host stamp, ns, for the cycle after it.
    last_ns: u64,
    /// The robot's base frame, the mounts' parent.
    base_frame: String,
}

/// `WireMode` as the diagnostic's level: tracking OK, searching WARN, lost ERROR.
fn level(m: WireMode) -> u8 {
    match m {
        WireMode::Tracking => 0,
        WireMode::Searching => 1,
        WireMode::Lost => 2,
    }
}

/// `/amcl_pose`'s message: `pose` (x, y m, φ rad) in `map` at `ns`, with the
/// covariance's upper triangle xx, xy, xφ, yy, yφ, φφ.
pub fn pose_message(ns: u64, p: [f64; 3], covariance: [f32; 6]) -> PoseWithCovarianceStamped {
    PoseWithCovarianceStamped {
        header: header(ns, MAP_FRAME),
        pose: PoseWithCovariance { pose: pose(p), covariance: planar_covariance(covariance) },
    }
}

/// `map → odom` at `ns` = (map → base) ∘ (odom → base)⁻¹, from the pose in
/// the map and the odometry's at the same time.
pub fn map_to_odom(ns: u64, p: [f64; 3], o: [f64; 3]) -> TfMessage {
    let phi = wrap(p[2] - o[2]);
    let (s, c) = phi.sin_cos();
    let mo = [p[0] - (c * o[0] - s * o[1]), p[1] - (s * o[0] + c * o[1]), phi];
    TfMessage { transforms: vec![transform(ns, MAP_FRAME, ODOM_FRAME, mo)] }
}

/// Transducer `k`'s `sensor_msgs/Range` at `ns` as `distro` lays it out:
/// `range` m (`+Inf`: no echo, REP 117), the Polaroid's cone and limits.
pub fn range_message(distro: Distro, ns: u64, k: usize, range: f32) -> RangeOut {
    let h = header(ns, &sonar_frame(k));
    let (fov, min, max) = (POLAROID_FIELD_OF_VIEW_RAD as f32, POLAROID_MIN_RANGE_M as f32, POLAROID_MAX_RANGE_M as f32);
    if distro.range_has_variance() {
        RangeOut::Jazzy(RangeMsg {
            header: h,
            radiation_type: ULTRASOUND,
            field_of_view: fov,
            min_range: min,
            max_range: max,
            range,
            variance: 0.0,
        })
    } else {
        RangeOut::Humble(RangeHumble {
            header: h,
            radiation_type: ULTRASOUND,
            field_of_view: fov,
            min_range: min,
            max_range: max,
            range,
        })
    }
}

/// The ring's mounts as `base → sonar_<k>` at `ns`, for `/tf_static`.
pub fn static_mounts(ns: u64, base: &str, mounts: &[Mount]) -> TfMessage {
    let transforms =
        mounts.iter().enumerate().map(|(k, m)| transform(ns, base, &sonar_frame(k), mount_pose(m))).collect();
    TfMessage { transforms }
}

/// `/particlecloud`'s message: the particles' poses in `map` at `ns`.
pub fn particle_cloud(ns: u64, particles: &[[f32; 3]]) -> PoseArray {
    PoseArray { header: header(ns, MAP_FRAME), poses: particles.iter().map(|q| pose(q.map(f64::from))).collect() }
}

/// `/diagnostics`' message for ring cycle `c`: its mode as the level, the
/// reason as the message (with the place test's standing: the places alive
/// and the best one's lead while searching, how far the pose trails the
/// null), and its counts as values.
pub fn mode_diagnostics(ns: u64, c: &CycleReport) -> DiagnosticArray {
    let trails =
        if c.behind > 0.0 { format!("; the pose trails the null by {:.1} nats", c.behind) } else { String::new() };
    let message = match c.mode {
        _ if c.handoff => "tracking: the particles handed off to the EKF".to_string(),
        WireMode::Tracking => format!("tracking: the gate accepted {} of {} readings{trails}", c.gate[1], c.gate[0]),
        WireMode::Searching if c.hypotheses > 0 => format!(
            "searching with {} particles: {} places alive, the best {:.1} nats ahead of the null and the rest{trails}",
            c.particles, c.hypotheses, c.lead
        ),
        WireMode::Searching => format!("searching with {} particles{trails}", c.particles),
        WireMode::Lost => format!("lost: the EKF's estimate is not trusted{trails}"),
    };
    let kv = |k: &str, v: String| KeyValue { key: k.into(), value: v };
    DiagnosticArray {
        header: header(ns, ""),
        status: vec![DiagnosticStatus {
            level: level(c.mode),
            name: "echoloc: localization".into(),
            message,
            hardware_id: "sonar controller".into(),
            values: vec![
                kv("cycle", c.cycle.to_string()),
                kv("particles", c.particles.to_string()),
                kv("gate tested", c.gate[0].to_string()),
                kv("gate accepted", c.gate[1].to_string()),
                kv("confirmed", c.verdicts[0].to_string()),
                kv("handoff", c.handoff.to_string()),
                kv("hypotheses", c.hypotheses.to_string()),
                kv("lead nats", format!("{:.3}", c.lead)),
                kv("behind nats", format!("{:.3}", c.behind)),
            ],
        }],
    }
}

/// `/diagnostics`' message when the controller says `Hello`, stamped at
/// the host's time it came: the clocks' anchor (docs/ros2.md), which a
/// node stamping its own messages for the controller (`/odom`) can read.
pub fn hello_diagnostics(ns: u64, protocol: u8, transducers: u8, map_crc: u32, time_us: u32) -> DiagnosticArray {
    let kv = |k: &str, v: String| KeyValue { key: k.into(), value: v };
    DiagnosticArray {
        header: header(ns, ""),
        status: vec![DiagnosticStatus {
            level: 0,
            name: LINK_STATUS.into(),
            message: format!(
                "the controller said hello: protocol {protocol}, {transducers} transducers, map CRC {map_crc:08x}"
            ),
            hardware_id: "sonar controller".into(),
            values: vec![
                kv("protocol", protocol.to_string()),
                kv("transducers", transducers.to_string()),
                kv("map crc", format!("{map_crc:08x}")),
                kv("controller time us", time_us.to_string()),
            ],
        }],
    }
}

/// The name of the link's own status (the `Hello`), beside the localizer's.
pub const LINK_STATUS: &str = "echoloc: link";

impl Bridge {
    /// For a controller with ring `mounts`, fed `odometry` (in the order sent).
    pub fn new(distro: Distro, mounts: &[Mount], odometry: &[Sample]) -> Self {
        let mut b = Self {
            distro,
            mounts: mounts.to_vec(),
            odometry: Vec::with_capacity(odometry.len()),
            odometry_clock: Unwrap::default(),
            anchor: None,
            clock: Unwrap::default(),
            last_ns: 0,
            base_frame: BASE_FRAME.into(),
        };
        for &s in odometry {
            b.add_odometry(s);
        }
        b
    }

    /// One more odometry sample sent to the controller (after those before it).
    pub fn add_odometry(&mut self, (t, x, y, th): Sample) {
        let t = self.odometry_clock.next(t);
        self.odometry.push((t, [x, y, th].map(f64::from)));
    }

    /// (host ns, controller µs unwrapped) where the two clocks were tied:
    /// the `Hello`, or a late joiner's first reading.
    pub fn anchor(&self) -> Option<(u64, u64)> {
        self.anchor
    }

    /// The mounts hang off `base` rather than `base_link`.
    pub fn with_base_frame(mut self, base: &str) -> Self {
        self.base_frame = base.trim_start_matches('/').into();
        self
    }

    /// The mounts as `base_link → sonar_<k>` (or the base given), for `/tf_static`.
    pub fn static_tf(&self, host_ns: u64) -> TfMessage {
        static_mounts(host_ns, &self.base_frame, &self.mounts)
    }

    /// The odometry pose at controller time `t` (µs, unwrapped): between the
    /// samples around it, θ the shorter way round, as the controller
    /// interpolates it; the nearest end outside them. `None` before any.
    pub fn odometry_at(&self, t: u64) -> Option<[f64; 3]> {
        let i = self.odometry.partition_point(|s| s.0 <= t);
        match (i.checked_sub(1).map(|j| self.odometry[j]), self.odometry.get(i)) {
            (Some((_, a)), None) => Some(a),
            (None, Some(&(_, b))) => Some(b),
            (Some((ta, a)), Some(&(tb, b))) => {
                let f = (t - ta) as f64 / (tb - ta) as f64;
                Some([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), wrap(a[2] + f * wrap(b[2] - a[2]))])
            }
            (None, None) => None,
        }
    }

    /// The messages for `m`, which arrived at host time `host_ns`.
    pub fn push(&mut self, m: &FromController, host_ns: u64) -> Vec<Out> {
        match m {
            FromController::Hello { protocol, transducers, map_crc, time_us } => {
                self.clock = Unwrap::default();
                let t = self.clock.next(*time_us);
                self.anchor = Some((host_ns, t));
                vec![Out::Diagnostics(hello_diagnostics(host_ns, *protocol, *transducers, *map_crc, *time_us))]
            }
            FromController::Reading(r) => self.reading(r, host_ns),
            FromController::Cycle(c) => vec![Out::Diagnostics(self.diagnostics(c))],
            _ => Vec::new(),
        }
    }

    /// Controller time `t` (unwrapped µs) on the host's clock, ns.
    pub fn host_ns(&self, t: u64) -> u64 {
        let (h, c) = self.anchor.unwrap_or((0, 0));
        let dt = i128::from(t) - i128::from(c);
        (i128::from(h) + dt * 1000).clamp(0, i128::from(u64::MAX)) as u64
    }

    fn reading(&mut self, r: &ReadingReport, host_ns: u64) -> Vec<Out> {
        let t = self.clock.next(r.time_us);
        if self.anchor.is_none() {
            self.anchor = Some((host_ns, t));
        }
        let ns = self.host_ns(t);
        self.last_ns = ns;
        let p = r.pose.map(f64::from);
        let mut out = vec![Out::Pose(Box::new(pose_message(ns, p, r.covariance)))];
        if let Some(o) = self.odometry_at(t) {
            out.push(Out::Tf(map_to_odom(ns, p, o)));
        }
        let range = match r.outcome {
            WireOutcome::Range(mm) => Some(mm as f32 / 1000.0),
            // REP 117: nothing heard within range is +∞.
            WireOutcome::NoEcho => Some(f32::INFINITY),
            // An echo EERUF did not confirm, a fault, an untimed firing: no reading.
            _ => None,
        };
        if let Some(range) = range {
            let k = usize::from(r.transducer);
            out.push(Out::Range(k, range_message(self.distro, ns, k, range)));
        }
        out
    }

    fn diagnostics(&self, c: &CycleReport) -> DiagnosticArray {
        mode_diagnostics(self.last_ns, c)
    }
}

/// Where `/initialpose` wants the controller, as a link command: `SetPose`
/// (track from there) when its standard deviations are within `wide`
/// (σ of x or y m, σ of yaw rad), else `Search` around it. Refused, with the
/// reason, when it is not a pose in `map` (a frame other than `map`, a
/// number not finite, a zero quaternion, a negative variance).
pub fn initial_pose_command(m: &PoseWithCovarianceStamped, wide: [f64; 2]) -> Result<ToController, String> {
    if m.header.frame_id.trim_start_matches('/') != MAP_FRAME {
        return Err(format!("frame {:?}: the controller's map is frame \"map\"", m.header.frame_id));
    }
    let p = &m.pose.pose;
    let c = &m.pose.covariance.0;
    let (x, y) = (p.position.x, p.position.y);
    if !(x.is_finite() && y.is_finite() && c.iter().all(|v| v.is_finite())) {
        return Err("a number that is not finite".into());
    }
    let Some(yaw) = p.orientation.yaw() else {
        return Err("an orientation that is no rotation (a zero or non-finite quaternion)".into());
    };
    let (vx, vy, vt) = (c[0], c[7], c[35]);
    if vx < 0.0 || vy < 0.0 || vt < 0.0 {
        return Err(format!("a negative variance (x {vx}, y {vy}, yaw {vt})"));
    }
    // A standard deviation of zero is no filter's start: a millimetre and a milliradian at least.
    let sigma = [vx.sqrt().max(1e-3), vy.sqrt().max(1e-3), vt.sqrt().max(1e-3)];
    if x.abs() > 1e6 || y.abs() > 1e6 {
        return Err(format!("({x}, {y}) m: beyond any map"));
    }
    let pose = [x as f32, y as f32, yaw as f32];
    let sigma32 = sigma.map(|s| s.min(1e6) as f32);
    if sigma[0].max(sigma[1]) > wide[0] || sigma[2] > wide[1] {
        Ok(ToController::Search { around: Some((pose, sigma32)) })
    } else {
        Ok(ToController::SetPose { pose, sigma: sigma32 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echoloc::link::{WireUpdate, WireVerdict};

    fn reading(time_us: u32, pose: [f32; 3], outcome: WireOutcome) -> FromController {
        FromController::Reading(ReadingReport {
            time_us,
            cycle: 0,
            transducer: 2,
            outcome,
            predicted_mm: None,
            kappa: 0.0,
            verdict: WireVerdict::Inconclusive,
            update: WireUpdate::None,
            pose,
            covariance: [0.01, 0.0, 0.0, 0.02, 0.0, 0.001],
            mode: WireMode::Tracking,
        })
    }

    /// The clock: the host's time at `Hello` plus the controller's since,
    /// across the controller's 2³² µs wrap.
    #[test]
    fn stamps_follow_the_hello_anchor_across_the_wrap() {
        let mut b = Bridge::new(Distro::Jazzy, &[], &[]);
        let hello =
            FromController::Hello { protocol: 2, transducers: 16, map_crc: 0xBEEF, time_us: u32::MAX - 999_999 };
        // The anchor, said on /diagnostics at the host's time it came.
        match &b.push(&hello, 5_000_000_000)[..] {
            [Out::Diagnostics(d)] => {
                assert_eq!(d.header.stamp.nanos(), 5_000_000_000);
                assert_eq!(d.status[0].name, LINK_STATUS);
                let v = &d.status[0].values;
                assert_eq!((v[2].value.as_str(), v[3].value.as_str()), ("0000beef", "4293967296"));
            }
            o => panic!("{o:?}"),
        }
        let stamp = |o: &[Out]| match &o[0] {
            Out::Pose(p) => p.header.stamp.nanos(),
            o => panic!("{o:?}"),
        };
        let o = b.push(&reading(u32::MAX - 499_999, [0.0; 3], WireOutcome::NoEcho), 9);
        assert_eq!(stamp(&o), 5_500_000_000);
        // 1.5 s after the Hello, past the wrap.
        let o = b.push(&reading(500_000, [0.0; 3], WireOutcome::NoEcho), 9);
        assert_eq!(stamp(&o), 6_500_000_000);
    }

    /// `map → odom` composed with the odometry at the reading's time gives
    /// the reading's pose (composed here by hand, in the other order).
    #[test]
    fn map_to_odom_composed_with_the_odometry_is_the_pose() {
        let odo: [Sample; 2] = [(0, 1.0, 0.0, 0.0), (1_000_000, 2.0, 1.0, 1.0)];
        let mut b = Bridge::new(Distro::Humble, &[], &odo);
        b.push(&FromController::Hello { protocol: 2, transducers: 16, map_crc: 0, time_us: 0 }, 0);
        let p = [3.0f32, -1.0, 2.5];
        let o = b.push(&reading(250_000, p, WireOutcome::Range(1234)), 0);
        let Out::Tf(tf) = &o[1] else { panic!("{o:?}") };
        let t = &tf.transforms[0];
        assert_eq!((t.header.frame_id.as_str(), t.child_frame_id.as_str()), ("map", "odom"));
        let (tx, ty, yaw) = (t.transform.translation.x, t.transform.translation.y, t.transform.rotation.yaw().unwrap());
        // The odometry a quarter of the way: (1.25, 0.25, 0.25).
        let (ox, oy, oth) = (1.25f64, 0.25f64, 0.25f64);
        let (x, y) = (tx + yaw.cos() * ox - yaw.sin() * oy, ty + yaw.sin() * ox + yaw.cos() * oy);
        let th = yaw + oth;
        assert!((x - 3.0).abs() < 1e-9 && (y + 1.0).abs() < 1e-9, "({x}, {y})");
        assert!((th - 2.5).abs() < 1e-6, "{th}");
        let Out::Range(2, RangeOut::Humble(r)) = &o[2] else { panic!("{o:?}") };
        assert_eq!((r.range, r.header.frame_id.as_str()), (1.234, "sonar_2"));
        // An unconfirmed echo is no reading; no echo is +∞.
        assert_eq!(b.push(&reading(300_000, p, WireOutcome::Unconfirmed(900)), 0).len(), 2);
        let o = b.push(&reading(350_000, p, WireOutcome::NoEcho), 0);
        assert!(matches!(&o[2], Out::Range(_, RangeOut::Humble(r)) if r.range == f32::INFINITY));
    }

    /// The diagnostic says the place test's standing: the places alive and
    /// the best one's lead while searching, how far the pose trails.
    #[test]
    fn a_cycles_diagnostic_says_the_places_standing() {
        let c = CycleReport {
            cycle: 4,
            verdicts: [3, 0, 0, 1, 0, 2],
            gate: [6, 4],
            mode: WireMode::Searching,
            particles: 1024,
            handoff: false,
            hypotheses: 5,
            lead: 37.25,
            behind: 0.0,
        };
        let d = mode_diagnostics(7, &c);
        let st = &d.status[0];
        assert_eq!(st.level, 1);
        assert_eq!(
            st.message,
            "searching with 1024 particles: 5 places alive, the best 37.2 nats ahead of the null and the rest"
        );
        let v: Vec<(&str, &str)> = st.values.iter().map(|kv| (kv.key.as_str(), kv.value.as_str())).collect();
        assert!(
            v.contains(&("hypotheses", "5")) && v.contains(&("lead nats", "37.250")) && v.contains(&("confirmed", "3"))
        );
        let lost = CycleReport { mode: WireMode::Lost, behind: 151.5, ..c };
        assert_eq!(
            mode_diagnostics(7, &lost).status[0].message,
            "lost: the EKF's estimate is not trusted; the pose trails the null by 151.5 nats"
        );
        assert_eq!(mode_diagnostics(7, &lost).status[0].level, 2);
    }

    #[test]
    fn odometry_between_samples_turns_the_shorter_way() {
        let b = Bridge::new(Distro::Jazzy, &[], &[(10, 0.0, 0.0, 3.0), (20, 0.0, 0.0, -3.0)]);
        let mid = b.odometry_at(15).unwrap()[2];
        assert!((mid.abs() - std::f64::consts::PI).abs() < 1e-9, "{mid}");
        assert_eq!(b.odometry_at(5).unwrap()[2], 3.0);
        assert_eq!(b.odometry_at(25).unwrap()[2], -3.0);
        assert!(Bridge::new(Distro::Jazzy, &[], &[]).odometry_at(1).is_none());
    }

    /// rviz's *2D Pose Estimate* (σ 0.5 m, 0.26 rad) starts tracking there;
    /// a wide one searches around it; what is no pose in `map` is refused.
    #[test]
    fn initial_poses_set_search_or_are_refused() {
        use crate::bag::msgs::Covariance;
        let msg = |frame: &str, x: f64, vxy: f64, vt: f64| {
            let mut c = [0.0; 36];
            (c[0], c[7], c[35]) = (vxy, vxy, vt);
            PoseWithCovarianceStamped {
                header: header(0, frame),
                pose: PoseWithCovariance { pose: pose([x, 2.0, 1.0]), covariance: Covariance(c) },
            }
        };
        let wide = [1.0, 0.5];
        match initial_pose_command(&msg("map", 1.0, 0.25, 0.0685), wide) {
            Ok(ToController::SetPose { pose, sigma }) => {
                assert_eq!(pose, [1.0, 2.0, 1.0]);
                assert!((sigma[0] - 0.5).abs() < 1e-6 && (sigma[2] - 0.0685f32.sqrt()).abs() < 1e-6);
            }
            o => panic!("{o:?}"),
        }
        assert!(matches!(
            initial_pose_command(&msg("/map", 1.0, 9.0, 0.1), wide),
            Ok(ToController::Search { around: Some((_, s)) }) if s[0] == 3.0
        ));
        assert!(matches!(initial_pose_command(&msg("map", 1.0, 0.0, 1.0), wide), Ok(ToController::Search { .. })));
        assert!(initial_pose_command(&msg("odom", 1.0, 0.25, 0.07), wide).unwrap_err().contains("frame"));
        assert!(initial_pose_command(&msg("map", f64::NAN, 0.25, 0.07), wide).unwrap_err().contains("finite"));
        assert!(initial_pose_command(&msg("map", 1.0, f64::INFINITY, 0.07), wide).unwrap_err().contains("finite"));
        assert!(initial_pose_command(&msg("map", 1.0, -0.25, 0.07), wide).unwrap_err().contains("negative"));
        let mut m = msg("map", 1.0, 0.25, 0.07);
        m.pose.pose.orientation = crate::bag::msgs::Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 0.0 };
        assert!(initial_pose_command(&m, wide).unwrap_err().contains("orientation"));
    }
}
