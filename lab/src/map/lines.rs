//! Straight walls from an occupancy grid (`map import --walls lines`,
//! issue #35, DESIGN §4.9): a sonar hears a long wall as one face, so the
//! map holds it as one line through the cells the wall's surface lies in,
//! not as a staircase round their free faces with a speck at every gap.
//!
//! 1. **Surface cells**: occupied cells next to a known-free one (what a
//!    range sensor saw; a wall's inside is not a surface).
//! 2. **Walls**: surface cells within [`LINK_M`] of each other are one
//!    group (a dotted wall is one wall); each group is split until every
//!    cell lies within the **deviation bound** ε of its line (total least
//!    squares; split where the farthest cell projects), and a line is cut
//!    where its cells leave a gap wider than [`GAP_M`] (a door).
//!    Neighbouring lines that one line fits within ε are merged again.
//! 3. **Corners**: two walls whose ends lie within [`CLOSE_M`] of their
//!    lines' crossing are drawn to it, so an inside corner is closed.
//! 4. **Specks**: a group too short for a wall ([`MIN_WALL_M`]) stays as the
//!    square round its cells (a post, a chair leg, or noise).
//!
//! The bound: every surface cell's centre lies within ε of a wall or
//! inside a speck's square (`every_surface_cell_is_within_the_bound`).
//! The wall runs through the cells' centres: where the surface is, half a
//! cell behind the free faces the contour follows.

use echoloc::geometry::Point;

use super::build::Shape;
use super::ros::{Cell, Grid};

/// Surface cells this close are one wall's, m (bridges a dotted wall: a
/// single pass, one scan a metre, leaves gaps of a few cells along walls
/// it saw at a glancing angle).
pub const LINK_M: f64 = 0.4;
/// A gap along a line wider than this ends the wall, m (a door is 0.7 m or more).
pub const GAP_M: f64 = 0.5;
/// A group shorter than this is a speck, m ...
pub const MIN_WALL_M: f64 = 0.2;
/// ... or with fewer cells than this (two posts are not a wall).
pub const MIN_WALL_CELLS: usize = 3;
/// Ends this close to their lines' crossing are drawn to it, m.
pub const CLOSE_M: f64 = 0.2;
/// Most splits of one group (a bound on the work for any grid).
const MAX_DEPTH: usize = 24;

/// A point, m.
type P = (f64, f64);

/// How the walls are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineOptions {
    /// The deviation bound ε, m (0: one cell).
    pub tolerance_m: f64,
}

/// A wall: its ends, m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    pub a: P,
    pub b: P,
}

/// What the extraction made.
#[derive(Clone, Debug, Default)]
pub struct Lines {
    pub walls: Vec<Wall>,
    /// Specks: squares (corners, m).
    pub specks: Vec<[P; 4]>,
    /// Surface cells in all.
    pub surface_cells: usize,
}

/// Whether a cell counts as occupied (`unknown_occupied`: unknown cells too).
fn occupied(c: Cell, unknown_occupied: bool) -> bool {
    c == Cell::Occupied || (unknown_occupied && c == Cell::Unknown)
}

