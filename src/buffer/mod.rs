//! C-space buffers (DESIGN §4.3): a convex piece grown by `t_b`.
//!
//! The buffered piece is the Minkowski sum of the piece with an integer
//! octagon that *circumscribes* the disk of radius `t_b`, so it contains every
//! point within `t_b` of the piece (conservative: at most 8.2 % further out at
//! the octagon's corners). Buffers only serve the search for in-range beacons;
//! ranges are always predicted from the true edges.
//!
//! The octagon is exact in integers: vertices `(±a, ±s)` and `(±s, ±a)` with
//! `a = t_b` and `s` the least integer with `(a + s)² ≥ 2a²`, so that every
//! edge lies at distance at least `a` from the origin (the axis edges at
//! exactly `a`, the diagonal ones at `(a + s)/√2 ≥ a`).
//!
//! ```
//! use echoloc::buffer::grow;
//! use echoloc::geometry::{Convex, Point};
//! let sq = [Point::new(0, 0), Point::new(1000, 0), Point::new(1000, 1000), Point::new(0, 1000)];
//! let grown = grow(Convex::new(&sq).unwrap(), 100).unwrap();
//! assert_eq!(grown.len(), 8); // axis edges merge with the octagon's: 4 + 4 diagonals
//! assert!(Convex::new(&grown).is_ok());
//! ```

use heapless::Vec;

use crate::geometry::{cross, isqrt, Convex, Point, MAX_BUFFERED_VERTICES};

/// Largest buffer, mm (100 m): keeps grown coordinates far from overflow.
pub const MAX_BUFFER_MM: u32 = 100_000;

/// Why a piece could not be grown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BufferError {
    /// `t_b` above [`MAX_BUFFER_MM`].
    BufferTooLarge,
    /// A grown coordinate would leave `±COORD_MAX`.
    CoordinateOutOfRange,
    /// More than [`MAX_BUFFERED_VERTICES`] vertices (input too large).
    TooManyVertices,
}

/// The vertices of a grown piece.
pub type Buffered = Vec<Point, MAX_BUFFERED_VERTICES>;

/// The circumscribing octagon's short half-side `s` for apothem `a`.
///
/// `s = ⌈a·√2⌉ − a`, the least `s` with `(a + s)² ≥ 2a²`; exact for every
/// `u32`. For `a ≥ 1`, `2a²` is never a square, so `⌈√(2a²)⌉ = ⌊√(2a²)⌋ + 1`.
pub fn octagon_s(a: u32) -> u32 {
    let a64 = u64::from(a);
    if a == 0 {
        return 0;
    }
    if a64 < 1 << 31 {
        // 2a² < 2⁶³: in u64, and the bound is visible to the compiler.
        let r = isqrt(2 * a64 * a64).min(u64::from(u32::MAX));
        return ((r + 1).saturating_sub(a64)).min(u64::from(u32::MAX)) as u32;
    }
    // Beyond 2³¹ (no map needs it): in u128. `isqrt(⌊2a²/4⌋)·2` is at most 2
    // below `√(2a²)`; four steps settle it. The saturating and checked forms
    // are exact (every value stays below 2⁷⁰) and show the compiler so.
    let a = u128::from(a);
    let target = 2 * a * a;
    let root = (u128::from(isqrt((target >> 2) as u64)) << 1).min(1 << 34);
    let mut s = root.saturating_sub(a);
    let below = |r: u128| r.checked_mul(r).is_some_and(|r2| r2 < target);
    for _ in 0..4 {
        if below(a.saturating_add(s)) {
            s = s.saturating_add(1);
        }
    }
    // s < a ≤ u32::MAX.
    s.min(u128::from(u32::MAX)) as u32
}

/// The octagon circumscribing the disk of radius `a`, counter-clockwise,
/// starting at its lowest-then-leftmost vertex. For `a = 1`, where `s = a`,
/// it degenerates to the square `(±1, ±1)`. Refused above
/// [`MAX_BUFFER_MM`] (`BufferTooLarge`), which keeps every vertex in range.
pub fn octagon(a: u32) -> Result<Vec<Point, 8>, BufferError> {
    if a > MAX_BUFFER_MM {
        return Err(BufferError::BufferTooLarge);
    }
    Ok(octagon_within(a))
}

