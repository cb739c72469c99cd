//! Splitting a simple polygon into convex pieces: ear clipping, then
//! Hertel–Mehlhorn merging of triangles across diagonals while the union stays
//! convex (at most four times the minimum number of pieces). Import-time work:
//! it runs on the host, but is `no_std` and allocation-free like the rest.

use heapless::Vec;

use super::{orient, HolesError, Point, MAX_PIECE_VERTICES};

/// Why a polygon could not be split.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SplitError<E> {
    /// Fewer than three distinct, non-collinear vertices: no area.
    Degenerate,
    /// More vertices than the working capacity `N`.
    TooManyVertices,
    /// A coordinate beyond `±COORD_MAX`.
    CoordinateOutOfRange,
    /// Two non-adjacent edges meet: the polygon is not simple.
    NotSimple {
        /// Index of the first edge (its start vertex, after cleaning).
        edge_a: usize,
        /// Index of the second edge.
        edge_b: usize,
    },
    /// No ear was found (cannot happen for a simple polygon; kept as a guard).
    NoEar,
    /// The caller's sink refused a piece.
    Sink(E),
}

const NONE: u16 = u16::MAX;

/// Splits the simple polygon `poly` (either orientation, any number of
/// collinear or repeated vertices) into strictly convex counter-clockwise
/// pieces of at most `max_piece_vertices` vertices (clamped to
/// `3..=MAX_PIECE_VERTICES`), handing each to `emit`. `N` is the working
/// capacity: the most vertices `poly` may have (at most 65 535). Returns the
/// number of pieces.
///
/// The pieces cover the polygon exactly: their areas add up to its area and
/// their interiors are disjoint.
///
/// ```
/// use echoloc::geometry::{split_convex, Point};
/// // An L shape: six vertices, one reflex corner.
/// let l = [(0, 0), (20, 0), (20, 10), (10, 10), (10, 20), (0, 20)].map(|(x, y)| Point::new(x, y));
/// let mut n = 0;
/// let count = split_convex::<16, ()>(&l, 24, |piece| { n += piece.len(); Ok(()) }).unwrap();
/// assert_eq!(count, 2);
/// ```
pub fn split_convex<const N: usize, E>(
    poly: &[Point],
    max_piece_vertices: usize,
    emit: impl FnMut(&[Point]) -> Result<(), E>,
) -> Result<usize, SplitError<E>> {
    // A polygon without holes: the same checks, cleaning, orientation and
    // clipping as with holes, with the errors named for a single ring.
    super::split_convex_with_holes::<N, E>(poly, &[], max_piece_vertices, emit).map_err(|e| match e {
        HolesError::TooManyVertices => SplitError::TooManyVertices,
        HolesError::CoordinateOutOfRange(_) => SplitError::CoordinateOutOfRange,
        HolesError::Degenerate(_) => SplitError::Degenerate,
        HolesError::Intersect { edge_a, edge_b, .. } => SplitError::NotSimple { edge_a, edge_b },
        HolesError::Sink(e) => SplitError::Sink(e),
        // Bridges and nesting concern holes: with none, only the guard remains.
        HolesError::NoEar | HolesError::HoleOutside(_) | HolesError::NestedHoles { .. } | HolesError::NoBridge(_) => {
            SplitError::NoEar
        }
    })
}

/// Twice the signed area of a ring (positive when counter-clockwise), exact
/// (`i128`: the sum of many `i64` terms may exceed `i64`); 0 below three
/// vertices.
///
/// ```
/// use echoloc::geometry::{ring_area2, Point};
/// let sq = [Point::new(0, 0), Point::new(10, 0), Point::new(10, 10), Point::new(0, 10)];
/// assert_eq!(ring_area2(&sq), 200);
/// ```
pub fn ring_area2(ring: &[Point]) -> i128 {
    let n = ring.len();
    if n < 3 {
        return 0;
    }
    (1..n - 1).map(|i| orient(ring[0], ring[i], ring[i + 1]) as i128).sum()
}

/// Drops repeated and collinear vertices (straight runs and zero-width
/// spikes) from the cyclic ring `pts[from..]` until none is left.
pub(super) fn clean_ring<const N: usize>(pts: &mut Vec<Point, N>, from: usize) {
    loop {
        let before = pts.len();
        let mut i = 0;
        while pts.len() - from >= 3 && i < pts.len() - from {
            let m = pts.len() - from;
            let (a, b, c) = (pts[from + (i + m - 1) % m], pts[from + i], pts[from + (i + 1) % m]);
            if a == b || orient(a, b, c) == 0 {
                pts.remove(from + i);
            } else {
                i += 1;
            }
        }
        if pts.len() == before {
            break;
        }
    }
}

/// Why [`clip_and_merge`] stopped.
pub(super) enum ClipError<E> {
    NoEar,
    Sink(E),
}