/// The lines of `g`.
pub fn extract(g: &Grid, unknown_occupied: bool, o: &LineOptions) -> Lines {
    let res = g.yaml.resolution;
    let eps = if o.tolerance_m > 0.0 { o.tolerance_m } else { res };
    let (w, h) = (g.width as i64, g.height as i64);
    let centre = |c: i64, r: i64| {
        (g.yaml.origin[0] + (c as f64 + 0.5) * res, g.yaml.origin[1] + ((h - 1 - r) as f64 + 0.5) * res)
    };
    // 1. Surface cells.
    let at = |c: i64, r: i64| (c >= 0 && r >= 0 && c < w && r < h).then(|| g.cells[(r * w + c) as usize]);
    let mut surface: Vec<(i64, i64)> = Vec::new();
    let mut index = vec![u32::MAX; g.cells.len()];
    for r in 0..h {
        for c in 0..w {
            if !at(c, r).is_some_and(|x| occupied(x, unknown_occupied)) {
                continue;
            }
            let free_next = (-1..=1).any(|dr| (-1..=1).any(|dc| at(c + dc, r + dr) == Some(Cell::Free)));
            if free_next {
                index[(r * w + c) as usize] = surface.len() as u32;
                surface.push((c, r));
            }
        }
    }
    // 2. Groups within LINK_M.
    let k = (LINK_M / res).floor().max(1.0) as i64;
    let mut group = vec![u32::MAX; surface.len()];
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for s in 0..surface.len() {
        if group[s] != u32::MAX {
            continue;
        }
        let id = groups.len() as u32;
        let mut members = vec![s];
        group[s] = id;
        let mut i = 0;
        while i < members.len() {
            let (c, r) = surface[members[i]];
            for dr in -k..=k {
                for dc in -k..=k {
                    if (dr * dr + dc * dc) as f64 * res * res > LINK_M * LINK_M + 1e-12 {
                        continue;
                    }
                    let (cc, rr) = (c + dc, r + dr);
                    if cc < 0 || rr < 0 || cc >= w || rr >= h {
                        continue;
                    }
                    let j = index[(rr * w + cc) as usize];
                    if j != u32::MAX && group[j as usize] == u32::MAX {
                        group[j as usize] = id;
                        members.push(j as usize);
                    }
                }
            }
            i += 1;
        }
        groups.push(members);
    }
    let mut out = Lines { surface_cells: surface.len(), ..Lines::default() };
    let half = res / 2.0;
    for members in &groups {
        let pts: Vec<P> = members.iter().map(|&s| centre(surface[s].0, surface[s].1)).collect();
        let mut segs: Vec<Vec<P>> = Vec::new();
        split(&pts, eps, 0, &mut segs);
        let mut walls: Vec<(Wall, Vec<P>)> = Vec::new();
        for seg in segs {
            for run in by_gaps(&seg) {
                match fit(&run) {
                    Some((wall, _)) if run.len() >= MIN_WALL_CELLS && len(wall) + res >= MIN_WALL_M => {
                        walls.push((extend(wall, half), run))
                    }
                    _ => out.specks.extend(run.iter().map(|&p| square(p, half))),
                }
            }
        }
        merge(&mut walls, eps, half);
        out.walls.extend(walls.into_iter().map(|(w, _)| w));
    }
    close_corners(&mut out.walls);
    out.specks.sort_by(|a, b| a[0].0.total_cmp(&b[0].0).then(a[0].1.total_cmp(&b[0].1)));
    out.specks.dedup();
    out
}

/// Splits `p` until each part fits a line within `eps`.
fn split(p: &[P], eps: f64, depth: usize, out: &mut Vec<Vec<P>>) {
    let Some((_, (m, d))) = fit(p) else {
        out.push(p.to_vec());
        return;
    };
    let dist = |q: P| ((q.0 - m.0) * -d.1 + (q.1 - m.1) * d.0).abs();
    let proj = |q: P| (q.0 - m.0) * d.0 + (q.1 - m.1) * d.1;
    let (far, worst) = p.iter().map(|&q| (q, dist(q))).fold(((0.0, 0.0), -1.0), |a, b| if b.1 > a.1 { b } else { a });
    if worst <= eps || depth >= MAX_DEPTH || p.len() < 3 {
        out.push(p.to_vec());
        return;
    }
    let mut t: Vec<f64> = p.iter().map(|&q| proj(q)).collect();
    let mut cut = proj(far);
    let (lo, hi) = t.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &v| (a.0.min(v), a.1.max(v)));
    // The farthest cell at an end splits nothing: cut in the middle instead.
    if cut <= lo + 1e-9 || cut >= hi - 1e-9 {
        t.sort_by(f64::total_cmp);
        cut = t[t.len() / 2];
    }
    let (a, b): (Vec<P>, Vec<P>) = p.iter().partition(|&&q| proj(q) <= cut);
    if a.is_empty() || b.is_empty() {
        out.push(p.to_vec());
        return;
    }
    split(&a, eps, depth + 1, out);
    split(&b, eps, depth + 1, out);
}