/// [`octagon`] for `a ≤ MAX_BUFFER_MM` (checked by the caller); built in
/// place, without a `Result` to copy out of.
#[inline(always)]
fn octagon_within(a: u32) -> Vec<Point, 8> {
    // Both below 2¹⁷ (the `min`s): the negations below cannot overflow.
    let s = octagon_s(a).min(MAX_BUFFER_MM) as i32;
    let a = a.min(MAX_BUFFER_MM) as i32;
    let all = [
        Point::new(-s, -a),
        Point::new(s, -a),
        Point::new(a, -s),
        Point::new(a, s),
        Point::new(s, a),
        Point::new(-s, a),
        Point::new(-a, s),
        Point::new(-a, -s),
    ];
    let mut out = Vec::new();
    for (k, &v) in all.iter().enumerate() {
        if all[(k + 1) % 8] != v {
            let _ = out.push(v);
        }
    }
    out
}

/// Grows `piece` by `t_b` millimetres (see the module docs). `t_b = 0` gives
/// the piece itself; a wall grows into a solid ten-gon (a stadium's hull).
pub fn grow(piece: Convex<'_>, t_b: u32) -> Result<Buffered, BufferError> {
    if t_b > MAX_BUFFER_MM {
        return Err(BufferError::BufferTooLarge);
    }
    let p = piece.vertices();
    let mut out = Buffered::new();
    if t_b == 0 {
        out.extend_from_slice(p).map_err(|_| BufferError::TooManyVertices)?;
        return Ok(out);
    }
    let lim = crate::geometry::COORD_MAX as i64 - t_b as i64;
    if p.iter().any(|v| (v.x as i64).abs() > lim || (v.y as i64).abs() > lim) {
        return Err(BufferError::CoordinateOutOfRange);
    }
    let q = octagon_within(t_b);
    // Minkowski sum of convex polygons: start at both lowest-leftmost
    // vertices and merge the edge sequences by polar angle (exact compare).
    let start = |v: &[Point]| (0..v.len()).min_by_key(|&i| (v[i].y, v[i].x)).unwrap_or(0);
    let (n, m) = (p.len(), q.len());
    // The sum has at least `n` vertices: a larger piece cannot fit the
    // result; refused before the merge, which also shows the compiler
    // that the indices below stay small.
    if n > MAX_BUFFERED_VERTICES {
        return Err(BufferError::TooManyVertices);
    }
    if n == 0 || m == 0 {
        // Never: a `Convex` has two vertices or more, an octagon four. The
        // test lets the compiler drop the `% 0` panic paths below.
        return Ok(out);
    }
    let sp = start(p);
    let (mut i, mut j) = (0usize, 0usize);
    // `i ≤ n` and `j ≤ m` throughout (a side stops once it is done); the
    // test makes it visible, so the counts below cannot overflow.
    while (i < n || j < m) && i <= n && j <= m {
        // Positions round both outlines. `sp < n ≤ 32`, `i ≤ n`, `j ≤ m ≤ 8`:
        // the `min`s change nothing but show the compiler these sums are small.
        let (ki, kj) = (sp.min(MAX_BUFFERED_VERTICES) + i.min(MAX_BUFFERED_VERTICES), j.min(8));
        let (a, pa) = (p[ki % n], p[(ki + 1) % n]);
        let (b, qb) = (q[kj % m], q[(kj + 1) % m]);
        // In range by the check against `lim` above; checked all the same,
        // because the vertices come from memory the compiler cannot see.
        let (Some(x), Some(y)) = (a.x.checked_add(b.x), a.y.checked_add(b.y)) else {
            return Err(BufferError::CoordinateOutOfRange);
        };
        let v = Point::new(x, y);
        if out.last() != Some(&v) {
            out.push(v).map_err(|_| BufferError::TooManyVertices)?;
        }
        let (ep, eq) = (pa.sub(a), qb.sub(b));
        let c = if i == n {
            -1
        } else if j == m {
            1
        } else {
            angle_cmp(ep, eq)
        };
        // c > 0: p's edge comes first by angle; c == 0: parallel, take both.
        if c >= 0 {
            i += 1;
        }
        // (`j < m` holds whenever `c ≤ 0`: said for the compiler.)
        if c <= 0 && j < m {
            j += 1;
        }
    }
    // Drop the closing duplicate and any collinear vertex (parallel edges of a
    // wall's two faces with an octagon edge can line up).
    if out.len() > 1 && out.first() == out.last() {
        out.truncate(out.len() - 1);
    }
    let mut k = 0;
    while out.len() > 3 && k < out.len() {
        let len = out.len();
        // Neighbours without `%`, and reads through `get`: no panic path.
        let (prev, next) = (if k == 0 { len - 1 } else { k - 1 }, if k + 1 == len { 0 } else { k + 1 });
        let (Some(&a), Some(&b), Some(&c)) = (out.get(prev), out.get(k), out.get(next)) else { break };
        if crate::geometry::orient(a, b, c) == 0 {
            // Remove vertex k: shift the tail down one, then drop the last.
            for i in k..len - 1 {
                if let Some(&v) = out.get(i + 1) {
                    if let Some(slot) = out.get_mut(i) {
                        *slot = v;
                    }
                }
            }
            out.truncate(out.len() - 1);
        } else {
            k += 1;
        }
    }
    Ok(out)
}

