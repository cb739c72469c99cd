//! Occupied cells → polygons with holes, by marching squares over the cell
//! centres.
//!
//! Samples are the cell centres (a free border of samples surrounds the
//! image). Each square of four samples gets contour segments between the
//! midpoints of its sides where the class changes, oriented with the
//! occupied side on the left, so outer boundaries run counter-clockwise and
//! holes clockwise. At a saddle (two occupied corners on a diagonal) the
//! occupied corners are joined: occupied cells connect through corners
//! (8-connectivity), free ones only through sides. Every side midpoint is
//! the start of exactly one segment and the end of one, so the segments
//! close into rings that never touch or cross. A ring belongs to the
//! 8-connected component of occupied cells on its left: one outer ring per
//! component, the others are its holes.
//!
//! Vertices are on a half-cell lattice: `(u, v)` = `(2·column + 1, 2·row + 1)`
//! at a cell centre, rows counted up from the bottom of the map.

use std::collections::HashMap;

/// A polygon with holes on the half-cell lattice.
#[derive(Clone, Debug, PartialEq)]
pub struct LatticePolygon {
    pub outer: Vec<(i64, i64)>,
    pub holes: Vec<Vec<(i64, i64)>>,
}

/// Traces the boundaries of `occ` (`width × height`, row 0 at the TOP, as
/// in the image). Polygons come in order of their components' first cell.
pub fn trace(occ: &[bool], width: usize, height: usize) -> Vec<LatticePolygon> {
    let (w, h) = (width as i64, height as i64);
    // Sample (i, j), j counted up from the bottom; outside is free.
    let at = |i: i64, j: i64| -> bool { i >= 0 && j >= 0 && i < w && j < h && occ[((h - 1 - j) * w + i) as usize] };
    // Components of occupied cells, 8-connected.
    let mut label = vec![u32::MAX; width * height];
    let mut comps = 0u32;
    let idx = |i: i64, j: i64| ((h - 1 - j) * w + i) as usize;
    let mut stack = Vec::new();
    for j in (0..h).rev() {
        for i in 0..w {
            if !at(i, j) || label[idx(i, j)] != u32::MAX {
                continue;
            }
            label[idx(i, j)] = comps;
            stack.push((i, j));
            while let Some((x, y)) = stack.pop() {
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        let (a, b) = (x + dx, y + dy);
                        if at(a, b) && label[idx(a, b)] == u32::MAX {
                            label[idx(a, b)] = comps;
                            stack.push((a, b));
                        }
                    }
                }
            }
            comps += 1;
        }
    }
    // Segments: start midpoint → end midpoint.
    let mut next: HashMap<(i64, i64), (i64, i64)> = HashMap::new();
    for j in -1..h {
        for i in -1..w {
            // Corners counter-clockwise: BL, BR, TR, TL; side k runs from
            // corner k to corner k + 1.
            let c = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            if c.iter().all(|&x| x) || c.iter().all(|&x| !x) {
                continue;
            }
            let mid = [(2 * i + 2, 2 * j + 1), (2 * i + 3, 2 * j + 2), (2 * i + 2, 2 * j + 3), (2 * i + 1, 2 * j + 2)];
            for k in 0..4 {
                if c[k] && !c[(k + 1) % 4] {
                    // Occupied → free: a segment starts here and ends at the
                    // next side (counter-clockwise) where free → occupied.
                    let e = (1..4).map(|d| (k + d) % 4).find(|&e| !c[e] && c[(e + 1) % 4]).unwrap_or(k);
                    next.insert(mid[k], mid[e]);
                }
            }
        }
    }
    // Rings, grouped by the component on their left.
    let mut starts: Vec<(i64, i64)> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut outers: Vec<Option<Vec<(i64, i64)>>> = vec![None; comps as usize];
    let mut holes: Vec<Vec<Vec<(i64, i64)>>> = vec![Vec::new(); comps as usize];
    for s in starts {
        if !next.contains_key(&s) {
            continue; // already traced
        }
        let mut ring = Vec::new();
        let mut p = s;
        while let Some(q) = next.remove(&p) {
            ring.push(p);
            p = q;
        }
        // The occupied sample beside the first vertex (a side midpoint).
        let (u, v) = ring[0];
        let (a, b) = if u % 2 == 0 {
            ((u / 2 - 1, (v - 1) / 2), (u / 2, (v - 1) / 2))
        } else {
            (((u - 1) / 2, v / 2 - 1), ((u - 1) / 2, v / 2))
        };
        let cell = if at(a.0, a.1) { a } else { b };
        let comp = label[idx(cell.0, cell.1)] as usize;
        let ring = drop_straight(ring);
        if area2(&ring) > 0 {
            outers[comp] = Some(ring);
        } else {
            holes[comp].push(ring);
        }
    }
    outers.into_iter().zip(holes).filter_map(|(o, holes)| o.map(|outer| LatticePolygon { outer, holes })).collect()
}

/// Drops vertices in the middle of straight runs.
fn drop_straight(ring: Vec<(i64, i64)>) -> Vec<(i64, i64)> {
    let n = ring.len();
    (0..n)
        .filter(|&k| {
            let (a, b, c) = (ring[(k + n - 1) % n], ring[k], ring[(k + 1) % n]);
            (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0) != 0
        })
        .map(|k| ring[k])
        .collect()
}

/// Twice the signed area of a lattice ring.
pub fn area2(r: &[(i64, i64)]) -> i128 {
    let n = r.len();
    (0..n).map(|k| (r[k].0 as i128) * (r[(k + 1) % n].1 as i128) - (r[(k + 1) % n].0 as i128) * (r[k].1 as i128)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(rows: &[&str]) -> (Vec<bool>, usize, usize) {
        let w = rows[0].len();
        (rows.iter().flat_map(|r| r.bytes().map(|b| b == b'#')).collect(), w, rows.len())
    }

    #[test]
    fn one_cell_is_a_diamond() {
        let (g, w, h) = grid(&["...", ".#.", "..."]);
        let p = trace(&g, w, h);
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].outer.len(), 4);
        assert_eq!(area2(&p[0].outer), 4); // half a cell: 2 lattice units² × 2
        assert!(p[0].holes.is_empty());
    }

    #[test]
    fn a_ring_of_walls_has_one_hole_and_diagonals_connect() {
        let (g, w, h) = grid(&["#####", "#...#", "#...#", "#####", ".....", "#....", ".#..."]);
        let p = trace(&g, w, h);
        assert_eq!(p.len(), 2, "{p:?}");
        assert_eq!(p[0].holes.len(), 1);
        assert!(area2(&p[0].holes[0]) < 0);
        assert!(p[1].holes.is_empty(), "diagonal pair is one component");
    }
}