/// The runs of `p` along its line with no gap wider than [`GAP_M`].
fn by_gaps(p: &[P]) -> Vec<Vec<P>> {
    let Some((_, (m, d))) = fit(p) else { return vec![p.to_vec()] };
    let mut q: Vec<(f64, P)> = p.iter().map(|&v| ((v.0 - m.0) * d.0 + (v.1 - m.1) * d.1, v)).collect();
    q.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<Vec<P>> = vec![Vec::new()];
    for (i, &(t, v)) in q.iter().enumerate() {
        if i > 0 && t - q[i - 1].0 > GAP_M {
            out.push(Vec::new());
        }
        if let Some(last) = out.last_mut() {
            last.push(v);
        }
    }
    out
}

/// The total-least-squares line through `p`: the wall from its first to
/// its last projection, and (centroid, unit direction).
fn fit(p: &[P]) -> Option<(Wall, (P, P))> {
    if p.is_empty() {
        return None;
    }
    let n = p.len() as f64;
    let m = (p.iter().map(|v| v.0).sum::<f64>() / n, p.iter().map(|v| v.1).sum::<f64>() / n);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for v in p {
        let (x, y) = (v.0 - m.0, v.1 - m.1);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let d = (th.cos(), th.sin());
    let (lo, hi) = p
        .iter()
        .map(|v| (v.0 - m.0) * d.0 + (v.1 - m.1) * d.1)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, t| (a.0.min(t), a.1.max(t)));
    Some((Wall { a: (m.0 + lo * d.0, m.1 + lo * d.1), b: (m.0 + hi * d.0, m.1 + hi * d.1) }, (m, d)))
}

fn len(w: Wall) -> f64 {
    (w.b.0 - w.a.0).hypot(w.b.1 - w.a.1)
}

/// The wall lengthened by `by` at each end (to its end cells' far sides).
fn extend(w: Wall, by: f64) -> Wall {
    let l = len(w);
    if l < 1e-12 {
        return w;
    }
    let d = ((w.b.0 - w.a.0) / l, (w.b.1 - w.a.1) / l);
    Wall { a: (w.a.0 - d.0 * by, w.a.1 - d.1 * by), b: (w.b.0 + d.0 * by, w.b.1 + d.1 * by) }
}

fn square(p: P, half: f64) -> [P; 4] {
    [(p.0 - half, p.1 - half), (p.0 + half, p.1 - half), (p.0 + half, p.1 + half), (p.0 - half, p.1 + half)]
}

/// Merges walls whose cells one line fits within `eps` (and leave no gap).
fn merge(walls: &mut Vec<(Wall, Vec<P>)>, eps: f64, half: f64) {
    loop {
        let mut merged = false;
        'outer: for i in 0..walls.len() {
            for j in i + 1..walls.len() {
                let (a, b) = (&walls[i], &walls[j]);
                let near = [a.0.a, a.0.b]
                    .iter()
                    .any(|&p| [b.0.a, b.0.b].iter().any(|&q| (p.0 - q.0).hypot(p.1 - q.1) <= GAP_M));
                if !near {
                    continue;
                }
                let mut pts = a.1.clone();
                pts.extend_from_slice(&b.1);
                let Some((wall, (m, d))) = fit(&pts) else { continue };
                let fits = pts.iter().all(|q| ((q.0 - m.0) * -d.1 + (q.1 - m.1) * d.0).abs() <= eps);
                if fits && by_gaps(&pts).len() == 1 {
                    walls[i] = (extend(wall, half), pts);
                    walls.remove(j);
                    merged = true;
                    break 'outer;
                }
            }
        }
        if !merged {
            return;
        }
    }
}

