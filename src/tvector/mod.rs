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

/// The closed cone of directions in which a ray from a point strictly
/// outside a solid piece meets it: between the rays to the two ends of the
/// piece's front chain (its tangent vertices), less than a half-turn wide.
/// A segment from that point whose direction lies outside it misses the
/// piece, so the pseudo-paths' exact test ([`Convex::hits_segment_with`])
/// runs only for the paths inside it: two cross products instead of a
/// t-vector for every other path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cone {
    /// From the point to the first vertex of the front chain ...
    a: (i32, i32),
    /// ... and to its last, clockwise of `a` (the piece is
    /// counter-clockwise, so its front chain turns clockwise as seen from
    /// outside). In `i32`: differences of in-range points fit, and each
    /// cross product is then two 32 × 32 → 64-bit multiplies.
    b: (i32, i32),
}

impl Cone {
    /// Whether the direction `d` (a difference of in-range points) lies in
    /// the closed cone; the zero direction does.
    #[inline]
    pub fn contains(&self, d: (i64, i64)) -> bool {
        let (a, b) = ((self.a.0 as i64, self.a.1 as i64), (self.b.0 as i64, self.b.1 as i64));
        cross(a, d) <= 0 && cross(d, b) <= 0
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

    /// The [`Cone`] of `p`, whose t-vector is `tp`: `None` when `p` is not
    /// strictly outside (`tp` empty), for a wall, or when the front chain is
    /// not one run of edges (never, for a valid piece and an in-range point;
    /// a caller then tests every direction).
    ///
    /// ```
    /// use echoloc::geometry::{Convex, Point};
    /// let sq = [Point::new(0, 0), Point::new(10, 0), Point::new(10, 10), Point::new(0, 10)];
    /// let piece = Convex::new(&sq).unwrap();
    /// let p = Point::new(20, 5);
    /// let cone = piece.cone_from(p, piece.tvector(p)).unwrap();
    /// assert!(cone.contains(Point::new(-5, 5).sub(p)));
    /// assert!(cone.contains(Point::new(10, 10).sub(p))); // a tangent vertex
    /// assert!(!cone.contains(Point::new(20, 50).sub(p)));
    /// assert!(!cone.contains(Point::new(40, 5).sub(p))); // the other way
    /// ```
    pub fn cone_from(&self, p: Point, tp: TVector) -> Option<Cone> {
        let v = self.vertices();
        let n = v.len();
        if !(3..=32).contains(&n) {
            return None;
        }
        let full = u32::MAX >> (32 - n);
        let m = tp.bits() & full;
        // Bit i of `before`: edge i − 1 is a front edge. One run of front
        // edges has one start (none when `m` is empty or full).
        let before = (m << 1 | m >> (n - 1)) & full;
        let starts = m & !before;
        if starts.count_ones() != 1 {
            return None;
        }
        // The chain runs from the start of its first edge to the end of its last.
        let i = starts.trailing_zeros() as usize;
        let j = i + m.count_ones() as usize;
        let a = v.get(i)?.sub(p);
        let b = v.get(if j < n { j } else { j - n })?.sub(p);
        (cross(a, b) < 0).then_some(Cone { a: (a.0 as i32, a.1 as i32), b: (b.0 as i32, b.1 as i32) })
    }

    /// Whether the closed segment from `p` to `g` meets the closed piece, `p`
    /// strictly outside with t-vector `tp` and cone `cone` (from
    /// [`Convex::cone_from`]): exact, as [`Convex::hits_segment`]. Outside
    /// the cone even the ray misses. Inside it the ray meets the piece, so
    /// the segment's own line is no separating axis, and the segment misses
    /// only when both ends lie outside one same edge: no vertex loop, and
    /// only `p`'s front edges (the set bits of `tp`) are tested against `g`.
    #[inline]
    pub fn hits_from(&self, tp: TVector, cone: &Cone, p: Point, g: Point) -> bool {
        if !cone.contains(g.sub(p)) {
            return false;
        }
        let v = self.vertices();
        let mut front = tp.bits();
        while front != 0 {
            let i = front.trailing_zeros() as usize;
            front &= front - 1;
            let j = if i + 1 < v.len() { i + 1 } else { 0 };
            if let (Some(&a), Some(&b)) = (v.get(i), v.get(j)) {
                if cross(b.sub(a), g.sub(a)) < 0 {
                    return false; // `g` too lies strictly outside front edge `i`
                }
            }
        }
        true
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
    /// Never inlined: one copy serves every caller (flash).
    #[inline(never)]
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

    /// Uniform integers in `[-span, span]`, from a fixed seed.
    fn xorshift(mut x: u64) -> impl FnMut(i64) -> i64 {
        move |span| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as i64 % (2 * span + 1) - span
        }
    }

    /// 3–32 points of a circle of radius `r` at random angles,
    /// counter-clockwise, into `out`: their count (rounding may leave them
    /// not strictly convex, which `Convex::new` refuses).
    fn random_piece(next: &mut impl FnMut(i64) -> i64, r: i64, out: &mut [Point; 32]) -> usize {
        let n = 3 + next(14).unsigned_abs() as usize * 2 % 30;
        let mut ang = [0f64; 32];
        for a in ang[..n].iter_mut() {
            *a = (next(1 << 20) as f64 / (1 << 20) as f64 + 1.0) * core::f64::consts::PI;
        }
        ang[..n].sort_by(|a, b| a.partial_cmp(b).unwrap());
        for (v, a) in out.iter_mut().zip(&ang[..n]) {
            *v = p((r as f64 * a.cos()).round() as i32, (r as f64 * a.sin()).round() as i32);
        }
        n
    }

    /// Against the exact segment test on a ray long enough to pass every
    /// vertex: a direction lies in the cone exactly when the ray meets the
    /// piece, on random convex pieces of 3–32 vertices, from random outside
    /// points, for random directions, the directions to every vertex (always
    /// in), and those directions turned by a unit (the cone's edges).
    #[test]
    fn cone_is_exactly_the_directions_whose_ray_meets_the_piece() {
        let mut next = xorshift(0x853c_49e6_748f_ea9b);
        let (mut inside, mut outside, mut pieces) = (0, 0, 0);
        let mut verts = [p(0, 0); 32];
        for _ in 0..3_000 {
            let r = 1_000 + next(1_000_000).abs();
            let n = random_piece(&mut next, r, &mut verts);
            let Ok(piece) = Convex::new(&verts[..n]) else { continue };
            if piece.is_wall() {
                continue;
            }
            let o = p(next(3_000_000) as i32, next(3_000_000) as i32);
            let to = piece.tvector(o);
            if to.is_inside() {
                continue;
            }
            pieces += 1;
            let cone = piece.cone_from(o, to).expect("a cone from every outside point");
            let ray_hits = |d: (i64, i64)| {
                let k = (6_000_000 / d.0.abs().max(d.1.abs()).max(1)).max(1) + 1;
                let end = p((o.x as i64 + d.0 * k) as i32, (o.y as i64 + d.1 * k) as i32);
                piece.hits_segment(o, end)
            };
            let mut check = |d: (i64, i64)| {
                if d == (0, 0) {
                    return;
                }
                let c = cone.contains(d);
                assert_eq!(c, ray_hits(d), "piece {:?}, from {o:?}, direction {d:?}", piece.vertices());
                if c {
                    inside += 1;
                } else {
                    outside += 1;
                }
            };
            for &v in piece.vertices() {
                let d = v.sub(o);
                assert!(cone.contains(d), "the direction to vertex {v:?} from {o:?}");
                let s = 1_000_000 / d.0.abs().max(d.1.abs()).max(1) + 1;
                for (ex, ey) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                    check((d.0 * s + ex, d.1 * s + ey));
                }
            }
            for _ in 0..20 {
                check((next(1_000_000), next(1_000_000)));
            }
        }
        assert!(pieces > 2_000 && inside > 10_000 && outside > 10_000, "{pieces} pieces, {inside} in, {outside} out");
    }

