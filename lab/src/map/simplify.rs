//! Simplification of a polygon with holes with a guaranteed error bound,
//! keeping it valid.
//!
//! Douglas–Peucker on each closed ring with the exact distance to the
//! *segment* (not its line), compared squared in `i128`: every dropped vertex
//! lies within `tol` of the segment that replaces it, so every point of the
//! old boundary is within `tol` of the new one and back (Hausdorff distance
//! ≤ `tol`). Kept vertices are original vertices.
//!
//! Validity is then checked exactly — no two segments of any of the
//! polygon's rings meet (other than neighbours at their shared vertex), each
//! ring keeps its orientation — and every segment in a conflict is refined
//! (its farthest dropped vertex comes back) until none is left. Refining
//! converges to the original rings, which are valid. A hole no wider than
//! `2·tol` in x or y is dropped: every point of it lies within `tol` of its
//! boundary, so the bound still holds.

use echoloc::geometry::{dot, orient, ring_area2, segments_intersect, strictly_inside, Point};

/// Squared distance from `p` to the closed segment `ab`, compared with
/// `tol²`: whether `p` lies within `tol` of it. Exact.
pub fn within(p: Point, a: Point, b: Point, tol: i64) -> bool {
    dist2_cmp(p, a, b, tol * tol)
}

fn dist2_cmp(p: Point, a: Point, b: Point, t2: i64) -> bool {
    let (dx, dy) = b.sub(a);
    let (px, py) = p.sub(a);
    let dot = dx as i128 * px as i128 + dy as i128 * py as i128;
    let len2 = dx as i128 * dx as i128 + dy as i128 * dy as i128;
    if dot <= 0 || len2 == 0 {
        return p.dist2(a) as i128 <= t2 as i128;
    }
    if dot >= len2 {
        return p.dist2(b) as i128 <= t2 as i128;
    }
    let cr = dx as i128 * py as i128 - dy as i128 * px as i128;
    cr * cr <= t2 as i128 * len2
}

/// A measure growing with the distance from `p` to segment `ab`, for
/// picking the farthest vertex: (squared distance numerator, denominator).
fn far(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = b.sub(a);
    let (px, py) = p.sub(a);
    let len2 = (dx * dx + dy * dy) as f64;
    let dot = (dx * px + dy * py) as f64;
    if len2 == 0.0 || dot <= 0.0 {
        return p.dist2(a) as f64;
    }
    if dot >= len2 {
        return p.dist2(b) as f64;
    }
    let cr = (dx * py - dy * px) as f64;
    cr * cr / len2
}

/// The farthest vertex of `ring` strictly between positions `s` and `e`
/// (cyclic) from segment `ring[s] ring[e]`, with whether it lies beyond `tol`.
fn farthest(ring: &[Point], s: usize, e: usize, tol: i64) -> Option<(usize, bool)> {
    let n = ring.len();
    let (a, b) = (ring[s], ring[e % n]);
    let mut best: Option<(usize, f64)> = None;
    let mut k = (s + 1) % n;
    while k != e % n {
        let d = far(ring[k], a, b);
        if best.is_none_or(|(_, bd)| d > bd) {
            best = Some((k, d));
        }
        k = (k + 1) % n;
    }
    best.map(|(k, _)| (k, !within(ring[k], a, b, tol)))
}

