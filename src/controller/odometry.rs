//! The robot's odometry as it arrives from its main computer: cumulative
//! poses in the odometry frame, time-stamped, at the robot's own rate (say
//! 50 Hz), independent of when the transducers fire. [`OdometrySync`] keeps
//! the last `N` samples and gives the increment from the previous reading
//! to the next, interpolating between the two samples around the reading's
//! time. Cumulative poses rather than increments: a lost message loses no
//! motion, only resolution.
//!
//! ```
//! use echoloc::controller::{OdometrySample, OdometrySync};
//!
//! let mut odo = OdometrySync::<8>::new();
//! odo.push(OdometrySample { time_us: 0, pose: [1.0, 0.0, 0.0] }).unwrap();
//! odo.push(OdometrySample { time_us: 20_000, pose: [1.2, 0.0, 0.0] }).unwrap();
//! // The first reading anchors the track: no motion before it.
//! assert_eq!(odo.increment_to(5_000).unwrap().dx, 0.0);
//! // 10 ms later the robot has gone 0.1 m (a quarter of the way is 0.05 m).
//! let u = odo.increment_to(15_000).unwrap();
//! assert!((u.dx - 0.1).abs() < 1e-6 && u.dy == 0.0);
//! // Beyond the newest sample the controller must wait for more.
//! assert!(odo.increment_to(25_000).is_err());
//! ```

use heapless::Deque;

use crate::f32math::sin_cos;
use crate::referencing::{wrap, Motion};

/// One odometry message: the robot's cumulative pose at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OdometrySample {
    /// The controller's clock, µs (wrapping).
    pub time_us: u32,
    /// x, y (m), θ (rad) in the odometry frame.
    pub pose: [f32; 3],
}

/// Why a sample was refused or an increment cannot be given yet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OdometryError {
    /// A non-finite number in the sample.
    NotFinite,
    /// Not later than the newest sample held.
    OutOfOrder,
    /// No sample at or after the time asked: wait for the next message.
    NotYet,
    /// The time asked is older than every sample held (the reading came
    /// too late, or the buffer is too short for the message rate).
    TooOld,
}

impl core::fmt::Display for OdometryError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::NotFinite => "odometry sample with a non-finite number",
            Self::OutOfOrder => "odometry sample not later than the one before",
            Self::NotYet => "no odometry up to the reading's time yet",
            Self::TooOld => "the reading is older than every odometry sample held",
        })
    }
}

impl core::error::Error for OdometryError {}

/// `b` is at or after `a` (wrapping, less than 2³¹ µs apart).
fn at_or_after(a: u32, b: u32) -> bool {
    (b.wrapping_sub(a) as i32) >= 0
}

/// The last `N` (at least 2) odometry samples and the pose at the last reading.
#[derive(Clone, Debug)]
pub struct OdometrySync<const N: usize> {
    samples: Deque<OdometrySample, N>,
    last: Option<[f32; 3]>,
}

impl<const N: usize> Default for OdometrySync<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> OdometrySync<N> {
    const ROOM: () = assert!(N >= 2, "interpolation needs two samples");

    /// Empty.
    pub const fn new() -> Self {
        let () = Self::ROOM;
        Self { samples: Deque::new(), last: None }
    }

    /// Takes a sample; when full, the oldest is dropped.
    pub fn push(&mut self, s: OdometrySample) -> Result<(), OdometryError> {
        if !s.pose.iter().all(|v| v.is_finite()) {
            return Err(OdometryError::NotFinite);
        }
        if let Some(newest) = self.samples.back() {
            if at_or_after(s.time_us, newest.time_us) {
                return Err(OdometryError::OutOfOrder);
            }
        }
        if self.samples.is_full() {
            self.samples.pop_front();
        }
        // Room was just made.
        let _ = self.samples.push_back(s);
        Ok(())
    }

    /// The newest sample's time, if any.
    pub fn newest_us(&self) -> Option<u32> {
        self.samples.back().map(|s| s.time_us)
    }

    /// Whether [`increment_to`](Self::increment_to) can answer for `t` now.
    pub fn covers(&self, t: u32) -> bool {
        self.newest_us().is_some_and(|n| at_or_after(t, n))
    }