/// Ear clipping, then Hertel–Mehlhorn merging, of the counter-clockwise ring
/// `pts`. The ring may be *weakly* simple — the output of bridging holes
/// into an outer ring: two vertices may share a position (a bridge's ends
/// appear twice) as long as the polygon's interior wedges there do not
/// overlap and no vertex lies inside another edge. Hands each strictly convex
/// counter-clockwise piece (at most `maxv` vertices) to `emit`; returns the
/// number of pieces.
pub(super) fn clip_and_merge<const N: usize, E>(
    pts: &[Point],
    maxv: usize,
    mut emit: impl FnMut(&[Point]) -> Result<(), E>,
) -> Result<usize, ClipError<E>> {
    let n = pts.len();
    if n < 3 || n > N {
        return Err(ClipError::NoEar);
    }
    // Ear clipping, remembering which triangle lies across each chain edge
    // so that the diagonals (and the triangles on both sides) are known.
    let mut rem: Vec<u16, N> = (0..n as u16).collect();
    let mut across: Vec<u16, N> = (0..n).map(|_| NONE).collect();
    let mut tris: Vec<[u16; 3], N> = Vec::new();
    // (u, v, t1, t2): t1 holds the directed edge u→v, t2 holds v→u.
    let mut diags: Vec<(u16, u16, u16, u16), N> = Vec::new();
    let mut i = 0usize;
    let mut misses = 0usize;
    let at = |k: u16| pts[k as usize];
    while rem.len() > 3 {
        let m = rem.len();
        i %= m;
        let (ip, ii, iq) = (rem[(i + m - 1) % m], rem[i], rem[(i + 1) % m]);
        let (a, b, c) = (at(ip), at(ii), at(iq));
        let o = orient(a, b, c);
        if o == 0 && (a == b || b == c || super::dot(b.sub(a), c.sub(b)) <= 0) {
            // A repeated vertex or a zero-width spike (left by an earlier
            // clip, or where a bridge folds back): dropping it changes no
            // area. The merged chain edge loses its neighbour (no diagonal
            // to merge across).
            rem.remove(i);
            across[ip as usize] = NONE;
            misses = 0;
            continue;
        }
        // A straight vertex (o == 0, b strictly between a and c) is no ear
        // tip; it stays, so that no other vertex ends up inside an edge.
        // Other vertices at a corner's position (a bridge's twin) cannot
        // reach into the triangle: their wedges lie outside this corner's.
        let is_ear = o > 0
            && rem.iter().all(|&r| {
                let p = at(r);
                r == ip
                    || r == ii
                    || r == iq
                    || p == a
                    || p == b
                    || p == c
                    || !(orient(a, b, p) >= 0 && orient(b, c, p) >= 0 && orient(c, a, p) >= 0)
            });
        if is_ear {
            let t = tris.len() as u16;
            let _ = tris.push([ip, ii, iq]);
            if across[ip as usize] != NONE {
                let _ = diags.push((ip, ii, t, across[ip as usize]));
            }
            if across[ii as usize] != NONE {
                let _ = diags.push((ii, iq, t, across[ii as usize]));
            }
            across[ip as usize] = t;
            rem.remove(i);
            i = i.saturating_sub(1);
            misses = 0;
        } else {
            i += 1;
            misses += 1;
            if misses > m {
                // Only straight vertices left (no area): done. Anything
                // else is a guard that a valid input never reaches.
                let p0 = at(rem[0]);
                let p1 = rem.iter().map(|&k| at(k)).find(|&p| p != p0).unwrap_or(p0);
                if rem.iter().all(|&k| orient(p0, p1, at(k)) == 0) {
                    rem.clear();
                    break;
                }
                return Err(ClipError::NoEar);
            }
        }
    }
    if rem.len() == 3 && orient(at(rem[0]), at(rem[1]), at(rem[2])) > 0 {
        let t = tris.len() as u16;
        let _ = tris.push([rem[0], rem[1], rem[2]]);
        for k in 0..3 {
            let (u, v) = (rem[k], rem[(k + 1) % 3]);
            if across[u as usize] != NONE {
                let _ = diags.push((u, v, t, across[u as usize]));
            }
        }
    }
    // Hertel–Mehlhorn: merge across each diagonal while convex.
    let mut pieces: Vec<Vec<u16, MAX_PIECE_VERTICES>, N> =
        tris.iter().map(|t| Vec::from_slice(t).unwrap_or_default()).collect();
    let mut parent: Vec<u16, N> = (0..tris.len() as u16).collect();
    let find = |parent: &mut Vec<u16, N>, mut x: u16| {
        while parent[x as usize] != x {
            let up = parent[parent[x as usize] as usize];
            parent[x as usize] = up;
            x = up;
        }
        x
    };
    for &(u, v, t1, t2) in diags.iter() {
        let (a, b) = (find(&mut parent, t1), find(&mut parent, t2));
        if a == b {
            continue;
        }
        if let Some(merged) = merge(pts, &pieces[a as usize], &pieces[b as usize], u, v, maxv) {
            pieces[a as usize] = merged;
            pieces[b as usize].clear();
            parent[b as usize] = a;
        }
    }
    // Emit.
    let mut count = 0;
    let mut buf: Vec<Point, MAX_PIECE_VERTICES> = Vec::new();
    for piece in pieces.iter().filter(|p| !p.is_empty()) {
        buf.clear();
        for &k in piece {
            let _ = buf.push(at(k));
        }
        emit(&buf).map_err(ClipError::Sink)?;
        count += 1;
    }
    Ok(count)
}

