//! The robot's true motion along the route, and the wheel odometry it logs.
//!
//! The robot turns in place at each waypoint (at the turn rate) and drives
//! straight between them (at the speed): the true position never leaves the
//! route, so the route's clearance is the robot's. Odometry is differential
//! drive: the true motion, sampled every [`ODOMETRY_DT_S`], becomes true
//! wheel distances over the true wheelbase; the encoders read them through
//! wrong wheel radii with random slip; the robot integrates what it read over
//! its nominal wheelbase.

use super::config::OdometryModel;
use super::geom::{wrap, P};
use crate::credence::rng::Rng;

/// Odometry integration step, s: a robot's usual 100 Hz wheel loop.
pub const ODOMETRY_DT_S: f64 = 0.01;
/// Route segments shorter than this are dropped, m.
const MIN_SEGMENT_M: f64 = 1e-9;

/// A pose: x, y (m) and heading (rad; unwrapped inside this module).
pub type Pose = (f64, f64, f64);

/// One piece of motion: from `a` to `b` linearly over `[t0, t0 + dur]`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Piece {
    t0: f64,
    dur: f64,
    a: Pose,
    b: Pose,
}

/// The true motion along the route.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    pieces: Vec<Piece>,
    start: Pose,
    duration: f64,
    /// Kidnaps: at `t` the robot is carried from the first pose to the
    /// second; its wheels do not turn.
    jumps: Vec<(f64, Pose, Pose)>,
}

impl Trajectory {
    /// Follows `route` at `speed` m/s, turning in place at `turn_rate` rad/s,
    /// starting at its first point facing along its first segment.
    pub fn new(route: &[P], speed: f64, turn_rate: f64) -> Self {
        let mut pieces = Vec::new();
        let mut t = 0.0;
        let first = route.windows(2).find(|w| seg_len(w[0], w[1]) > MIN_SEGMENT_M);
        let h0 = first.map_or(0.0, |w| libm::atan2(w[1].1 - w[0].1, w[1].0 - w[0].0));
        let start = route.first().map_or((0.0, 0.0, h0), |p| (p.0, p.1, h0));
        let mut at = start;
        for w in route.windows(2) {
            let l = seg_len(w[0], w[1]);
            if l <= MIN_SEGMENT_M {
                continue;
            }
            let dir = libm::atan2(w[1].1 - w[0].1, w[1].0 - w[0].0);
            let turn = wrap(dir - at.2);
            if turn != 0.0 {
                let b = (at.0, at.1, at.2 + turn);
                let dur = turn.abs() / turn_rate;
                pieces.push(Piece { t0: t, dur, a: at, b });
                t += dur;
                at = b;
            }
            let b = (w[1].0, w[1].1, at.2);
            let dur = l / speed;
            pieces.push(Piece { t0: t, dur, a: at, b });
            t += dur;
            at = b;
        }
        Self { pieces, start, duration: t, jumps: Vec::new() }
    }

    /// Through `keys` (time s, pose; times increasing, headings unwrapped),
    /// straight and at a steady rate between each two: a path given as
    /// dense poses (a lidar run's, `crate::from_scans::path`).
    pub fn through(keys: &[(f64, Pose)]) -> Self {
        let start = keys.first().map_or((0.0, 0.0, 0.0), |k| k.1);
        let t0 = keys.first().map_or(0.0, |k| k.0);
        let pieces = keys
            .windows(2)
            .filter(|w| w[1].0 > w[0].0)
            .map(|w| Piece { t0: w[0].0 - t0, dur: w[1].0 - w[0].0, a: w[0].1, b: w[1].1 })
            .collect();
        let duration = keys.last().map_or(0.0, |k| k.0 - t0);
        Self { pieces, start, duration, jumps: Vec::new() }
    }

    /// The pose at the end.
    pub fn end(&self) -> Pose {
        self.pieces.last().map_or(self.start, |p| p.b)
    }

    /// Distance driven (turns in place drive none) up to `t`, m.
    pub fn driven(&self, t: f64) -> f64 {
        let mut d = 0.0;
        for p in &self.pieces {
            if p.t0 >= t {
                break;
            }
            let s = if p.dur > 0.0 { ((t - p.t0) / p.dur).clamp(0.0, 1.0) } else { 1.0 };
            if !self.jumps.iter().any(|j| j.0 == p.t0 && p.dur == 0.0) {
                d += libm::hypot(p.b.0 - p.a.0, p.b.1 - p.a.1) * s;
            }
        }
        d
    }

