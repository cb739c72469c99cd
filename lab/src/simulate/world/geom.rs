//! Plain geometry in metres: the map's true outlines read once, and the
//! distances the route and clutter placement are checked with.

use echoloc::map::{MapSource, ObstacleKind};

/// A point, m.
pub type P = (f64, f64);

/// One true convex piece of the map (or of the clutter), in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Outline {
    /// The map obstacle it belongs to (for clutter, an index of its own).
    pub obstacle: u16,
    /// Vertices, counter-clockwise; two for a wall (a thin segment).
    pub pts: Vec<P>,
}

/// The map's true pieces, in metres (read once; no map query is used).
pub fn map_outlines<M: MapSource>(map: &M) -> Vec<Outline> {
    map.pieces_iter()
        .map(|p| Outline {
            obstacle: p.obstacle,
            pts: p.shape.vertices().iter().map(|v| (f64::from(v.x) / 1000.0, f64::from(v.y) / 1000.0)).collect(),
        })
        .collect()
}

/// The area of each map obstacle, m² (0 for walls).
pub fn obstacle_areas<M: MapSource>(map: &M, outlines: &[Outline]) -> Vec<f64> {
    let mut area = vec![0.0; map.obstacle_count()];
    for o in outlines {
        if let Some(a) = area.get_mut(usize::from(o.obstacle)) {
            *a += polygon_area(&o.pts);
        }
    }
    area
}

/// Whether map obstacle `i` is a wall.
pub fn is_wall_obstacle<M: MapSource>(map: &M, i: usize) -> bool {
    u16::try_from(i).ok().and_then(|i| map.obstacle(i)).is_some_and(|o| o.kind == ObstacleKind::Wall)
}

/// Signed area of a polygon (positive counter-clockwise), m²; 0 for a segment.
pub fn polygon_area(pts: &[P]) -> f64 {
    let n = pts.len();
    if n < 3 {
        return 0.0;
    }
    let s: f64 = (0..n).map(|i| cross(pts[i], pts[(i + 1) % n])).sum();
    s / 2.0
}

/// `a × b`.
pub fn cross(a: P, b: P) -> f64 {
    a.0 * b.1 - a.1 * b.0
}

/// Distance from `p` to the segment `a b`.
pub fn seg_dist(p: P, a: P, b: P) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 { (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    libm::hypot(p.0 - a.0 - t * dx, p.1 - a.1 - t * dy)
}

/// Distance from `p` to a convex outline (0 inside a solid one).
pub fn outline_dist(p: P, pts: &[P]) -> f64 {
    let n = pts.len();
    if n >= 3 && (0..n).all(|i| cross(sub(pts[(i + 1) % n], pts[i]), sub(p, pts[i])) >= 0.0) {
        return 0.0;
    }
    let edges = if n == 2 { 1 } else { n };
    (0..edges).map(|i| seg_dist(p, pts[i], pts[(i + 1) % n])).fold(f64::INFINITY, f64::min)
}

/// `a − b`.
pub fn sub(a: P, b: P) -> P {
    (a.0 - b.0, a.1 - b.1)
}

/// Bounding box `(min, max)` of some points, or `None` if there are none.
pub fn bbox<'a>(pts: impl IntoIterator<Item = &'a P>) -> Option<(P, P)> {
    pts.into_iter().fold(None, |acc, &p| match acc {
        None => Some((p, p)),
        Some((lo, hi)) => Some(((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))),
    })
}

/// A rectangle `w × h` centred on `c`, turned by `angle`, counter-clockwise.
pub fn rectangle(c: P, w: f64, h: f64, angle: f64) -> Vec<P> {
    let (s, co) = (libm::sin(angle), libm::cos(angle));
    [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
        .iter()
        .map(|&(u, v)| {
            let (x, y) = (u * w, v * h);
            (c.0 + co * x - s * y, c.1 + s * x + co * y)
        })
        .collect()
}

pub use crate::angle::wrap;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_to_outlines() {
        let sq = vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
        assert_eq!(outline_dist((0.5, 0.5), &sq), 0.0);
        assert!((outline_dist((2.0, 0.5), &sq) - 1.0).abs() < 1e-12);
        assert!((outline_dist((2.0, 2.0), &sq) - 2f64.sqrt()).abs() < 1e-12);
        let wall = vec![(0.0, 0.0), (2.0, 0.0)];
        assert!((outline_dist((1.0, -0.3), &wall) - 0.3).abs() < 1e-12);
        assert!((polygon_area(&sq) - 1.0).abs() < 1e-12);
        assert!((polygon_area(&rectangle((3.0, 1.0), 0.4, 1.2, 0.7)) - 0.48).abs() < 1e-12);
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
    }
}