/// Merges convex pieces `a` (holding edge u→v) and `b` (holding v→u) if the
/// union is convex and small enough; collinear vertices at u or v are dropped.
fn merge(pts: &[Point], a: &[u16], b: &[u16], u: u16, v: u16, maxv: usize) -> Option<Vec<u16, MAX_PIECE_VERTICES>> {
    let (na, nb) = (a.len(), b.len());
    let ia = (0..na).find(|&k| a[k] == u && a[(k + 1) % na] == v)?;
    let ib = (0..nb).find(|&k| b[k] == v && b[(k + 1) % nb] == u)?;
    // Walk a from v round to u, then b after u up to (not including) v.
    let mut ring: Vec<u16, { 2 * MAX_PIECE_VERTICES }> = Vec::new();
    for k in 0..na {
        ring.push(a[(ia + 1 + k) % na]).ok()?;
    }
    for k in 0..nb - 2 {
        ring.push(b[(ib + 2 + k) % nb]).ok()?;
    }
    let at = |k: u16| pts[k as usize];
    let m = ring.len();
    // Only the corners at u (index na-1) and v (index 0) changed.
    let turn = |k: usize| orient(at(ring[(k + m - 1) % m]), at(ring[k]), at(ring[(k + 1) % m]));
    let (tu, tv) = (turn(na - 1), turn(0));
    if tu < 0 || tv < 0 {
        return None;
    }
    let mut out: Vec<u16, MAX_PIECE_VERTICES> = Vec::new();
    for (k, &idx) in ring.iter().enumerate() {
        if (k == na - 1 && tu == 0) || (k == 0 && tv == 0) {
            continue;
        }
        if out.len() == maxv {
            return None;
        }
        out.push(idx).ok()?;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Convex;

    fn pts(v: &[(i32, i32)]) -> [Point; 32] {
        let mut out = [Point::default(); 32];
        for (o, &(x, y)) in out.iter_mut().zip(v) {
            *o = Point::new(x, y);
        }
        out
    }

    fn split_area(poly: &[Point]) -> (usize, i64) {
        let mut area = 0;
        let n = split_convex::<64, ()>(poly, 24, |piece| {
            let c = Convex::new(piece).expect("piece must be strictly convex");
            area += c.area2();
            Ok(())
        })
        .unwrap();
        (n, area)
    }

    #[test]
    fn convex_stays_one_piece_either_orientation() {
        let sq = pts(&[(0, 0), (10, 0), (10, 10), (0, 10)]);
        assert_eq!(split_area(&sq[..4]), (1, 200));
        let cw = pts(&[(0, 0), (0, 10), (10, 10), (10, 0)]);
        assert_eq!(split_area(&cw[..4]), (1, 200));
    }

    #[test]
    fn collinear_and_repeated_vertices_are_dropped() {
        let sq = pts(&[(0, 0), (5, 0), (10, 0), (10, 0), (10, 10), (0, 10)]);
        assert_eq!(split_area(&sq[..6]), (1, 200));
    }

    #[test]
    fn comb_splits_into_convex_teeth() {
        // A comb with three teeth: area = base 30x10 + 3 teeth 5x10.
        let c = pts(&[
            (0, 0),
            (30, 0),
            (30, 20),
            (25, 20),
            (25, 10),
            (15, 10),
            (15, 20),
            (10, 20),
            (10, 10),
            (5, 10),
            (5, 20),
            (0, 20),
        ]);
        let (n, a) = split_area(&c[..12]);
        assert_eq!(a, 2 * (300 + 3 * 50));
        assert!((3..=8).contains(&n), "{n} pieces");
    }

    #[test]
    fn bad_inputs() {
        let bow = pts(&[(0, 0), (10, 10), (10, 0), (0, 10)]);
        assert!(matches!(split_convex::<8, ()>(&bow[..4], 24, |_| Ok(())), Err(SplitError::NotSimple { .. })));
        let line = pts(&[(0, 0), (5, 0), (10, 0)]);
        assert_eq!(split_convex::<8, ()>(&line[..3], 24, |_| Ok(())), Err(SplitError::Degenerate));
        let sq = pts(&[(0, 0), (10, 0), (10, 10), (0, 10)]);
        assert_eq!(split_convex::<3, ()>(&sq[..4], 24, |_| Ok(())), Err(SplitError::TooManyVertices));
        assert_eq!(split_convex::<8, u8>(&sq[..4], 24, |_| Err(7)), Err(SplitError::Sink(7)));
    }
}
