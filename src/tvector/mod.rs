//! t-vectors: the paper's collision primitive (DESIGN §4.2).
//!
//! The t-vector of a point `p` against a convex piece is a bit mask whose bit
//! `i` is set when `p` lies strictly outside edge `i`'s supporting line. The
//! t-vector papers are not available; this is the project's reconstruction:
//!
//! * the set bits of `t(p)` are exactly the piece's *front* surfaces seen from
//!   `p` (a surface faces `p` when `p` is on its outer side);
//! * `t(p) = 0` means `p` is inside or on the closed piece;
//! * a segment `ab` misses the piece when `t(a) & t(b) ≠ 0` — both ends are
//!   outside the same edge, like Cohen–Sutherland outcodes;
//! * otherwise the segment meets the piece unless every vertex lies strictly
//!   on one side of the line `ab`. With the edge normals already tested by
//!   the bit masks, this completes a separating-axis test, so the decision is
//!   exact.
//!
//! Walls (two-vertex pieces) get two more bits, the end caps: bit 2 when `p`
//! lies strictly before `a` along `a→b`, bit 3 when strictly beyond `b`.
//! Then `t(p) = 0` still means `p` is on the wall, and the same tests are
//! exact for walls too.
//!
//! ```
//! use echoloc::geometry::{Convex, Point};
//! let sq = [Point::new(0, 0), Point::new(10, 0), Point::new(10, 10), Point::new(0, 10)];
//! let piece = Convex::new(&sq).unwrap();
//! let t = piece.tvector(Point::new(20, 5));
//! assert_eq!(t.bits(), 0b0010);            // outside edge 1 only: x = 10 faces it
//! assert_eq!(piece.front_surfaces(t), 0b0010);
//! assert!(piece.hits_segment(Point::new(20, 5), Point::new(-5, 5)));
//! assert!(!piece.hits_segment(Point::new(20, 5), Point::new(20, 50)));
//! ```

use crate::geometry::{cross, dot, Convex, ParamRange, Point, Segment};

/// The edge-side bit mask of a point against one convex piece.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TVector(u32);

impl TVector {
    /// The raw mask: bit `i` set when strictly outside edge `i` (walls: bits 2
    /// and 3 are the end caps).
    #[inline]
    pub const fn bits(self) -> u32 {
        self.0
    }

    /// Whether the point lies inside or on the closed piece.
    #[inline]
    pub const fn is_inside(self) -> bool {
        self.0 == 0
    }

    /// The trivial reject: both points strictly outside one same edge.
    #[inline]
    pub const fn shares_outside(self, other: TVector) -> bool {
        self.0 & other.0 != 0
    }
}

/// The exact parameter at which a segment enters a piece: `num / den` of the
/// way from its start, with `0 ≤ num ≤ den` and `den > 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Entry {
    /// Numerator.
    pub num: i64,
    /// Denominator, positive.
    pub den: i64,
}

impl Entry {
    /// Compares two entries exactly.
    pub fn cmp_exact(&self, o: &Entry) -> core::cmp::Ordering {
        (self.num as i128 * o.den as i128).cmp(&(o.num as i128 * self.den as i128))
    }

    /// The point at this parameter along `seg`, rounded to the nearest mm.
    pub fn point_on(&self, seg: Segment) -> Point {
        let (dx, dy) = seg.b.sub(seg.a);
        let r = |a: i32, d: i64| -> i32 {
            let p = d as i128 * self.num as i128;
            let den = self.den as i128;
            // round half away from zero
            let q = if p >= 0 { (2 * p + den) / (2 * den) } else { -((-2 * p + den) / (2 * den)) };
            (a as i128 + q) as i32
        };
        Point::new(r(seg.a.x, dx), r(seg.a.y, dy))
    }
}