    /// `hits_from` against `hits_segment` on random pieces, from random
    /// outside points, to ends short of, in, across and past the piece.
    #[test]
    fn hits_from_answers_as_hits_segment() {
        let mut next = xorshift(0x2f69_3b1a_c0de_4421);
        let (mut hits, mut misses) = (0, 0);
        let mut verts = [p(0, 0); 32];
        for _ in 0..3_000 {
            let r = 200 + next(20_000).abs();
            let n = random_piece(&mut next, r, &mut verts);
            let Ok(piece) = Convex::new(&verts[..n]) else { continue };
            let o = p(next(60_000) as i32, next(60_000) as i32);
            let to = piece.tvector(o);
            let Some(cone) = piece.cone_from(o, to) else { continue };
            for k in 0..40 {
                // Ends near the piece (short of it, inside it, just past it)
                // and far off.
                let span = if k % 2 == 0 { r + 50 } else { 80_000 };
                let g = p(next(span) as i32, next(span) as i32);
                let want = piece.hits_segment(o, g);
                assert_eq!(piece.hits_from(to, &cone, o, g), want, "{:?} from {o:?} to {g:?}", piece.vertices());
                if want {
                    hits += 1;
                } else {
                    misses += 1;
                }
            }
        }
        assert!(hits > 10_000 && misses > 10_000, "{hits} hits, {misses} misses");
    }

    #[test]
    fn cone_refuses_inside_points_and_walls() {
        let c = Convex::new(&SQ).unwrap();
        assert_eq!(c.cone_from(p(5, 5), c.tvector(p(5, 5))), None);
        assert_eq!(c.cone_from(p(10, 5), c.tvector(p(10, 5))), None, "on the boundary");
        let w = [p(0, 0), p(10, 0)];
        let wall = Convex::new(&w).unwrap();
        assert_eq!(wall.cone_from(p(5, 5), wall.tvector(p(5, 5))), None);
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
