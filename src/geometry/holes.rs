//! Splitting a polygon *with holes* into convex pieces.
//!
//! Each hole is bridged into the outer ring (after D. Eberly,
//! "Triangulation by Ear Clipping", §3): holes are taken in decreasing order
//! of their largest x; from a hole's rightmost vertex `M` a bridge runs to
//! the nearest vertex `V` of the ring built so far that lies strictly right
//! of `M`, that `M` sees inside the polygon (exact segment tests against
//! every ring edge) and whose interior wedge the bridge enters. The ring
//! becomes `… V, M, (hole from M round to M), M', V', …`: weakly simple, with
//! the bridge's ends twice. The ear clipping and Hertel–Mehlhorn merging of
//! [`split_convex`](super::split_convex) then run on it unchanged: their ear
//! test ignores vertices that share a corner's position (a twin's wedge lies
//! outside the corner's), and zero-width spikes are dropped when the clipping
//! reaches them.
//!
//! Every decision is an exact integer predicate; nothing allocates.

use heapless::Vec;

use super::split::{clean_ring, clip_and_merge, ring_area2, ClipError};
use super::{orient, point_on_segment, segments_intersect, Point, MAX_PIECE_VERTICES};

/// Which ring of the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Ring {
    /// The outer boundary.
    Outer,
    /// Hole `i` (its index in the caller's list).
    Hole(usize),
}

/// Why a polygon with holes could not be split.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HolesError<E> {
    /// The rings, plus two bridge vertices per hole, exceed the working
    /// capacity `N` (or `N` exceeds 65 535).
    TooManyVertices,
    /// A coordinate of this ring is beyond `±COORD_MAX`.
    CoordinateOutOfRange(Ring),
    /// This ring has no area (fewer than three distinct, non-collinear vertices).
    Degenerate(Ring),
    /// Two edges meet that must not: within one ring (not simple), or of two
    /// rings (a hole touches or crosses the outer ring or another hole).
    /// Edge indices count vertices after cleaning.
    Intersect {
        /// The first ring.
        ring_a: Ring,
        /// Its edge.
        edge_a: usize,
        /// The second ring (may equal `ring_a`).
        ring_b: Ring,
        /// Its edge.
        edge_b: usize,
    },
    /// This hole lies outside the outer ring.
    HoleOutside(usize),
    /// Hole `inner` lies inside hole `outer`.
    NestedHoles {
        /// The enclosing hole.
        outer: usize,
        /// The enclosed hole.
        inner: usize,
    },
    /// No bridge found for this hole (a guard: cannot happen for valid input).
    NoBridge(usize),
    /// No ear found (a guard: cannot happen for valid input).
    NoEar,
    /// The caller's sink refused a piece.
    Sink(E),
}

