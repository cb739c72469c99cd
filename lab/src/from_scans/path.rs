//! The robot's path between a lidar run's scans, and its timing.
//!
//! The logs keep one scan per 0.5–1 m of travel; the ring fires every
//! 0.6 s along the way. Between two scans the robot drives a cubic Hermite
//! curve whose ends point along the scans' headings (a differential drive
//! goes where it points, so its odometry sees no sideways slip); where a
//! scan's heading is far from the way to the next (a turn on the spot, or
//! backing up), it turns in place towards it, drives straight, and turns
//! to the next heading. A step shorter than 5 cm is a turn on the spot.
//!
//! Time: the logged stamps, where they are possible; a step logged faster
//! than [`MAX_SPEED_M_S`] or [`MAX_TURN_DEG_S`] allows (or backwards: the
//! Intel log has four stamps earlier than the one before) takes the time
//! those limits need, and is counted as retimed.

use crate::lidar::Scan;
use crate::simulate::world::{wrap, Trajectory};

/// Fastest the robot drives between two scans, m/s (a Pioneer's top speed
/// is 1.2 m/s; the Intel robot averages 0.19 m/s).
pub const MAX_SPEED_M_S: f64 = 1.0;
/// Fastest it turns, °/s.
pub const MAX_TURN_DEG_S: f64 = 100.0;
/// The shortest time between two scans, s.
const MIN_STEP_S: f64 = 0.05;
/// A step shorter than this is a turn on the spot, m.
const SPOT_M: f64 = 0.05;
/// A heading further than this from the way to the next scan is a turn
/// before driving, not a curve, degrees.
const CURVE_MAX_DEG: f64 = 75.0;
/// Samples of the path, m and degrees apart at most.
const SAMPLE_M: f64 = 0.02;
const SAMPLE_DEG: f64 = 2.0;

/// The path through a run's scans.
#[derive(Clone, Debug)]
pub struct RunPath {
    /// The robot's motion, from t = 0 at the first scan.
    pub traj: Trajectory,
    /// When the robot passes each scan, s on the path's clock.
    pub scan_times: Vec<f64>,
    /// Steps whose logged time was impossible (backwards or too fast).
    pub retimed: usize,
    /// Steps driven as turn, straight, turn (not a curve).
    pub turn_drive_turn: usize,
}

type Pose = (f64, f64, f64);

/// The path through `scans` (their robot poses, in order).
pub fn through(scans: &[Scan]) -> RunPath {
    let mut keys: Vec<(f64, Pose)> = Vec::new();
    let mut scan_times = Vec::with_capacity(scans.len());
    let (mut retimed, mut tdt) = (0, 0);
    let Some(first) = scans.first() else {
        return RunPath { traj: Trajectory::through(&[]), scan_times, retimed, turn_drive_turn: 0 };
    };
    let mut at: Pose = (first.robot[0], first.robot[1], first.robot[2]);
    let mut t = 0.0;
    keys.push((t, at));
    scan_times.push(t);
    for w in scans.windows(2) {
        let b = (w[1].robot[0], w[1].robot[1], at.2 + wrap(w[1].robot[2] - at.2));
        let (samples, len, turn, curved) = step(at, b);
        tdt += usize::from(!curved);
        let need = (len / MAX_SPEED_M_S).max(turn.abs() / MAX_TURN_DEG_S.to_radians()).max(MIN_STEP_S);
        let logged = w[1].time_s - w[0].time_s;
        let dt = if logged.is_finite() && logged >= need {
            logged
        } else {
            retimed += 1;
            need
        };
        // Time along the step in proportion to the distance and turn of each sample.
        let cost = |a: Pose, b: Pose| {
            ((b.0 - a.0).hypot(b.1 - a.1) / MAX_SPEED_M_S).max((b.2 - a.2).abs() / MAX_TURN_DEG_S.to_radians())
        };
        let total: f64 =
            std::iter::once(at).chain(samples.iter().copied()).zip(samples.iter()).map(|(a, &b)| cost(a, b)).sum();
        let mut prev = at;
        let mut acc = 0.0;
        for &p in &samples {
            acc += cost(prev, p);
            let s = if total > 0.0 { acc / total } else { 1.0 };
            keys.push((t + dt * s, p));
            prev = p;
        }
        t += dt;
        at = b;
        if let Some(last) = keys.last_mut() {
            *last = (t, b);
        }
        scan_times.push(t);
    }
    RunPath { traj: Trajectory::through(&keys), scan_times, retimed, turn_drive_turn: tdt }
}