/// Draws ends lying within [`CLOSE_M`] of two walls' crossing to it.
fn close_corners(walls: &mut [Wall]) {
    let n = walls.len();
    for i in 0..n {
        for j in i + 1..n {
            let (u, v) = (walls[i], walls[j]);
            let (du, dv) = ((u.b.0 - u.a.0, u.b.1 - u.a.1), (v.b.0 - v.a.0, v.b.1 - v.a.1));
            let den = du.0 * dv.1 - du.1 * dv.0;
            let (lu, lv) = (len(u), len(v));
            // Nearly parallel walls meet nowhere near.
            if lu < 1e-9 || lv < 1e-9 || (den / (lu * lv)).abs() < 0.5 {
                continue;
            }
            let w0 = (v.a.0 - u.a.0, v.a.1 - u.a.1);
            let s = (w0.0 * dv.1 - w0.1 * dv.0) / den;
            let t = (w0.0 * du.1 - w0.1 * du.0) / den;
            let x = (u.a.0 + s * du.0, u.a.1 + s * du.1);
            let end_of = |w: Wall, param: f64, l: f64| -> Option<bool> {
                // Which end is near the crossing (true: b), if one is within CLOSE_M.
                if (param * l).abs() <= CLOSE_M {
                    Some(false)
                } else if ((param - 1.0) * l).abs() <= CLOSE_M {
                    Some(true)
                } else {
                    let _ = w;
                    None
                }
            };
            if let (Some(eu), Some(ev)) = (end_of(u, s, lu), end_of(v, t, lv)) {
                if eu {
                    walls[i].b = x;
                } else {
                    walls[i].a = x;
                }
                if ev {
                    walls[j].b = x;
                } else {
                    walls[j].a = x;
                }
            }
        }
    }
}

