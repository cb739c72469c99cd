//! Range measurement models (Leonard & Durrant-Whyte, DESIGN §4.6) and the
//! odometry motion model, with analytic Jacobians. Metres and radians, `f32`.

use crate::f32math::{sin_cos, sqrt};
use crate::geometry::Point;
use crate::map::MapSource;
use crate::predict::{Case, Mount, Prediction};

/// What a predicted echo comes from, in the map frame (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Target {
    /// A plane (Case I): the range is the perpendicular distance from the
    /// transducer to the line through `point` with unit normal `normal`.
    Plane {
        /// A point on the line, m.
        point: [f32; 2],
        /// Its unit normal, m.
        normal: [f32; 2],
    },
    /// A point (Cases II/III: a corner or a clipped edge end): the range is
    /// the distance to it.
    Point {
        /// The point, m.
        point: [f32; 2],
    },
}

impl Target {
    /// The target a prediction stands for: its edge's line for Case I, the
    /// predicted echo point otherwise. `None` if the prediction's piece or
    /// edge is not in `map` (a prediction from another map).
    pub fn of<M: MapSource + ?Sized>(map: &M, p: &Prediction) -> Option<Self> {
        let mm = |q: Point| [q.x as f32 / 1000.0, q.y as f32 / 1000.0];
        if p.case != Case::I {
            return Some(Target::Point { point: mm(p.point) });
        }
        let piece = map.piece(p.piece)?;
        if usize::from(p.edge) >= piece.shape.edge_count() {
            return None;
        }
        let (a, b) = piece.shape.edge(usize::from(p.edge));
        // Normal from the exact integer direction, normalised once in f32.
        let (ex, ey) = ((b.x as i64 - a.x as i64) as f32, (b.y as i64 - a.y as i64) as f32);
        let len = sqrt(ex * ex + ey * ey);
        if len == 0.0 {
            return None;
        }
        Some(Target::Plane { point: mm(a), normal: [ey / len, -ex / len] })
    }
}

/// A transducer's mount in metres and radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MountM {
    /// Forward, m.
    pub x: f32,
    /// Left, m.
    pub y: f32,
}

impl From<&Mount> for MountM {
    fn from(m: &Mount) -> Self {
        Self { x: m.x_mm as f32 / 1000.0, y: m.y_mm as f32 / 1000.0 }
    }
}

/// The transducer's position for robot pose `x` = (x, y, φ) and its
/// derivative by φ: `pose ∘ mount` carries the mount offset rotated by φ.
pub fn sensor_position(x: &[f32; 3], m: MountM) -> ([f32; 2], [f32; 2]) {
    let (s, c) = sin_cos(x[2]);
    let p = [x[0] + c * m.x - s * m.y, x[1] + s * m.x + c * m.y];
    let dp = [-s * m.x - c * m.y, c * m.x - s * m.y];
    (p, dp)
}

/// The predicted range h(x), m, of `target` seen from the transducer at
/// `mount` on a robot at `x`, and its Jacobian ∂h/∂(x, y, φ). `None` where h
/// is not differentiable (the transducer on the point itself).
pub fn range_model(x: &[f32; 3], mount: MountM, target: &Target) -> Option<(f32, [f32; 3])> {
    let (s, ds) = sensor_position(x, mount);
    match *target {
        Target::Plane { point, normal } => {
            let g = normal[0] * (s[0] - point[0]) + normal[1] * (s[1] - point[1]);
            // |g| is smooth away from the line; the sign says which side the transducer is on.
            let sign = if g < 0.0 { -1.0 } else { 1.0 };
            let dphi = normal[0] * ds[0] + normal[1] * ds[1];
            Some((g * sign, [sign * normal[0], sign * normal[1], sign * dphi]))
        }
        Target::Point { point } => {
            let d = [s[0] - point[0], s[1] - point[1]];
            let h = sqrt(d[0] * d[0] + d[1] * d[1]);
            if h.is_nan() || h <= 1e-6 {
                return None;
            }
            let u = [d[0] / h, d[1] / h];
            Some((h, [u[0], u[1], u[0] * ds[0] + u[1] * ds[1]]))
        }
    }
}