impl Convex<'_> {
    /// The t-vector of `p` against this piece.
    #[inline]
    pub fn tvector(&self, p: Point) -> TVector {
        let v = self.vertices();
        let n = v.len();
        let mut bits = 0u32;
        // The last edge first, each bit shifted up past the earlier ones:
        // edge `i` ends at bit `i` (at most 32 edges, `Convex::new`), and no
        // shift is by more than one place, so none can overflow.
        for i in (0..n).rev() {
            let cur = v[i];
            let next = if i + 1 < n { v[i + 1] } else { v[0] };
            bits = bits << 1 | u32::from(cross(next.sub(cur), p.sub(cur)) < 0);
        }
        if n == 2 {
            let (a, b) = (v[0], v[1]);
            let ab = b.sub(a);
            if dot(p.sub(a), ab) < 0 {
                bits |= 1 << 2;
            }
            if dot(p.sub(b), ab) > 0 {
                bits |= 1 << 3;
            }
        }
        TVector(bits)
    }

    /// The front (visible) surfaces seen from the point whose t-vector is `t`:
    /// bit `i` for edge `i`. Wall caps are not surfaces and are masked off.
    #[inline]
    pub fn front_surfaces(&self, t: TVector) -> u32 {
        // One bit per edge, all 32 of them for a full buffered piece
        // (`1 << 32` would overflow: the mask is built from the top).
        let n = self.edge_count().min(32) as u32;
        t.bits() & u32::MAX.checked_shr(32 - n).unwrap_or(0)
    }

    /// Exact decision for the closed segment `ab` against the closed piece,
    /// with the t-vectors of its ends already known (for example the
    /// transducer's, computed once per piece for all pseudo-paths).
    #[inline]
    pub fn hits_segment_with(&self, a: Point, ta: TVector, b: Point, tb: TVector) -> bool {
        if ta.shares_outside(tb) {
            return false;
        }
        if ta.is_inside() || tb.is_inside() {
            return true;
        }
        // Separating axis along the segment's normal: all vertices strictly on
        // one side of line ab.
        let ab = b.sub(a);
        let (mut left, mut right) = (false, false);
        for &v in self.vertices() {
            let o = cross(ab, v.sub(a));
            left |= o >= 0;
            right |= o <= 0;
            if left && right {
                return true;
            }
        }
        false
    }

    /// Exact decision: does the closed segment `ab` meet the closed piece?
    #[inline]
    pub fn hits_segment(&self, a: Point, b: Point) -> bool {
        self.hits_segment_with(a, self.tvector(a), b, self.tvector(b))
    }

    /// Where the segment first meets the piece, exactly, or `None` if it
    /// misses (Cyrus–Beck clipping with rational parameters).
    pub fn entry(&self, seg: Segment) -> Option<Entry> {
        let d = seg.b.sub(seg.a);
        let mut r = ParamRange::UNIT;
        let v = self.vertices();
        let n = v.len();
        for i in 0..n {
            let (p, q) = (v[i], v[(i + 1) % n]);
            let e = q.sub(p);
            if !r.cut(cross(e, seg.a.sub(p)), cross(e, d)) {
                return None;
            }
        }
        if n == 2 {
            let (a, b) = (v[0], v[1]);
            let ab = b.sub(a);
            let ba = a.sub(b);
            if !r.cut(dot(seg.a.sub(a), ab), dot(d, ab)) || !r.cut(dot(seg.a.sub(b), ba), dot(d, ba)) {
                return None;
            }
        }
        // Reduce to i64: lo ∈ [0, 1] with its denominator |c1| < 2^63.
        let (lo_n, lo_d) = (r.lo.num, r.lo.den);
        let g = gcd(lo_n.unsigned_abs(), lo_d.unsigned_abs()).max(1);
        // g divides both, so each quotient's magnitude fits i64.
        let q = |v: i64| (v.unsigned_abs() / g) as i64 * v.signum();
        Some(Entry { num: q(lo_n), den: q(lo_d) })
    }
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    const fn p(x: i32, y: i32) -> Point {
        Point::new(x, y)
    }
    const SQ: [Point; 4] = [p(0, 0), p(10, 0), p(10, 10), p(0, 10)];

    #[test]
    fn tvector_bits_and_fronts() {
        let c = Convex::new(&SQ).unwrap();
        assert_eq!(c.tvector(p(5, 5)).bits(), 0);
        assert_eq!(c.tvector(p(10, 5)).bits(), 0, "on the boundary is inside");
        assert_eq!(c.tvector(p(5, -3)).bits(), 0b0001);
        assert_eq!(c.tvector(p(20, 20)).bits(), 0b0110);
        assert_eq!(c.tvector(p(-1, 5)).bits(), 0b1000);
    }

    #[test]
    fn segment_cases() {
        let c = Convex::new(&SQ).unwrap();
        assert!(c.hits_segment(p(-5, 5), p(15, 5)), "through");
        assert!(c.hits_segment(p(-5, 10), p(15, 10)), "along an edge");
        assert!(c.hits_segment(p(10, 10), p(20, 20)), "touching a vertex");
        assert!(!c.hits_segment(p(-5, 11), p(15, 11)), "just above");
        assert!(c.hits_segment(p(3, 3), p(4, 4)), "inside");
        // t(a) & t(b) = 0 yet a miss: corner cut outside the square.
        assert!(!c.hits_segment(p(-1, 9), p(1, 12)));
        assert!(c.hits_segment(p(-1, 9), p(2, 11)), "cuts the corner");
    }

    #[test]
    fn wall_is_two_sided_with_caps() {
        let w = [p(0, 0), p(10, 0)];
        let c = Convex::new(&w).unwrap();
        assert!(c.is_wall());
        assert_eq!(c.tvector(p(5, 0)).bits(), 0);
        // Edge 0 (a→b) faces −y, edge 1 (b→a) faces +y.
        assert_eq!(c.front_surfaces(c.tvector(p(5, -5))), 0b01);
        assert_eq!(c.front_surfaces(c.tvector(p(5, 5))), 0b10);
        assert!(!c.hits_segment(p(11, 0), p(20, 0)), "collinear beyond the end");
        assert!(c.hits_segment(p(10, 0), p(20, 0)), "collinear touching");
        assert!(c.hits_segment(p(5, 5), p(5, -5)), "crossing");
        assert!(!c.hits_segment(p(11, 5), p(11, -5)), "beside the end");
    }

    #[test]
    fn entry_parameters() {
        let c = Convex::new(&SQ).unwrap();
        let s = Segment::new(p(-10, 5), p(30, 5));
        let e = c.entry(s).unwrap();
        assert_eq!((e.num, e.den), (1, 4));
        assert_eq!(e.point_on(s), p(0, 5));
        assert_eq!(c.entry(Segment::new(p(5, 5), p(50, 50))).unwrap().num, 0);
        assert!(c.entry(Segment::new(p(-5, 11), p(15, 11))).is_none());
        let w = [p(0, 0), p(0, 10)];
        let wall = Convex::new(&w).unwrap();
        let e = wall.entry(Segment::new(p(-8, 5), p(8, 5))).unwrap();
        assert_eq!((e.num, e.den), (1, 2));
        assert!(wall.entry(Segment::new(p(-8, 11), p(8, 11))).is_none());
    }
}