    /// The odometry pose at `t`, interpolated between the samples around it.
    pub fn pose_at(&self, t: u32) -> Result<[f32; 3], OdometryError> {
        let newest = self.samples.back().ok_or(OdometryError::NotYet)?;
        if !at_or_after(t, newest.time_us) {
            return Err(OdometryError::NotYet);
        }
        let mut before: Option<&OdometrySample> = None;
        for s in self.samples.iter() {
            if at_or_after(s.time_us, t) {
                before = Some(s);
            } else {
                let Some(b) = before else { return Err(OdometryError::TooOld) };
                let span = s.time_us.wrapping_sub(b.time_us) as f32;
                let k = t.wrapping_sub(b.time_us) as f32 / span;
                let dth = wrap(s.pose[2] - b.pose[2]);
                return Ok([
                    b.pose[0] + k * (s.pose[0] - b.pose[0]),
                    b.pose[1] + k * (s.pose[1] - b.pose[1]),
                    wrap(b.pose[2] + k * dth),
                ]);
            }
        }
        // `t` is at or after every sample and the newest is at or after `t`.
        Ok(newest.pose)
    }

    /// The motion from the previous call's time to `t`, in the robot's frame
    /// at the previous call (zero at the first call, which anchors the
    /// track). Samples older than the one at or before `t` are dropped.
    pub fn increment_to(&mut self, t: u32) -> Result<Motion, OdometryError> {
        let p = self.pose_at(t)?;
        let u = match self.last {
            Some(a) => relative(&a, &p),
            None => Motion { dx: 0.0, dy: 0.0, dphi: 0.0 },
        };
        self.last = Some(p);
        while self.samples.len() >= 2 && self.samples.iter().nth(1).is_some_and(|s| at_or_after(s.time_us, t)) {
            self.samples.pop_front();
        }
        Ok(u)
    }
}

/// `b` seen from `a`: the motion that takes pose `a` to pose `b`.
pub fn relative(a: &[f32; 3], b: &[f32; 3]) -> Motion {
    let (s, c) = sin_cos(a[2]);
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    Motion { dx: c * dx + s * dy, dy: -s * dx + c * dy, dphi: wrap(b[2] - a[2]) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::referencing::compose;

    #[test]
    fn relative_inverts_compose() {
        for (a, u) in [
            ([1.0f32, 2.0, 0.3], Motion { dx: 0.2, dy: -0.05, dphi: 0.1 }),
            ([-3.0, 0.5, 3.1], Motion { dx: 0.0, dy: 0.3, dphi: 0.2 }),
            ([0.0, 0.0, -1.7], Motion { dx: -0.1, dy: 0.0, dphi: -0.05 }),
        ] {
            let (b, _, _) = compose(&a, &u);
            let r = relative(&a, &b);
            assert!(
                (r.dx - u.dx).abs() < 1e-5 && (r.dy - u.dy).abs() < 1e-5 && (r.dphi - u.dphi).abs() < 1e-5,
                "{r:?}"
            );
        }
    }

    #[test]
    fn interpolates_across_the_angle_wrap_and_refuses_bad_samples() {
        let mut o = OdometrySync::<4>::new();
        o.push(OdometrySample { time_us: 100, pose: [0.0, 0.0, 3.1] }).unwrap();
        o.push(OdometrySample { time_us: 300, pose: [0.0, 0.0, -3.1] }).unwrap();
        // Half way round the wrap: π, not 0.
        let p = o.pose_at(200).unwrap();
        assert!((p[2].abs() - core::f32::consts::PI).abs() < 1e-5, "{p:?}");
        assert_eq!(o.push(OdometrySample { time_us: 300, pose: [0.0; 3] }), Err(OdometryError::OutOfOrder));
        assert_eq!(o.push(OdometrySample { time_us: 400, pose: [f32::NAN, 0.0, 0.0] }), Err(OdometryError::NotFinite));
        assert_eq!(o.pose_at(50), Err(OdometryError::TooOld));
        assert_eq!(o.pose_at(301), Err(OdometryError::NotYet));
    }

    #[test]
    fn a_full_buffer_drops_the_oldest_and_time_wraps() {
        let mut o = OdometrySync::<2>::new();
        let t0 = u32::MAX - 50;
        for k in 0..4u32 {
            o.push(OdometrySample { time_us: t0.wrapping_add(40 * k), pose: [k as f32, 0.0, 0.0] }).unwrap();
        }
        // Samples at t0+80 (x = 2) and t0+120 (x = 3), across the wrap.
        assert_eq!(o.pose_at(t0.wrapping_add(60)), Err(OdometryError::TooOld));
        assert_eq!(o.pose_at(t0.wrapping_add(100)).unwrap()[0], 2.5);
        assert!(o.covers(t0.wrapping_add(120)) && !o.covers(t0.wrapping_add(121)));
    }
}
