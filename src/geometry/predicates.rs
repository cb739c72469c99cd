//! Exact orientation and intersection predicates on in-range points.

use super::Point;

/// Cross product of two difference vectors, exact in `i64` when every
/// component lies within `±(2³¹ − 1)`.
///
/// That is the domain: every difference of two in-range points
/// ([`Point::sub`], `|·| ≤ 2·COORD_MAX`), the windows' edge directions
/// (`|·| ≤ 2¹⁴`). There each product is below `2⁶²` and the difference
/// below `2⁶³`, so the two's-complement (wrapping) operations below are the
/// exact ones; wider components are outside the contract and wrap
/// (the property test checks exactness over the whole domain against
/// `i128`).
#[inline]
pub const fn cross(u: (i64, i64), v: (i64, i64)) -> i64 {
    u.0.wrapping_mul(v.1).wrapping_sub(u.1.wrapping_mul(v.0))
}

/// Dot product of two difference vectors, exact in `i64` when every
/// component lies within `±(2³¹ − 1)` (the domain of [`cross`]: each
/// product is at most `(2³¹ − 1)² < 2⁶²`, their sum below `2⁶³`).
#[inline]
pub const fn dot(u: (i64, i64), v: (i64, i64)) -> i64 {
    u.0.wrapping_mul(v.0).wrapping_add(u.1.wrapping_mul(v.1))
}

/// Twice the signed area of triangle `abc`: positive when `c` lies to the left
/// of the directed line `a→b` (counter-clockwise turn), zero when collinear.
#[inline]
pub const fn orient(a: Point, b: Point, c: Point) -> i64 {
    cross(b.sub(a), c.sub(a))
}

/// Which side of a directed line a point lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Side {
    /// Strictly left (counter-clockwise).
    Left,
    /// On the line.
    On,
    /// Strictly right (clockwise).
    Right,
}

impl Side {
    /// The side of `c` relative to the directed line `a→b`.
    pub const fn of(a: Point, b: Point, c: Point) -> Side {
        let o = orient(a, b, c);
        if o > 0 {
            Side::Left
        } else if o < 0 {
            Side::Right
        } else {
            Side::On
        }
    }
}

/// Whether `p` lies on the closed segment `ab`.
pub const fn point_on_segment(p: Point, a: Point, b: Point) -> bool {
    orient(a, b, p) == 0
        && (if a.x < b.x { a.x } else { b.x }) <= p.x
        && p.x <= (if a.x > b.x { a.x } else { b.x })
        && (if a.y < b.y { a.y } else { b.y }) <= p.y
        && p.y <= (if a.y > b.y { a.y } else { b.y })
}

/// Whether the closed segments `ab` and `cd` share at least one point
/// (touching and collinear overlap included).
pub const fn segments_intersect(a: Point, b: Point, c: Point, d: Point) -> bool {
    let o1 = orient(a, b, c).signum();
    let o2 = orient(a, b, d).signum();
    let o3 = orient(c, d, a).signum();
    let o4 = orient(c, d, b).signum();
    if o1 * o2 < 0 && o3 * o4 < 0 {
        return true;
    }
    (o1 == 0 && point_on_segment(c, a, b))
        || (o2 == 0 && point_on_segment(d, a, b))
        || (o3 == 0 && point_on_segment(a, c, d))
        || (o4 == 0 && point_on_segment(b, c, d))
}

#[cfg(test)]
mod tests {
    use super::*;
    const fn p(x: i32, y: i32) -> Point {
        Point::new(x, y)
    }

    #[test]
    fn orientation_signs() {
        assert!(orient(p(0, 0), p(10, 0), p(5, 1)) > 0);
        assert!(orient(p(0, 0), p(10, 0), p(5, -1)) < 0);
        assert_eq!(orient(p(0, 0), p(10, 0), p(20, 0)), 0);
    }

    #[test]
    fn extreme_coordinates_do_not_overflow() {
        use crate::geometry::COORD_MAX as M;
        // The largest possible cross product magnitude.
        let o = orient(p(-M, -M), p(M, -M), p(-M, M));
        let d = 2 * M as i64;
        assert_eq!(o, d * d);
        let o = orient(p(-M, -M), p(M, M), p(M, -M));
        assert_eq!(o, -(d * d));
    }

    #[test]
    fn intersections() {
        assert!(segments_intersect(p(0, 0), p(10, 10), p(0, 10), p(10, 0)));
        assert!(segments_intersect(p(0, 0), p(10, 0), p(10, 0), p(20, 5)), "touching end");
        assert!(segments_intersect(p(0, 0), p(10, 0), p(5, 0), p(20, 0)), "collinear overlap");
        assert!(!segments_intersect(p(0, 0), p(10, 0), p(11, 0), p(20, 0)), "collinear apart");
        assert!(!segments_intersect(p(0, 0), p(10, 0), p(0, 1), p(10, 1)), "parallel");
        assert!(segments_intersect(p(0, 0), p(10, 0), p(5, 0), p(5, 7)), "T junction");
    }
}