/// Splits the polygon with outer ring `outer` and holes `holes` (any
/// orientation each; repeated and collinear vertices allowed) into strictly
/// convex counter-clockwise pieces of at most `max_piece_vertices` vertices
/// (clamped to `3..=MAX_PIECE_VERTICES`), handing each to `emit`. Returns the
/// number of pieces.
///
/// The rings must be simple, must not touch one another, every hole must lie
/// inside the outer ring and no hole inside another; each violation is its
/// own error. `N` is the working capacity: at least the total number of
/// vertices plus two per hole (at most 65 535). The pieces cover exactly
/// the outer polygon minus the holes: their areas add up to that area and
/// their interiors are disjoint. With no holes this is
/// [`split_convex`](super::split_convex).
///
/// ```
/// use echoloc::geometry::{split_convex_with_holes, Point};
/// let p = |v: [(i32, i32); 4]| v.map(|(x, y)| Point::new(x, y));
/// // A square frame: 30 × 30 with a 10 × 10 hole.
/// let outer = p([(0, 0), (30, 0), (30, 30), (0, 30)]);
/// let hole = p([(10, 10), (20, 10), (20, 20), (10, 20)]);
/// let mut area2 = 0i64;
/// let n = split_convex_with_holes::<32, ()>(&outer, &[&hole], 24, |piece| {
///     area2 += (1..piece.len() - 1)
///         .map(|i| echoloc::geometry::orient(piece[0], piece[i], piece[i + 1]))
///         .sum::<i64>();
///     Ok(())
/// })
/// .unwrap();
/// assert!(n >= 4);
/// assert_eq!(area2, 2 * (900 - 100));
/// ```
pub fn split_convex_with_holes<const N: usize, E>(
    outer: &[Point],
    holes: &[&[Point]],
    max_piece_vertices: usize,
    emit: impl FnMut(&[Point]) -> Result<(), E>,
) -> Result<usize, HolesError<E>> {
    let maxv = max_piece_vertices.clamp(3, MAX_PIECE_VERTICES);
    let total = outer.len() + holes.iter().map(|h| h.len() + 2).sum::<usize>();
    if total > N || N > u16::MAX as usize {
        return Err(HolesError::TooManyVertices);
    }
    // 1. Clean each ring into `pts`; `starts[r]` is ring r's first vertex
    // (ring 0 the outer, ring 1 + i hole i), `starts[rings]` the end.
    let mut pts: Vec<Point, N> = Vec::new();
    let mut starts: Vec<u16, N> = Vec::new();
    for (r, ring) in core::iter::once(outer).chain(holes.iter().copied()).enumerate() {
        let which = ring_id(r);
        if !ring.iter().all(|p| p.in_range()) {
            return Err(HolesError::CoordinateOutOfRange(which));
        }
        let from = pts.len();
        // Capacities were checked above.
        let _ = starts.push(from as u16);
        let _ = pts.extend_from_slice(ring);
        clean_ring(&mut pts, from);
        if pts.len() - from < 3 {
            return Err(HolesError::Degenerate(which));
        }
    }
    let _ = starts.push(pts.len() as u16);
    let rings = holes.len() + 1;
    let ring_of = |r: usize| &pts[starts[r] as usize..starts[r + 1] as usize];

    // 2. No two edges meet, within a ring (except neighbours at their shared
    // vertex) or across rings.
    for ra in 0..rings {
        let a = ring_of(ra);
        for rb in ra..rings {
            let b = ring_of(rb);
            for i in 0..a.len() {
                let (p, q) = (a[i], a[(i + 1) % a.len()]);
                let first = if ra == rb { i + 1 } else { 0 };
                for j in first..b.len() {
                    if ra == rb && (j == i + 1 || (i == 0 && j == a.len() - 1)) {
                        continue; // neighbours (cleaning left no straight or folded corner)
                    }
                    let (s, t) = (b[j], b[(j + 1) % b.len()]);
                    if p.x.max(q.x) < s.x.min(t.x)
                        || s.x.max(t.x) < p.x.min(q.x)
                        || p.y.max(q.y) < s.y.min(t.y)
                        || s.y.max(t.y) < p.y.min(q.y)
                    {
                        continue;
                    }
                    if segments_intersect(p, q, s, t) {
                        return Err(HolesError::Intersect {
                            ring_a: ring_id(ra),
                            edge_a: i,
                            ring_b: ring_id(rb),
                            edge_b: j,
                        });
                    }
                }
            }
        }
    }
    // Orientation: outer counter-clockwise, holes clockwise. (A simple ring
    // has area; a crossed one was refused above.)
    for r in 0..rings {
        let (from, to) = (starts[r] as usize, starts[r + 1] as usize);
        let area2 = ring_area2(&pts[from..to]);
        if area2 == 0 {
            return Err(HolesError::Degenerate(ring_id(r)));
        }
        if (r == 0) != (area2 > 0) {
            pts[from..to].reverse();
        }
    }
    let ring_of = |r: usize| &pts[starts[r] as usize..starts[r + 1] as usize];
    // 3. Nesting: with no edges meeting, one vertex decides a whole ring.
    for h in 1..rings {
        if !strictly_inside(ring_of(0), ring_of(h)[0]) {
            return Err(HolesError::HoleOutside(h - 1));
        }
        for g in 1..rings {
            if g != h && strictly_inside(ring_of(g), ring_of(h)[0]) {
                return Err(HolesError::NestedHoles { outer: g - 1, inner: h - 1 });
            }
        }
    }

    // 4. Bridges, holes in decreasing order of their largest x.
    let mut ring: Vec<u16, N> = (0..starts[1]).collect();
    let mut order: Vec<(i32, u16), N> =
        (1..rings).map(|h| (ring_of(h).iter().map(|p| p.x).max().unwrap_or(0), h as u16)).collect();
    order.sort_unstable_by(|a, b| b.cmp(a));
    let mut cand: Vec<u16, N> = Vec::new();
    for &(_, h) in order.iter() {
        let h = h as usize;
        let (hs, he) = (starts[h] as usize, starts[h + 1] as usize);
        // M: the rightmost vertex (the lowest of equals, for determinism).
        let mi = (hs..he).max_by_key(|&k| (pts[k].x, -(pts[k].y as i64))).unwrap_or(hs);
        let m = pts[mi];
        cand.clear();
        for (k, &idx) in ring.iter().enumerate() {
            if pts[idx as usize].x > m.x {
                let _ = cand.push(k as u16);
            }
        }
        cand.sort_unstable_by_key(|&k| (pts[ring[k as usize] as usize].dist2(m), k));
        let len = ring.len();
        let at = |k: usize| pts[ring[k % len] as usize];
        let found = cand.iter().map(|&k| k as usize).find(|&k| {
            let (u, v, w) = (at(k + len - 1), at(k), at(k + 1));
            let inside = if orient(u, v, w) > 0 {
                orient(u, v, m) > 0 && orient(v, w, m) > 0
            } else {
                orient(u, v, m) > 0 || orient(v, w, m) > 0
            };
            inside
                && (0..len).all(|j| {
                    let (p, q) = (at(j), at(j + 1));
                    if !segments_intersect(m, v, p, q) {
                        return true;
                    }
                    // Touching the ring only at V itself is allowed.
                    (p == v && !point_on_segment(q, m, v)) || (q == v && !point_on_segment(p, m, v))
                })
        });
        let Some(k) = found else {
            return Err(HolesError::NoBridge(h - 1));
        };
        let vi = ring[k];
        // The twins M' and V' are new vertices at the same positions.
        let (m2, v2) = (pts.len() as u16, pts.len() as u16 + 1);
        let _ = pts.push(m);
        let _ = pts.push(pts[vi as usize]);
        // Insert M, the hole round to M, M', V' after position k.
        let old = ring.len();
        let hn = he - hs;
        for s in 0..hn {
            let _ = ring.push((hs + (mi - hs + s) % hn) as u16);
        }
        let _ = ring.push(m2);
        let _ = ring.push(v2);
        let added = ring.len() - old;
        ring[k + 1..].rotate_right(added);
    }

    // 5. Ear clipping and merging on the bridged ring.
    let merged: Vec<Point, N> = ring.iter().map(|&k| pts[k as usize]).collect();
    drop(ring);
    clip_and_merge::<N, E>(&merged, maxv, emit).map_err(|e| match e {
        ClipError::NoEar => HolesError::NoEar,
        ClipError::Sink(e) => HolesError::Sink(e),
    })
}