    /// Ends the motion at `t` (cutting the piece under way there).
    pub fn cut(&mut self, t: f64) {
        let t = t.clamp(0.0, self.duration);
        self.pieces.retain(|p| p.t0 < t || (p.t0 == t && p.dur == 0.0 && t == 0.0));
        if let Some(p) = self.pieces.last_mut() {
            if p.t0 + p.dur > t && p.dur > 0.0 {
                let s = (t - p.t0) / p.dur;
                p.b = lerp(p.a, p.b, s);
                p.dur = t - p.t0;
            }
        }
        self.jumps.retain(|j| j.0 <= t);
        self.duration = t;
    }

    /// The robot is carried to `to` at the end of the motion (no time passes).
    pub fn jump(&mut self, to: Pose) {
        let from = self.end();
        let t = self.duration;
        self.pieces.push(Piece { t0: t, dur: 0.0, a: from, b: to });
        self.jumps.push((t, from, to));
    }

    /// Goes on along `route` from the end of the motion: a turn in place
    /// towards each point, then a straight drive (the route's first point
    /// is where the robot stands, or near it).
    pub fn extend(&mut self, route: &[P], speed: f64, turn_rate: f64) {
        let mut t = self.duration;
        let mut at = self.end();
        for &q in route {
            let l = seg_len((at.0, at.1), q);
            if l <= MIN_SEGMENT_M {
                continue;
            }
            let dir = libm::atan2(q.1 - at.1, q.0 - at.0);
            let turn = wrap(dir - at.2);
            if turn != 0.0 {
                let b = (at.0, at.1, at.2 + turn);
                let dur = turn.abs() / turn_rate;
                self.pieces.push(Piece { t0: t, dur, a: at, b });
                t += dur;
                at = b;
            }
            let b = (q.0, q.1, at.2);
            let dur = l / speed;
            self.pieces.push(Piece { t0: t, dur, a: at, b });
            t += dur;
            at = b;
        }
        self.duration = t;
    }

    /// The kidnaps: (time s, carried from, carried to).
    pub fn jumps(&self) -> &[(f64, Pose, Pose)] {
        &self.jumps
    }

    /// Total time, s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// The true pose at `t` (clamped to the motion's span), heading unwrapped.
    pub fn pose(&self, t: f64) -> Pose {
        let i = self.pieces.partition_point(|p| p.t0 <= t);
        let Some(p) = i.checked_sub(1).and_then(|i| self.pieces.get(i)) else {
            return self.start;
        };
        let s = if p.dur > 0.0 { ((t - p.t0) / p.dur).clamp(0.0, 1.0) } else { 1.0 };
        lerp(p.a, p.b, s)
    }
}

fn seg_len(a: P, b: P) -> f64 {
    libm::hypot(b.0 - a.0, b.1 - a.1)
}

fn lerp(a: Pose, b: Pose, s: f64) -> Pose {
    (a.0 + (b.0 - a.0) * s, a.1 + (b.1 - a.1) * s, a.2 + (b.2 - a.2) * s)
}

/// The systematic odometry errors drawn for one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryErrors {
    /// True left wheel radius over nominal.
    pub left_scale: f64,
    /// True right wheel radius over nominal.
    pub right_scale: f64,
    /// True (effective) wheelbase over nominal.
    pub wheelbase_scale: f64,
}

impl OdometryErrors {
    /// The heading corrections these errors call for, as
    /// `echoloc::referencing::calibration` states them: per radian the
    /// odometry turned, and per metre it drove forward (rad). From
    /// `Odometry::integrate`: turning in place, the odometry reads the true
    /// turn × wheelbase_scale × h, with h = (1/left + 1/right)/2; driving
    /// straight, it reads h metres a metre and turns (1/right − 1/left)/wheelbase
    /// a metre. (A correction `dφ·(1 + per_rad) + per_m·dx` scales the drift too.)
    pub fn heading_bias(&self, wheelbase_m: f64) -> (f64, f64) {
        let h = (1.0 / self.left_scale + 1.0 / self.right_scale) / 2.0;
        let per_rad = 1.0 / (self.wheelbase_scale * h) - 1.0;
        let drift = (1.0 / self.right_scale - 1.0 / self.left_scale) / wheelbase_m;
        (per_rad, -(1.0 + per_rad) * drift / h)
    }

    /// Draws the scales of `model`, each with a random sign.
    pub fn draw(model: &OdometryModel, rng: &mut Rng) -> Self {
        let sign = |rng: &mut Rng| if rng.next_f64() < 0.5 { -1.0 } else { 1.0 };
        let diff = sign(rng) * rng.uniform(model.wheel_diff.0, model.wheel_diff.1);
        let common = rng.uniform(-model.wheel_common, model.wheel_common);
        let base = sign(rng) * rng.uniform(model.wheelbase_scale.0, model.wheelbase_scale.1);
        Self {
            left_scale: 1.0 + common - diff / 2.0,
            right_scale: 1.0 + common + diff / 2.0,
            wheelbase_scale: 1.0 + base,
        }
    }
}

