//! The route: shortest paths on the grid between random goals in the
//! largest free region that holds the clearance, shortcut by line of sight,
//! chained until the requested length.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::config::WorldError;
use super::geom::P;
use super::grid::{Grid, CELL_M};
use crate::credence::rng::Rng;

/// Smallest extent of the free region to drive in, m: below it the route
/// would only turn on the spot.
const MIN_EXTENT_M: f64 = 1.0;
/// Goals are drawn at least this far (straight line) from the robot, m, or
/// half the region's extent if that is less: legs long enough to see the map.
const GOAL_MIN_M: f64 = 3.0;
/// Draws of a goal before settling for any reachable cell.
const GOAL_TRIES: usize = 50;
/// Legs in a row that add no length before the planner gives up.
const STALLED_LEGS: usize = 20;

/// The free space the route is planned in.
pub struct FreeSpace<'g> {
    grid: &'g Grid,
    /// Cells whose every point within half a diagonal keeps the clearance.
    free: Vec<bool>,
    /// The region the route lives in.
    region: Vec<usize>,
    /// Whether each cell is in the region.
    in_region: Vec<bool>,
    /// The clearance, m (for messages).
    clearance_m: f64,
}

impl<'g> FreeSpace<'g> {
    /// The largest 8-connected region of cells at least `clearance + margin`
    /// from every obstacle cell (`dist` from [`Grid::edt`]), preferring
    /// regions that do not reach the grid's border (the outside of a closed
    /// building).
    pub fn new(grid: &'g Grid, dist: &[f64], clearance_m: f64) -> Result<Self, WorldError> {
        let free: Vec<bool> = dist.iter().map(|&d| d >= clearance_m + Grid::MARGIN).collect();
        let (_, regions) = grid.regions(&free);
        let best = |inner: bool| {
            regions.iter().filter(|r| !inner || !r.border).max_by_key(|r| r.cells.len()).filter(|r| !r.cells.is_empty())
        };
        let region = best(true).or_else(|| best(false)).ok_or(WorldError::NoFreeSpace { clearance_m })?;
        let pts: Vec<P> = region.cells.iter().map(|&k| grid.centre(k)).collect();
        let extent = super::geom::bbox(&pts).map(|(lo, hi)| libm::hypot(hi.0 - lo.0, hi.1 - lo.1)).unwrap_or(0.0);
        if extent < MIN_EXTENT_M {
            return Err(WorldError::TooSmall { clearance_m, extent_m: extent });
        }
        let mut in_region = vec![false; grid.len()];
        for &k in &region.cells {
            in_region[k] = true;
        }
        Ok(Self { grid, free, region: region.cells.clone(), in_region, clearance_m })
    }

    /// The region's extent (bounding box diagonal), m.
    fn extent(&self) -> f64 {
        let pts: Vec<P> = self.region.iter().map(|&k| self.grid.centre(k)).collect();
        super::geom::bbox(&pts).map(|(lo, hi)| libm::hypot(hi.0 - lo.0, hi.1 - lo.1)).unwrap_or(0.0)
    }

    /// The route: `distance_m` long (the last leg cut to fit), starting at a
    /// random cell of the region.
    pub fn route(&self, distance_m: f64, rng: &mut Rng) -> Result<Vec<P>, WorldError> {
        let at = self.region[((rng.next_f64() * self.region.len() as f64) as usize).min(self.region.len() - 1)];
        self.route_from(at, distance_m, rng)
    }

    /// The region's cell holding `p`, if `p` is in the region (a kidnapped
    /// robot must be set down where the route can go on).
    pub fn region_cell(&self, p: P) -> Option<usize> {
        self.grid.cell_of(p).filter(|&k| self.in_region[k])
    }

    /// A route `distance_m` long from cell `start` of the region.
    pub fn route_from(&self, start: usize, distance_m: f64, rng: &mut Rng) -> Result<Vec<P>, WorldError> {
        let pick = |rng: &mut Rng| {
            self.region[((rng.next_f64() * self.region.len() as f64) as usize).min(self.region.len() - 1)]
        };
        let goal_min = GOAL_MIN_M.min(self.extent() / 2.0);
        let mut at = start;
        let mut route = vec![self.grid.centre(at)];
        let mut length = 0.0;
        let mut stalled = 0;
        let mut scratch = Scratch {
            cost: vec![f64::INFINITY; self.grid.len()],
            from: vec![usize::MAX; self.grid.len()],
            touched: Vec::new(),
        };
        while length < distance_m {
            let here = self.grid.centre(at);
            let mut goal = pick(rng);
            for _ in 0..GOAL_TRIES {
                let g = self.grid.centre(goal);
                if libm::hypot(g.0 - here.0, g.1 - here.1) >= goal_min {
                    break;
                }
                goal = pick(rng);
            }
            let leg = self.shortcut(&self.astar(at, goal, &mut scratch));
            let added: f64 = leg.windows(2).map(|w| libm::hypot(w[1].0 - w[0].0, w[1].1 - w[0].1)).sum();
            if added < CELL_M {
                stalled += 1;
                if stalled >= STALLED_LEGS {
                    return Err(WorldError::TooSmall { clearance_m: self.clearance_m, extent_m: self.extent() });
                }
                continue;
            }
            stalled = 0;
            route.extend_from_slice(&leg[1..]);
            length += added;
            at = goal;
        }
        cut_to_length(&mut route, distance_m);
        Ok(route)
    }