/// Douglas–Peucker on a closed ring: which vertices to keep (at least three).
fn dp_ring(ring: &[Point], tol: i64) -> Vec<bool> {
    let n = ring.len();
    let mut keep = vec![false; n];
    if n <= 3 {
        return vec![true; n];
    }
    // Anchors: vertex 0 and the vertex farthest from it.
    let f = (1..n).max_by_key(|&k| ring[k].dist2(ring[0])).unwrap_or(1);
    keep[0] = true;
    keep[f] = true;
    let mut stack = vec![(0usize, f), (f, n)];
    while let Some((s, e)) = stack.pop() {
        if let Some((k, beyond)) = farthest(ring, s, e, tol) {
            if beyond {
                keep[k] = true;
                let k = if k < s { k + n } else { k };
                stack.push((s, k));
                stack.push((k % n, if e <= k % n { e + n } else { e }));
            }
        }
    }
    // At least a triangle: the farthest vertex from the chord 0–f.
    if keep.iter().filter(|&&k| k).count() < 3 {
        let k = (1..n).filter(|&k| k != f).max_by(|&x, &y| {
            far(ring[x], ring[0], ring[f])
                .partial_cmp(&far(ring[y], ring[0], ring[f]))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        if let Some(k) = k {
            keep[k] = true;
        }
    }
    keep
}

/// The simplified polygon (outer ring, holes) and whether it fell back to the
/// original rings.
pub fn simplify(outer: &[Point], holes: &[Vec<Point>], tol: u32) -> (Vec<Point>, Vec<Vec<Point>>) {
    let tol = tol as i64;
    if tol == 0 {
        return (outer.to_vec(), holes.to_vec());
    }
    let holes: Vec<&Vec<Point>> = holes
        .iter()
        .filter(|h| {
            let (x0, x1) = (h.iter().map(|p| p.x).min().unwrap_or(0), h.iter().map(|p| p.x).max().unwrap_or(0));
            let (y0, y1) = (h.iter().map(|p| p.y).min().unwrap_or(0), h.iter().map(|p| p.y).max().unwrap_or(0));
            (x1 - x0) as i64 > 2 * tol && (y1 - y0) as i64 > 2 * tol
        })
        .collect();
    let rings: Vec<&[Point]> = std::iter::once(outer).chain(holes.iter().map(|h| h.as_slice())).collect();
    let mut keep: Vec<Vec<bool>> = rings.iter().map(|r| dp_ring(r, tol)).collect();
    for _round in 0..200 {
        let simple: Vec<Vec<usize>> =
            keep.iter().map(|k| k.iter().enumerate().filter(|(_, &b)| b).map(|(i, _)| i).collect()).collect();
        let bad = conflicts(&rings, &simple);
        if bad.is_empty() {
            let pick = |r: usize| simple[r].iter().map(|&i| rings[r][i]).collect::<Vec<_>>();
            return (pick(0), (1..rings.len()).map(pick).collect());
        }
        let mut progress = false;
        for (r, seg) in bad {
            let idx = &simple[r];
            let (s, e) = (idx[seg], if seg + 1 < idx.len() { idx[seg + 1] } else { idx[0] + rings[r].len() });
            if let Some((k, _)) = farthest(rings[r], s, e, tol) {
                progress |= !keep[r][k];
                keep[r][k] = true;
            }
        }
        if !progress {
            break;
        }
    }
    // Cannot happen (refining ends at the valid original); kept as a guard.
    (outer.to_vec(), holes.iter().map(|h| h.to_vec()).collect())
}

/// Segments (ring, index in the simplified ring) that take part in a
/// conflict: two segments meeting that must not, or a ring whose
/// orientation flipped or vanished (all its segments).
fn conflicts(rings: &[&[Point]], simple: &[Vec<usize>]) -> Vec<(usize, usize)> {
    let mut bad = std::collections::BTreeSet::new();
    // Segments, with their x-range for a sweep.
    let mut segs: Vec<(i32, i32, usize, usize, Point, Point)> = Vec::new();
    // Each simplified ring's points, built once.
    let kept: Vec<Vec<Point>> =
        simple.iter().enumerate().map(|(r, idx)| idx.iter().map(|&i| rings[r][i]).collect()).collect();
    for (r, pts) in kept.iter().enumerate() {
        let idx = &simple[r];
        let want = ring_area2(rings[r]).signum();
        if pts.len() < 3 || ring_area2(pts).signum() != want {
            bad.extend((0..idx.len()).map(|s| (r, s)));
        }
        for s in 0..pts.len() {
            let (a, b) = (pts[s], pts[(s + 1) % pts.len()]);
            segs.push((a.x.min(b.x), a.x.max(b.x), r, s, a, b));
        }
    }
    // A hole that left the outer ring without crossing it.
    let outer = &kept[0];
    for r in 1..simple.len() {
        if let Some(&i) = simple[r].first() {
            if !strictly_inside(outer, rings[r][i]) {
                bad.extend((0..outer.len()).map(|s| (0, s)));
                bad.extend((0..simple[r].len()).map(|s| (r, s)));
            }
        }
    }
    segs.sort_unstable_by_key(|s| s.0);
    let mut active: Vec<usize> = Vec::new();
    for i in 0..segs.len() {
        let (x0, _, r, s, a, b) = segs[i];
        active.retain(|&j| segs[j].1 >= x0);
        for &j in &active {
            let (_, _, r2, s2, c, d) = segs[j];
            if a.y.max(b.y) < c.y.min(d.y) || c.y.max(d.y) < a.y.min(b.y) {
                continue;
            }
            let n = simple[r].len();
            let meet = if r == r2 && ((s + 1) % n == s2 || (s2 + 1) % n == s) {
                // Neighbours share a vertex; they must not fold back onto
                // each other. (A two-segment ring is caught by its area.)
                let (p, q, t) = if (s + 1) % n == s2 { (a, b, d) } else { (c, d, b) };
                orient(p, q, t) == 0 && dot(q.sub(p), t.sub(q)) <= 0
            } else {
                segments_intersect(a, b, c, d)
            };
            if meet {
                bad.insert((r, s));
                bad.insert((r2, s2));
            }
        }
        active.push(i);
    }
    bad.into_iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts(v: &[(i32, i32)]) -> Vec<Point> {
        v.iter().map(|&(x, y)| Point::new(x, y)).collect()
    }

    #[test]
    fn staircase_becomes_a_line_within_tolerance() {
        // A 45° staircase of 50 mm steps and a big triangle around it.
        let mut r = vec![Point::new(0, 0)];
        for k in 0..20 {
            r.push(Point::new(50 * k + 50, 50 * k));
            r.push(Point::new(50 * k + 50, 50 * k + 50));
        }
        r.push(Point::new(0, 1000));
        let (o, _) = simplify(&r, &[], 40);
        assert!(o.len() <= 4, "{o:?}");
        for p in &r {
            let n = o.len();
            assert!((0..n).any(|i| within(*p, o[i], o[(i + 1) % n], 40)));
        }
    }

    #[test]
    fn a_thin_gap_is_not_closed() {
        // The outer ring dips 90 mm; a hole sits in the dip. Straightening
        // the dip (within tol = 100) would cut the hole: refinement keeps it.
        let outer = pts(&[(0, 0), (500, -90), (1000, 0), (1000, 1000), (0, 1000)]);
        let hole = pts(&[(400, -30), (700, -30), (700, 300), (400, 300)]);
        let (o, h) = simplify(&outer, std::slice::from_ref(&hole), 100);
        assert_eq!(h.len(), 1);
        assert!(o.contains(&Point::new(500, -90)), "{o:?}");
        assert_eq!(conflicts(&[&o, &h[0]], &[(0..o.len()).collect(), (0..h[0].len()).collect()]), vec![]);
        // A hole no wider than 2·tol is dropped.
        let slit = pts(&[(100, 500), (100, 520), (900, 520), (900, 500)]);
        let (_, h) = simplify(&outer, &[slit], 20);
        assert!(h.is_empty());
    }

    #[test]
    fn exact_distance_to_segment() {
        let (a, b) = (Point::new(0, 0), Point::new(100, 0));
        assert!(within(Point::new(50, 10), a, b, 10));
        assert!(!within(Point::new(50, 11), a, b, 10));
        assert!(within(Point::new(106, 8), a, b, 10)); // 6² + 8² = 100
        assert!(!within(Point::new(107, 8), a, b, 10));
    }
}