/// The shapes of the extraction, mm: each wall a two-point wall, each speck
/// a square.
pub fn shapes(l: &Lines) -> Vec<Shape> {
    let mm = |p: P| Point::new((p.0 * 1000.0).round() as i32, (p.1 * 1000.0).round() as i32);
    let mut out: Vec<Shape> =
        l.walls.iter().filter(|w| mm(w.a) != mm(w.b)).map(|w| Shape::Wall(vec![mm(w.a), mm(w.b)])).collect();
    out.extend(l.specks.iter().map(|s| Shape::Solid { outer: s.iter().map(|&p| mm(p)).collect(), holes: Vec::new() }));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::ros::{MapYaml, Mode};

    /// A grid of `w`×`h` cells of 5 cm, free, with `occ` (column, row from
    /// the bottom) occupied.
    fn grid(w: usize, h: usize, occ: &[(usize, usize)]) -> Grid {
        let mut cells = vec![Cell::Free; w * h];
        for &(c, r) in occ {
            cells[(h - 1 - r) * w + c] = Cell::Occupied;
        }
        let yaml = MapYaml {
            image: "x.pgm".into(),
            resolution: 0.05,
            origin: [0.0, 0.0, 0.0],
            negate: false,
            occupied_thresh: 0.65,
            free_thresh: 0.196,
            mode: Mode::Trinary,
        };
        Grid { width: w, height: h, cells, yaml }
    }

    fn dist_to_segment(p: P, w: &Wall) -> f64 {
        let (dx, dy) = (w.b.0 - w.a.0, w.b.1 - w.a.1);
        let l2 = dx * dx + dy * dy;
        let t = if l2 > 0.0 { (((p.0 - w.a.0) * dx + (p.1 - w.a.1) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
        (p.0 - w.a.0 - t * dx).hypot(p.1 - w.a.1 - t * dy)
    }

    #[test]
    fn a_dotted_staircase_wall_is_one_line() {
        // A 10 m wall at 3° to the x axis, one cell in three missing: a
        // staircase with gaps, as a single pass maps it.
        let mut occ = Vec::new();
        for c in 10..210 {
            if c % 3 == 0 {
                continue;
            }
            let r = 20 + ((c - 10) as f64 * 3f64.to_radians().tan()).round() as usize;
            occ.push((c, r));
        }
        let g = grid(230, 60, &occ);
        let l = extract(&g, false, &LineOptions { tolerance_m: 0.0 });
        assert_eq!(l.walls.len(), 1, "{:?}", l.walls);
        assert!(l.specks.is_empty());
        let w = l.walls[0];
        assert!((len(w) - 200.0 * 0.05 / 3f64.to_radians().cos()).abs() < 0.15, "{w:?}");
        for &(c, r) in &occ {
            let p = (0.05 * (c as f64 + 0.5), 0.05 * (r as f64 + 0.5));
            assert!(dist_to_segment(p, &w) <= 0.05 + 1e-9, "{p:?}");
        }
    }

    #[test]
    fn a_room_is_four_walls_closed_at_its_corners_and_a_door_cuts_one() {
        // A 4 m × 3 m room of one-cell walls, a 0.8 m door in the bottom wall.
        let mut occ = Vec::new();
        for c in 10..=90 {
            if !(40..56).contains(&c) {
                occ.push((c, 10));
            }
            occ.push((c, 70));
        }
        for r in 10..=70 {
            occ.push((10, r));
            occ.push((90, r));
        }
        // Free inside and out, so every wall cell is a surface.
        let g = grid(100, 80, &occ);
        let l = extract(&g, false, &LineOptions { tolerance_m: 0.0 });
        assert_eq!(l.walls.len(), 5, "{:?}", l.walls);
        // Every corner of the room is the end of two walls.
        for corner in [(0.525, 0.525), (4.525, 0.525), (0.525, 3.525), (4.525, 3.525)] {
            let ends = l
                .walls
                .iter()
                .flat_map(|w| [w.a, w.b])
                .filter(|e| (e.0 - corner.0).hypot(e.1 - corner.1) < 0.03)
                .count();
            assert_eq!(ends, 2, "corner {corner:?}: {:?}", l.walls);
        }
    }

    #[test]
    fn every_surface_cell_is_within_the_bound() {
        // A curved wall (a quarter circle of 3 m), a pillar and noise.
        let mut occ = Vec::new();
        for k in 0..=300 {
            let a = f64::from(k) / 300.0 * std::f64::consts::FRAC_PI_2;
            occ.push(((20.0 + 60.0 * a.cos()).round() as usize, (20.0 + 60.0 * a.sin()).round() as usize));
        }
        for c in 50..54 {
            for r in 40..44 {
                occ.push((c, r));
            }
        }
        occ.push((95, 5));
        let g = grid(100, 100, &occ);
        let eps = 0.04;
        let l = extract(&g, false, &LineOptions { tolerance_m: eps });
        assert!(l.walls.len() >= 4 && l.walls.len() <= 40, "{}", l.walls.len());
        for &(c, r) in &occ {
            let p = (0.05 * (c as f64 + 0.5), 0.05 * (r as f64 + 0.5));
            let on_wall = l.walls.iter().any(|w| dist_to_segment(p, w) <= eps + 1e-9);
            let in_speck = l
                .specks
                .iter()
                .any(|s| p.0 >= s[0].0 - 1e-9 && p.0 <= s[2].0 + 1e-9 && p.1 >= s[0].1 - 1e-9 && p.1 <= s[2].1 + 1e-9);
            // Interior cells of the pillar are not surfaces.
            let interior = (51..53).contains(&c) && (41..43).contains(&r);
            assert!(on_wall || in_speck || interior, "cell ({c}, {r}) at {p:?}");
        }
        assert!(l.specks.iter().any(|s| (s[0].0 - 4.75).abs() < 1e-9), "the noise cell stays a speck");
    }
}