    /// The shortest 8-connected path from `a` to `b` inside the region, as cell
    /// centres (A* with the octile distance, exact for 8-connected moves).
    fn astar(&self, a: usize, b: usize, scratch: &mut Scratch) -> Vec<P> {
        let g = self.grid;
        let Scratch { cost, from, touched } = scratch;
        for &k in touched.iter() {
            cost[k] = f64::INFINITY;
            from[k] = usize::MAX;
        }
        touched.clear();
        let (bi, bj) = g.ij(b);
        let h = |k: usize| {
            let (i, j) = g.ij(k);
            let (dx, dy) = ((i as f64 - bi as f64).abs(), (j as f64 - bj as f64).abs());
            (dx.max(dy) + (std::f64::consts::SQRT_2 - 1.0) * dx.min(dy)) * CELL_M
        };
        let mut open = BinaryHeap::new();
        cost[a] = 0.0;
        touched.push(a);
        open.push(Open { f: h(a), k: a });
        while let Some(Open { f, k }) = open.pop() {
            if k == b {
                break;
            }
            if f > cost[k] + h(k) {
                continue; // a stale entry: k was reached more cheaply since
            }
            let (i, j) = g.ij(k);
            for (ni, nj) in g.neighbours(i, j) {
                let q = g.idx(ni, nj);
                if !self.in_region[q] {
                    continue;
                }
                let step = if ni != i && nj != j { CELL_M * std::f64::consts::SQRT_2 } else { CELL_M };
                let c = cost[k] + step;
                if c < cost[q] {
                    if cost[q] == f64::INFINITY {
                        touched.push(q);
                    }
                    cost[q] = c;
                    from[q] = k;
                    open.push(Open { f: c + h(q), k: q });
                }
            }
        }
        let mut path = vec![g.centre(b)];
        let mut k = b;
        while k != a {
            k = from[k];
            if k == usize::MAX {
                // Unreachable cannot happen inside one region; stay put.
                return vec![g.centre(a)];
            }
            path.push(g.centre(k));
        }
        path.reverse();
        path
    }

    /// Greedy line-of-sight shortcutting: from each kept point, the farthest
    /// later point in sight through cells that all keep the clearance.
    fn shortcut(&self, path: &[P]) -> Vec<P> {
        let mut out = vec![path[0]];
        let mut i = 0;
        while i + 1 < path.len() {
            let mut j = i + 1;
            while j + 1 < path.len() && self.grid.segment_clear(path[i], path[j + 1], |k| self.free[k]) {
                j += 1;
            }
            out.push(path[j]);
            i = j;
        }
        out
    }
}

/// A* working arrays, kept between legs (only the cells a search touched are reset).
struct Scratch {
    cost: Vec<f64>,
    from: Vec<usize>,
    touched: Vec<usize>,
}

/// Cuts a polyline to `length` from its start.
fn cut_to_length(route: &mut Vec<P>, length: f64) {
    let mut acc = 0.0;
    for i in 1..route.len() {
        let (a, b) = (route[i - 1], route[i]);
        let l = libm::hypot(b.0 - a.0, b.1 - a.1);
        if acc + l >= length {
            let t = if l > 0.0 { (length - acc) / l } else { 0.0 };
            route[i] = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
            route.truncate(i + 1);
            return;
        }
        acc += l;
    }
}

/// An open A* node, ordered by least `f` (then by cell, for determinism).
#[derive(PartialEq)]
struct Open {
    f: f64,
    k: usize,
}

impl Eq for Open {}

impl Ord for Open {
    fn cmp(&self, o: &Self) -> Ordering {
        o.f.total_cmp(&self.f).then_with(|| o.k.cmp(&self.k))
    }
}

impl PartialOrd for Open {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// Length of a polyline, m.
pub fn length(route: &[P]) -> f64 {
    route.windows(2).map(|w| libm::hypot(w[1].0 - w[0].0, w[1].1 - w[0].1)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cut_keeps_the_start_and_the_length() {
        let mut r = vec![(0.0, 0.0), (3.0, 0.0), (3.0, 4.0)];
        cut_to_length(&mut r, 5.0);
        assert_eq!(r, vec![(0.0, 0.0), (3.0, 0.0), (3.0, 2.0)]);
        assert!((length(&r) - 5.0).abs() < 1e-12);
    }
}