/// A motion in the robot's frame at its start: forward, left (m) and turn
/// (rad), the increment between two odometry poses.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Motion {
    /// Forward, m.
    pub dx: f32,
    /// Left, m.
    pub dy: f32,
    /// Turn, rad.
    pub dphi: f32,
}

impl Motion {
    /// The increment from odometry pose `a` to `b` (x, y, θ), expressed in
    /// `a`'s frame, as a robot's cumulative odometry gives them (θ may be
    /// wrapped or not: the turn is reduced to (−π, π]).
    pub fn between(a: [f32; 3], b: [f32; 3]) -> Self {
        let (s, c) = sin_cos(a[2]);
        let (gx, gy) = (b[0] - a[0], b[1] - a[1]);
        Self { dx: c * gx + s * gy, dy: -s * gx + c * gy, dphi: wrap(b[2] - a[2]) }
    }

    /// Every component finite.
    pub fn is_finite(&self) -> bool {
        self.dx.is_finite() && self.dy.is_finite() && self.dphi.is_finite()
    }
}

/// `x ⊕ u`, with its Jacobians by `x` (F) and by `u` (G).
pub fn compose(x: &[f32; 3], u: &Motion) -> ([f32; 3], [[f32; 3]; 3], [[f32; 3]; 3]) {
    let (s, c) = sin_cos(x[2]);
    let next = [x[0] + c * u.dx - s * u.dy, x[1] + s * u.dx + c * u.dy, wrap(x[2] + u.dphi)];
    let f = [[1.0, 0.0, -s * u.dx - c * u.dy], [0.0, 1.0, c * u.dx - s * u.dy], [0.0, 0.0, 1.0]];
    let g = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    (next, f, g)
}

/// An angle reduced to (−π, π].
pub fn wrap(a: f32) -> f32 {
    use core::f32::consts::PI;
    if a > -PI && a <= PI {
        return a;
    }
    let r = a - 2.0 * PI * libm::floorf((a + PI) / (2.0 * PI));
    // floorf rounding can leave the result a hair outside: fold it back.
    if r <= -PI {
        r + 2.0 * PI
    } else if r > PI {
        r - 2.0 * PI
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_reduces() {
        use core::f32::consts::PI;
        for a in [0.0f32, 1.0, -1.0, 3.0, 4.0, -4.0, 100.0, -100.0, PI, -PI] {
            let w = wrap(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            assert!(
                libm::fabsf(libm::sinf(w) - libm::sinf(a)) < 1e-3 && libm::fabsf(libm::cosf(w) - libm::cosf(a)) < 1e-3
            );
        }
    }

    #[test]
    fn plane_range_by_hand() {
        // Wall x = 2 m, robot at (0.5, 0, 0), mount 0.2 m forward: 1.3 m.
        let t = Target::Plane { point: [2.0, -1.0], normal: [-1.0, 0.0] };
        let (h, j) = range_model(&[0.5, 0.0, 0.0], MountM { x: 0.2, y: 0.0 }, &t).unwrap();
        assert!((h - 1.3).abs() < 1e-6);
        // Moving towards the wall shortens the range; turning moves the mount sideways only.
        assert_eq!(j, [-1.0, 0.0, 0.0]);
    }

    #[test]
    fn motion_round_trip() {
        let a = [1.0f32, 2.0, 0.7];
        let u = Motion { dx: 0.3, dy: -0.1, dphi: 0.2 };
        let (b, _, _) = compose(&a, &u);
        let v = Motion::between(a, b);
        assert!((v.dx - u.dx).abs() < 1e-6 && (v.dy - u.dy).abs() < 1e-6 && (v.dphi - u.dphi).abs() < 1e-6);
    }
}