/// The samples from `a` to `b` (excluding `a`, ending at `b`), the step's
/// length and turn, and whether it is a curve.
fn step(a: Pose, b: Pose) -> (Vec<Pose>, f64, f64, bool) {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len = dx.hypot(dy);
    let turn = b.2 - a.2;
    let n_for =
        |l: f64, th: f64| ((l / SAMPLE_M).ceil().max((th.abs().to_degrees() / SAMPLE_DEG).ceil()) as usize).max(1);
    if len < SPOT_M {
        let n = n_for(len, turn);
        let v = (1..=n).map(|k| lerp(a, b, k as f64 / n as f64)).collect();
        return (v, len, turn, true);
    }
    let chord = dy.atan2(dx);
    // Forward when the headings face the way, backwards when both face away.
    let fwd =
        wrap(chord - a.2).abs().to_degrees() <= CURVE_MAX_DEG && wrap(chord - b.2).abs().to_degrees() <= CURVE_MAX_DEG;
    let back = (180.0 - wrap(chord - a.2).abs().to_degrees()) <= CURVE_MAX_DEG
        && (180.0 - wrap(chord - b.2).abs().to_degrees()) <= CURVE_MAX_DEG;
    if fwd || back {
        let sgn = if fwd { 1.0 } else { -1.0 };
        let (ta, tb) = ((a.2.cos() * sgn * len, a.2.sin() * sgn * len), (b.2.cos() * sgn * len, b.2.sin() * sgn * len));
        let n = n_for(len * 1.2, turn);
        let mut out = Vec::with_capacity(n);
        let mut h = a.2;
        for k in 1..=n {
            let s = k as f64 / n as f64;
            let (p, d) = hermite(a, b, ta, tb, s);
            let dir = d.1.atan2(d.0) + if fwd { 0.0 } else { std::f64::consts::PI };
            h += wrap(dir - h);
            out.push((p.0, p.1, h));
        }
        // The end on the scan's own heading (the same angle, unwrapped alike).
        if let Some(last) = out.last_mut() {
            *last = b;
        }
        return (out, len, turn, true);
    }
    // Turn towards the way (or away from it, whichever is nearer), drive, turn.
    let face =
        if wrap(chord - a.2).abs() <= std::f64::consts::FRAC_PI_2 { chord } else { chord + std::f64::consts::PI };
    let h1 = a.2 + wrap(face - a.2);
    let mid_a = (a.0, a.1, h1);
    let mid_b = (b.0, b.1, h1);
    let mut out = Vec::new();
    for (from, to) in [(a, mid_a), (mid_a, mid_b), (mid_b, b)] {
        let n = n_for((to.0 - from.0).hypot(to.1 - from.1), to.2 - from.2);
        out.extend((1..=n).map(|k| lerp(from, to, k as f64 / n as f64)));
    }
    let total_turn = (h1 - a.2).abs() + (b.2 - h1).abs();
    (out, len, total_turn.copysign(turn), false)
}

/// The Hermite curve from `a` to `b` with end tangents `ta`, `tb` at `s`: the point and the tangent.
fn hermite(a: Pose, b: Pose, ta: (f64, f64), tb: (f64, f64), s: f64) -> ((f64, f64), (f64, f64)) {
    let (s2, s3) = (s * s, s * s * s);
    let (h00, h10, h01, h11) = (2.0 * s3 - 3.0 * s2 + 1.0, s3 - 2.0 * s2 + s, -2.0 * s3 + 3.0 * s2, s3 - s2);
    let (d00, d10, d01, d11) = (6.0 * s2 - 6.0 * s, 3.0 * s2 - 4.0 * s + 1.0, -6.0 * s2 + 6.0 * s, 3.0 * s2 - 2.0 * s);
    let p = (h00 * a.0 + h10 * ta.0 + h01 * b.0 + h11 * tb.0, h00 * a.1 + h10 * ta.1 + h01 * b.1 + h11 * tb.1);
    let d = (d00 * a.0 + d10 * ta.0 + d01 * b.0 + d11 * tb.0, d00 * a.1 + d10 * ta.1 + d01 * b.1 + d11 * tb.1);
    (p, d)
}

fn lerp(a: Pose, b: Pose, s: f64) -> Pose {
    (a.0 + (b.0 - a.0) * s, a.1 + (b.1 - a.1) * s, a.2 + (b.2 - a.2) * s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(t: f64, x: f64, y: f64, th: f64) -> Scan {
        Scan {
            time_s: t,
            robot: [x, y, th],
            laser: [x, y, th],
            odometry: None,
            angle_min: 0.0,
            angle_step: 0.1,
            ranges: vec![1.0, 1.0],
            line: 0,
        }
    }

    #[test]
    fn the_path_passes_every_scan_on_its_heading() {
        let scans = [
            scan(0.0, 0.0, 0.0, 0.0),
            scan(4.0, 1.0, 0.2, 0.4),
            scan(3.0, 1.5, 1.0, 1.6),   // earlier than the scan before: retimed
            scan(9.0, 1.5, 1.0, -2.0),  // a turn on the spot
            scan(12.0, 0.7, 1.0, -3.1), // a step backwards? No: θ −3.1 faces −x, the way it goes
        ];
        let p = through(&scans);
        assert_eq!(p.scan_times.len(), scans.len());
        assert_eq!(p.retimed, 1);
        for (s, &t) in scans.iter().zip(&p.scan_times) {
            let q = p.traj.pose(t);
            assert!((q.0 - s.robot[0]).abs() < 1e-9 && (q.1 - s.robot[1]).abs() < 1e-9, "{q:?} {s:?}");
            assert!(wrap(q.2 - s.robot[2]).abs() < 1e-9, "{q:?} {s:?}");
        }
        // Logged times kept where possible: the second scan at 4 s.
        assert!((p.scan_times[1] - 4.0).abs() < 1e-12);
    }

    #[test]
    fn a_curve_heads_where_it_goes() {
        // Between two scans the robot's heading is the curve's direction:
        // a small step along the heading moves the robot along the path.
        let p = through(&[scan(0.0, 0.0, 0.0, 0.0), scan(5.0, 1.0, 0.5, 0.9)]);
        for k in 1..99 {
            let t = 5.0 * f64::from(k) / 100.0;
            let (a, b) = (p.traj.pose(t), p.traj.pose(t + 0.01));
            let dir = (b.1 - a.1).atan2(b.0 - a.0);
            assert!(wrap(dir - a.2).abs() < 0.06, "at {t}: moving {dir}, heading {}", a.2);
        }
    }
}