fn ring_id(r: usize) -> Ring {
    if r == 0 {
        Ring::Outer
    } else {
        Ring::Hole(r - 1)
    }
}

/// Whether `p` lies strictly inside the simple ring (winding number, exact).
/// Points on the boundary are not inside.
///
/// ```
/// use echoloc::geometry::{strictly_inside, Point};
/// let sq = [Point::new(0, 0), Point::new(10, 0), Point::new(10, 10), Point::new(0, 10)];
/// assert!(strictly_inside(&sq, Point::new(5, 5)));
/// assert!(!strictly_inside(&sq, Point::new(10, 5)), "on the boundary");
/// assert!(!strictly_inside(&sq, Point::new(11, 5)));
/// ```
pub fn strictly_inside(ring: &[Point], p: Point) -> bool {
    let n = ring.len();
    let mut wn = 0i32;
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        if point_on_segment(p, a, b) {
            return false;
        }
        if a.y <= p.y {
            if b.y > p.y && orient(a, b, p) > 0 {
                wn += 1;
            }
        } else if b.y <= p.y && orient(a, b, p) < 0 {
            wn -= 1;
        }
    }
    wn != 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Convex;

    fn ring(v: &[(i32, i32)]) -> heapless::Vec<Point, 32> {
        v.iter().map(|&(x, y)| Point::new(x, y)).collect()
    }

    fn split(outer: &[Point], holes: &[&[Point]]) -> Result<(usize, i64), HolesError<()>> {
        let mut area = 0;
        let n = split_convex_with_holes::<256, ()>(outer, holes, 24, |piece| {
            area += Convex::new(piece).expect("piece must be strictly convex").area2();
            Ok(())
        })?;
        Ok((n, area))
    }

    #[test]
    fn frame_with_one_hole() {
        let o = ring(&[(0, 0), (30, 0), (30, 30), (0, 30)]);
        let h = ring(&[(10, 10), (20, 10), (20, 20), (10, 20)]);
        let (n, a) = split(&o, &[&h]).unwrap();
        assert_eq!(a, 2 * (900 - 100));
        assert!((4..=8).contains(&n), "{n} pieces");
        // Hole given clockwise: same result.
        let hr: heapless::Vec<Point, 32> = h.iter().rev().copied().collect();
        assert_eq!(split(&o, &[&hr]).unwrap().1, a);
    }

    #[test]
    fn several_holes_sharing_x_and_bridge_vertices() {
        // Holes aligned on the same x, so bridges compete for one vertex.
        let o = ring(&[(0, 0), (100, 0), (100, 100), (0, 100)]);
        let h1 = ring(&[(40, 10), (60, 10), (60, 20), (40, 20)]);
        let h2 = ring(&[(40, 40), (60, 40), (60, 60), (40, 60)]);
        let h3 = ring(&[(40, 80), (60, 80), (60, 90), (40, 90)]);
        let h4 = ring(&[(70, 45), (80, 50), (70, 55)]);
        let (_, a) = split(&o, &[&h1, &h2, &h3, &h4]).unwrap();
        assert_eq!(a, 2 * 10_000 - 2 * 200 - 2 * 400 - 2 * 200 - 100);
    }

    #[test]
    fn no_holes_matches_split_convex() {
        let l = ring(&[(0, 0), (20, 0), (20, 10), (10, 10), (10, 20), (0, 20)]);
        assert_eq!(split(&l, &[]).unwrap(), (2, 600));
    }

    #[test]
    fn bad_inputs() {
        let o = ring(&[(0, 0), (30, 0), (30, 30), (0, 30)]);
        let outside = ring(&[(40, 10), (50, 10), (50, 20)]);
        assert_eq!(split(&o, &[&outside]), Err(HolesError::HoleOutside(0)));
        let touching = ring(&[(0, 10), (10, 10), (10, 20)]);
        assert!(matches!(
            split(&o, &[&touching]),
            Err(HolesError::Intersect { ring_a: Ring::Outer, ring_b: Ring::Hole(0), .. })
        ));
        let big = ring(&[(5, 5), (25, 5), (25, 25), (5, 25)]);
        let small = ring(&[(10, 10), (20, 10), (20, 20)]);
        assert_eq!(split(&o, &[&big, &small]), Err(HolesError::NestedHoles { outer: 0, inner: 1 }));
        let a = ring(&[(5, 5), (15, 5), (15, 15), (5, 15)]);
        let b = ring(&[(10, 10), (20, 10), (20, 20), (10, 20)]);
        assert!(matches!(split(&o, &[&a, &b]), Err(HolesError::Intersect { .. })));
        let flat = ring(&[(10, 10), (20, 10), (15, 10)]);
        assert_eq!(split(&o, &[&flat]), Err(HolesError::Degenerate(Ring::Hole(0))));
        let bow = ring(&[(0, 0), (30, 30), (30, 0), (0, 20)]);
        assert!(matches!(split(&bow, &[]), Err(HolesError::Intersect { ring_a: Ring::Outer, .. })));
        let far = ring(&[(0, 0), (i32::MAX, 0), (0, 5)]);
        assert_eq!(split(&far, &[]), Err(HolesError::CoordinateOutOfRange(Ring::Outer)));
        assert_eq!(split_convex_with_holes::<8, ()>(&o, &[&small], 24, |_| Ok(())), Err(HolesError::TooManyVertices));
        assert_eq!(split_convex_with_holes::<32, u8>(&o, &[&small], 24, |_| Err(3)), Err(HolesError::Sink(3)));
    }
}