/// The odometry pose sampled every [`ODOMETRY_DT_S`].
#[derive(Clone, Debug, PartialEq)]
pub struct Odometry {
    poses: Vec<Pose>,
}

impl Odometry {
    /// Dead reckoning along `traj` with `errors` and the random slip of `model`.
    pub fn integrate(traj: &Trajectory, model: &OdometryModel, errors: &OdometryErrors, rng: &mut Rng) -> Self {
        let steps = (traj.duration() / ODOMETRY_DT_S).ceil() as usize + 1;
        let true_base = model.wheelbase_m * errors.wheelbase_scale;
        let mut poses = Vec::with_capacity(steps + 1);
        let mut prev = traj.pose(0.0);
        let mut odo = prev;
        poses.push(odo);
        for k in 1..=steps {
            let t = k as f64 * ODOMETRY_DT_S;
            let now = traj.pose(t);
            // A kidnap between the samples: the wheels only saw the motion
            // before it and after it, so `prev` is carried with the robot.
            for &(tj, from, to) in traj.jumps() {
                if tj > t - ODOMETRY_DT_S && tj <= t {
                    let (s, c) = (libm::sin(to.2 - from.2), libm::cos(to.2 - from.2));
                    let (dx, dy) = (prev.0 - from.0, prev.1 - from.1);
                    prev = (to.0 + c * dx - s * dy, to.1 + s * dx + c * dy, prev.2 + (to.2 - from.2));
                }
            }
            let dth = now.2 - prev.2;
            let mid = prev.2 + dth / 2.0;
            let ds = (now.0 - prev.0) * libm::cos(mid) + (now.1 - prev.1) * libm::sin(mid);
            let (dl, dr) = (ds - dth * true_base / 2.0, ds + dth * true_base / 2.0);
            let ml = dl / errors.left_scale + model.noise_m_per_sqrt_m * libm::sqrt(dl.abs()) * rng.normal();
            let mr = dr / errors.right_scale + model.noise_m_per_sqrt_m * libm::sqrt(dr.abs()) * rng.normal();
            let (ods, odth) = ((ml + mr) / 2.0, (mr - ml) / model.wheelbase_m);
            let h = odo.2 + odth / 2.0;
            odo = (odo.0 + ods * libm::cos(h), odo.1 + ods * libm::sin(h), odo.2 + odth);
            poses.push(odo);
            prev = now;
        }
        Self { poses }
    }

    /// The odometry pose at `t`, interpolated between samples (clamped to the
    /// span), heading unwrapped.
    pub fn pose(&self, t: f64) -> Pose {
        let f = (t / ODOMETRY_DT_S).max(0.0);
        let i = f.floor() as usize;
        match (self.poses.get(i), self.poses.get(i + 1)) {
            (Some(&a), Some(&b)) => lerp(a, b, f - i as f64),
            (Some(&a), None) => a,
            _ => self.poses.last().copied().unwrap_or((0.0, 0.0, 0.0)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trajectory_turns_in_place_then_drives() {
        let route = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0)];
        let t = Trajectory::new(&route, 0.5, std::f64::consts::FRAC_PI_2);
        // 4 s to (2, 0), 1 s to turn 90°, 2 s to (2, 1).
        assert!((t.duration() - 7.0).abs() < 1e-12);
        let p = t.pose(4.5);
        assert!((p.0 - 2.0).abs() < 1e-12 && p.1.abs() < 1e-12 && (p.2 - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        let p = t.pose(6.0);
        assert!((p.0 - 2.0).abs() < 1e-12 && (p.1 - 0.5).abs() < 1e-12);
        assert_eq!(t.pose(100.0), (2.0, 1.0, std::f64::consts::FRAC_PI_2));
    }

    #[test]
    fn perfect_wheels_reproduce_the_truth() {
        let route = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (-1.0, 3.0)];
        let t = Trajectory::new(&route, 0.4, 1.5);
        let model = OdometryModel { noise_m_per_sqrt_m: 0.0, ..OdometryModel::default() };
        let ideal = OdometryErrors { left_scale: 1.0, right_scale: 1.0, wheelbase_scale: 1.0 };
        let o = Odometry::integrate(&t, &model, &ideal, &mut Rng::new(1));
        let (a, b) = (t.pose(t.duration()), o.pose(t.duration()));
        // Steps that mix the end of a turn with the start of a drive are
        // integrated as arcs: a millimetre over the route.
        assert!((a.0 - b.0).abs() < 2e-3 && (a.1 - b.1).abs() < 2e-3 && (a.2 - b.2).abs() < 1e-9, "{a:?} {b:?}");
    }
}