/// Orders two edge vectors by polar angle in `[0, 2π)` measured from +x:
/// positive when `u` comes first.
fn angle_cmp(u: (i64, i64), v: (i64, i64)) -> i32 {
    let half = |w: (i64, i64)| if w.1 > 0 || (w.1 == 0 && w.0 > 0) { 0 } else { 1 };
    let (hu, hv) = (half(u), half(v));
    if hu != hv {
        return if hu < hv { 1 } else { -1 };
    }
    let c = cross(u, v);
    if c > 0 {
        1
    } else if c < 0 {
        -1
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octagon_is_exactly_conservative() {
        for a in [1u32, 2, 3, 7, 100, 750, 12345, MAX_BUFFER_MM] {
            let s = octagon_s(a) as u64;
            let a64 = a as u64;
            assert!((a64 + s) * (a64 + s) >= 2 * a64 * a64);
            assert!(s == 0 || (a64 + s - 1) * (a64 + s - 1) < 2 * a64 * a64, "s minimal");
            assert!(Convex::new(&octagon(a).unwrap()).is_ok());
        }
        assert_eq!(octagon_s(100), 42); // 100·(√2−1) = 41.42
    }

    #[test]
    fn grown_square_and_wall() {
        let sq = [Point::new(0, 0), Point::new(10, 0), Point::new(10, 10), Point::new(0, 10)];
        let g = grow(Convex::new(&sq).unwrap(), 100).unwrap();
        let c = Convex::new(&g).unwrap();
        // 4 axis edges lengthened, 4 diagonal corners: area = 10² + 4·10·100 + octagon.
        let oct = Convex::new(&octagon(100).unwrap()).unwrap().area2();
        assert_eq!(c.area2(), 2 * (100 + 4 * 1000) + oct);
        let w = [Point::new(0, 0), Point::new(0, 500)];
        let g = grow(Convex::new(&w).unwrap(), 50).unwrap();
        assert_eq!(g.len(), 8, "a vertical wall only stretches the octagon");
        assert!(Convex::new(&g).is_ok());
        let w = [Point::new(0, 0), Point::new(300, 400)];
        let g = grow(Convex::new(&w).unwrap(), 50).unwrap();
        assert_eq!(g.len(), 10);
        assert!(Convex::new(&g).is_ok());
    }

    #[test]
    fn zero_buffer_is_identity_and_limits_hold() {
        let sq = [Point::new(0, 0), Point::new(10, 0), Point::new(10, 10), Point::new(0, 10)];
        let c = Convex::new(&sq).unwrap();
        assert_eq!(&grow(c, 0).unwrap()[..], &sq[..]);
        assert_eq!(grow(c, MAX_BUFFER_MM + 1), Err(BufferError::BufferTooLarge));
        let m = crate::geometry::COORD_MAX;
        let far = [Point::new(m - 5, 0), Point::new(m - 5, 10)];
        assert_eq!(grow(Convex::new(&far).unwrap(), 10), Err(BufferError::CoordinateOutOfRange));
    }
}
