//! Shared helpers for echoloc's host integration tests: proptest generators
//! of convex pieces, simple polygons and maps, and conversions to the `geo`
//! crate, the independent implementation the geometry is checked against.

use echoloc::geometry::{Convex, Point};
use geo::{Coord, LineString, Polygon};
use proptest::prelude::*;

/// `geo` coordinates of a point.
pub fn coord(p: Point) -> Coord<f64> {
    Coord { x: p.x as f64, y: p.y as f64 }
}

/// A `geo` polygon with the given ring (closed automatically).
pub fn geo_polygon(ring: &[Point]) -> Polygon<f64> {
    Polygon::new(LineString::from(ring.iter().map(|&p| coord(p)).collect::<Vec<_>>()), vec![])
}

/// A `geo` line from a wall piece.
pub fn geo_line(a: Point, b: Point) -> geo::Line<f64> {
    geo::Line::new(coord(a), coord(b))
}

/// The convex hull of `pts`, counter-clockwise, strictly convex, computed
/// here by Andrew's monotone chain with exact integer turns. Returns fewer
/// than three points when they are collinear.
pub fn hull(mut pts: Vec<Point>) -> Vec<Point> {
    pts.sort();
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let turn = |a: Point, b: Point, c: Point| echoloc::geometry::orient(a, b, c);
    let mut lower: Vec<Point> = Vec::new();
    for &p in &pts {
        while lower.len() >= 2 && turn(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Vec<Point> = Vec::new();
    for &p in pts.iter().rev() {
        while upper.len() >= 2 && turn(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

/// Random convex pieces: hulls of 3–20 points in a box of half-size `r`
/// around a random centre, at most `max` vertices. On a coarse lattice half
/// of the time, so that touching and collinear cases come up often.
pub fn convex_piece(r: i32, max: usize) -> impl Strategy<Value = Vec<Point>> {
    (any::<bool>(), -r..r, -r..r, prop::collection::vec((-r..=r, -r..=r), 3..20)).prop_filter_map(
        "degenerate hull",
        move |(coarse, cx, cy, raw)| {
            let q = if coarse { 10 } else { 1 };
            let pts = raw.into_iter().map(|(x, y)| Point::new(cx + x / q * q, cy + y / q * q)).collect();
            let mut h = hull(pts);
            h.truncate(max);
            let h = hull(h);
            (h.len() >= 3 && Convex::new(&h).is_ok()).then_some(h)
        },
    )
}

/// Random segments near a piece: free ends, ends on vertices, ends on edge
/// lines (collinear cases), or degenerate (a point).
pub fn segment_near(piece: Vec<Point>, r: i32) -> impl Strategy<Value = (Vec<Point>, Point, Point)> {
    let n = piece.len();
    (0..7u8, 0..n, 0..n, -r..=r, -r..=r, -r..=r, -r..=r, -3i32..=3).prop_map(move |(mode, i, j, x0, y0, x1, y1, k)| {
        let c = piece[0];
        let free_a = Point::new(c.x + x0, c.y + y0);
        let free_b = Point::new(c.x + x1, c.y + y1);
        let vi = piece[i];
        let vn = piece[(i + 1) % n];
        // A point on edge i's supporting line, k edge-lengths along it.
        let on_line = Point::new(vi.x + k * (vn.x - vi.x), vi.y + k * (vn.y - vi.y));
        let (a, b) = match mode {
            0 => (free_a, free_b),
            1 => (piece[i], free_b),
            2 => (piece[i], piece[j]),
            3 => (on_line, vi),
            4 => (on_line, Point::new(vn.x + (vn.x - vi.x) * 2, vn.y + (vn.y - vi.y) * 2)),
            5 => {
                // Through vertex i in a random direction: often touches only there.
                let (dx, dy) = (x1 % 13, y1 % 13 + if x1 % 13 == 0 { 1 } else { 0 });
                let (s, t) = (x0.rem_euclid(7) + 1, y0.rem_euclid(7) + 1);
                (Point::new(vi.x + s * dx, vi.y + s * dy), Point::new(vi.x - t * dx, vi.y - t * dy))
            }
            _ => (free_a, free_a),
        };
        (piece.clone(), a, b)
    })
}

/// Random simple polygons: star-shaped around a centre, 3–40 vertices at
/// strictly increasing angles and random radii (often non-convex), on a
/// coarse lattice half of the time (collinear runs and axis-aligned edges).
pub fn star_polygon(r: i32) -> impl Strategy<Value = Vec<Point>> {
    (any::<bool>(), prop::collection::vec((0u32..1000, 1i32..=r), 3..40)).prop_filter_map(
        "not simple after rounding",
        move |(coarse, raw)| {
            let n = raw.len();
            let mut out: Vec<Point> = Vec::new();
            for (k, (jit, rad)) in raw.into_iter().enumerate() {
                // Angle sectors keep the vertices in angular order: star-shaped.
                let a = (k as f64 + 0.1 + 0.8 * jit as f64 / 1000.0) / n as f64 * std::f64::consts::TAU;
                let (mut x, mut y) = ((rad as f64 * a.cos()).round() as i32, (rad as f64 * a.sin()).round() as i32);
                if coarse {
                    x = x / 50 * 50;
                    y = y / 50 * 50;
                }
                out.push(Point::new(x, y));
            }
            out.dedup();
            is_simple(&out).then_some(out)
        },
    )
}

/// Brute-force simplicity: at least three vertices, positive area, no two
/// non-adjacent edges meeting, no adjacent edges overlapping.
pub fn is_simple(p: &[Point]) -> bool {
    use echoloc::geometry::{orient, segments_intersect};
    let n = p.len();
    if n < 3 {
        return false;
    }
    let area: i128 = (1..n - 1).map(|i| orient(p[0], p[i], p[i + 1]) as i128).sum();
    if area == 0 {
        return false;
    }
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        if a == b {
            return false;
        }
        for j in 0..n {
            if j == i {
                continue;
            }
            let (c, d) = (p[j], p[(j + 1) % n]);
            let adjacent = (j + 1) % n == i || (i + 1) % n == j;
            if adjacent {
                // Adjacent edges may only share their common vertex: a
                // fold-back (collinear overlap) is not simple.
                let shared = if (i + 1) % n == j { b } else { a };
                let other = if (i + 1) % n == j { d } else { c };
                let mine = if (i + 1) % n == j { a } else { b };
                if orient(mine, shared, other) == 0 {
                    let dot = (mine.x as i64 - shared.x as i64) * (other.x as i64 - shared.x as i64)
                        + (mine.y as i64 - shared.y as i64) * (other.y as i64 - shared.y as i64);
                    if dot > 0 {
                        return false;
                    }
                }
            } else if segments_intersect(a, b, c, d) {
                return false;
            }
        }
    }
    true
}

/// xorshift64: a small fixed stream for tests that draw their own cases, so
/// a failure names its case and every run draws the same ones.
pub struct XorShift64(pub u64);

impl XorShift64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in [lo, hi) (up to the modulo's bias, negligible here).
    pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + (self.next_u64() % (hi - lo) as u64) as i64
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}
