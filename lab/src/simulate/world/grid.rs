//! A square grid over the map: conservative rasterisation of outlines, the
//! exact Euclidean distance transform, connected regions.
//!
//! A cell is *occupied* when its centre lies within half a cell diagonal of
//! an outline, so every obstacle point lies in an occupied cell. Then for any
//! point `q` within half a diagonal of a cell centre `x`, the true distance
//! from `q` to the obstacles is at least `edt(x) − diagonal` (the distance is
//! 1-Lipschitz): [`Grid::MARGIN`] is that diagonal.

use super::geom::{outline_dist, seg_dist, P};

/// Cell size, m: the ROS maps' own resolution.
pub const CELL_M: f64 = 0.05;
/// Most cells of a grid: 200 m x 200 m (the simulator keeps a few grids of
/// distances and labels: some 0.5 GB at most).
pub const MAX_CELLS: usize = 16_000_000;

/// A grid of `nx × ny` cells of [`CELL_M`]; cell `(i, j)` has its centre at
/// `(x0 + i·cell, y0 + j·cell)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Centre of cell (0, 0), m.
    pub x0: f64,
    /// Centre of cell (0, 0), m.
    pub y0: f64,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
}

impl Grid {
    /// A cell's full diagonal, m: the margin between grid and true distances.
    pub const MARGIN: f64 = CELL_M * std::f64::consts::SQRT_2;

    /// A grid covering `lo..hi` with `pad` metres around.
    pub fn covering(lo: P, hi: P, pad: f64) -> Self {
        let nx = (((hi.0 - lo.0) + 2.0 * pad) / CELL_M).ceil() as usize + 1;
        let ny = (((hi.1 - lo.1) + 2.0 * pad) / CELL_M).ceil() as usize + 1;
        Self { x0: lo.0 - pad, y0: lo.1 - pad, nx, ny }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// Index of cell `(i, j)`.
    pub fn idx(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    /// `(i, j)` of index `k`.
    pub fn ij(&self, k: usize) -> (usize, usize) {
        (k % self.nx, k / self.nx)
    }

    /// Centre of cell `k`, m.
    pub fn centre(&self, k: usize) -> P {
        let (i, j) = self.ij(k);
        (self.x0 + i as f64 * CELL_M, self.y0 + j as f64 * CELL_M)
    }

    /// The cell whose centre is nearest `p`, if `p` is on the grid.
    pub fn cell_of(&self, p: P) -> Option<usize> {
        let i = ((p.0 - self.x0) / CELL_M).round();
        let j = ((p.1 - self.y0) / CELL_M).round();
        if i < 0.0 || j < 0.0 || i >= self.nx as f64 || j >= self.ny as f64 {
            return None;
        }
        Some(self.idx(i as usize, j as usize))
    }

    /// Cells `(i0..=i1, j0..=j1)` whose centres may lie within `pad` of the box `lo..hi`.
    fn span(&self, lo: P, hi: P, pad: f64) -> (usize, usize, usize, usize) {
        let f = |v: f64, o: f64, n: usize| (((v - o) / CELL_M).floor().max(0.0) as usize).min(n - 1);
        let c = |v: f64, o: f64, n: usize| (((v - o) / CELL_M).ceil().max(0.0) as usize).min(n - 1);
        (
            f(lo.0 - pad, self.x0, self.nx),
            c(hi.0 + pad, self.x0, self.nx),
            f(lo.1 - pad, self.y0, self.ny),
            c(hi.1 + pad, self.y0, self.ny),
        )
    }

    /// Every cell whose centre is within `pad` of the convex outline `pts`.
    pub fn outline_cells(&self, pts: &[P], pad: f64) -> Vec<usize> {
        let Some((lo, hi)) = super::geom::bbox(pts) else { return Vec::new() };
        let (i0, i1, j0, j1) = self.span(lo, hi, pad);
        let mut out = Vec::new();
        for j in j0..=j1 {
            for i in i0..=i1 {
                let k = self.idx(i, j);
                if outline_dist(self.centre(k), pts) <= pad {
                    out.push(k);
                }
            }
        }
        out
    }

    /// Marks every cell whose centre is within `pad` of the convex outline `pts`.
    pub fn mark_outline(&self, occ: &mut [bool], pts: &[P], pad: f64) {
        for k in self.outline_cells(pts, pad) {
            occ[k] = true;
        }
    }

    /// Marks every cell whose centre is within `pad` of the polyline `pts`.
    pub fn mark_polyline(&self, occ: &mut [bool], pts: &[P], pad: f64) {
        for w in pts.windows(2) {
            let Some((lo, hi)) = super::geom::bbox(w) else { continue };
            let (i0, i1, j0, j1) = self.span(lo, hi, pad);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let k = self.idx(i, j);
                    if !occ[k] && seg_dist(self.centre(k), w[0], w[1]) <= pad {
                        occ[k] = true;
                    }
                }
            }
        }
    }

    /// Conservative occupancy: cells within half a diagonal of an outline.
    pub fn rasterise<'a>(&self, outlines: impl IntoIterator<Item = &'a [P]>) -> Vec<bool> {
        let mut occ = vec![false; self.len()];
        for o in outlines {
            self.mark_outline(&mut occ, o, Self::MARGIN / 2.0);
        }
        occ
    }

    /// Exact Euclidean distance, m, from every cell centre to the nearest
    /// occupied cell centre (infinite when none is occupied): Felzenszwalb &
    /// Huttenlocher, "Distance Transforms of Sampled Functions", 2012, by
    /// columns then rows.
    pub fn edt(&self, occ: &[bool]) -> Vec<f64> {
        const BIG: f64 = 1e20;
        let mut d: Vec<f64> = occ.iter().map(|&o| if o { 0.0 } else { BIG }).collect();
        let n = self.nx.max(self.ny);
        let (mut f, mut out, mut v, mut z) = (vec![0.0; n], vec![0.0; n], vec![0usize; n], vec![0.0; n + 1]);
        for i in 0..self.nx {
            for j in 0..self.ny {
                f[j] = d[self.idx(i, j)];
            }
            edt_1d(&f[..self.ny], &mut out[..self.ny], &mut v, &mut z);
            for j in 0..self.ny {
                d[self.idx(i, j)] = out[j];
            }
        }
        for j in 0..self.ny {
            let row = j * self.nx..(j + 1) * self.nx;
            f[..self.nx].copy_from_slice(&d[row.clone()]);
            edt_1d(&f[..self.nx], &mut out[..self.nx], &mut v, &mut z);
            d[row].copy_from_slice(&out[..self.nx]);
        }
        d.iter().map(|&s| if s >= BIG / 2.0 { f64::INFINITY } else { s.sqrt() * CELL_M }).collect()
    }

    /// The 8-connected regions of `free` cells: a label per cell (`u32::MAX`
    /// for cells not free) and, per label, its cells and whether it touches
    /// the grid's border.
    pub fn regions(&self, free: &[bool]) -> (Vec<u32>, Vec<Region>) {
        let mut label = vec![u32::MAX; self.len()];
        let mut regions = Vec::new();
        let mut stack = Vec::new();
        for s in 0..self.len() {
            if !free[s] || label[s] != u32::MAX {
                continue;
            }
            let id = regions.len() as u32;
            let mut r = Region { cells: Vec::new(), border: false };
            label[s] = id;
            stack.push(s);
            while let Some(k) = stack.pop() {
                r.cells.push(k);
                let (i, j) = self.ij(k);
                if i == 0 || j == 0 || i + 1 == self.nx || j + 1 == self.ny {
                    r.border = true;
                }
                for (ni, nj) in self.neighbours(i, j) {
                    let q = self.idx(ni, nj);
                    if free[q] && label[q] == u32::MAX {
                        label[q] = id;
                        stack.push(q);
                    }
                }
            }
            regions.push(r);
        }
        (label, regions)
    }

    /// The up to 8 neighbours of `(i, j)` on the grid.
    pub fn neighbours(&self, i: usize, j: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        const D: [(isize, isize); 8] = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)];
        D.iter().filter_map(move |&(di, dj)| {
            let (ni, nj) = (i as isize + di, j as isize + dj);
            (ni >= 0 && nj >= 0 && (ni as usize) < self.nx && (nj as usize) < self.ny)
                .then_some((ni as usize, nj as usize))
        })
    }

    /// Whether every cell the segment `a b` passes through (closed cells,
    /// so corners count) satisfies `ok`; `false` if it leaves the grid.
    pub fn segment_clear(&self, a: P, b: P, ok: impl Fn(usize) -> bool) -> bool {
        // Samples a quarter cell apart: every point of the segment is within
        // an eighth of a cell of one, so testing every cell within an eighth
        // of a cell of each sample tests every cell the segment touches.
        const SLACK: f64 = 0.125 + 1e-6;
        let len = libm::hypot(b.0 - a.0, b.1 - a.1);
        let steps = (len / (CELL_M / 4.0)).ceil().max(1.0) as usize;
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let p = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
            let fi = (p.0 - self.x0) / CELL_M;
            let fj = (p.1 - self.y0) / CELL_M;
            let (i0, i1) = ((fi - 0.5 - SLACK).ceil(), (fi + 0.5 + SLACK).floor());
            let (j0, j1) = ((fj - 0.5 - SLACK).ceil(), (fj + 0.5 + SLACK).floor());
            if i0 < 0.0 || j0 < 0.0 || i1 >= self.nx as f64 || j1 >= self.ny as f64 {
                return false;
            }
            for j in j0 as usize..=j1 as usize {
                for i in i0 as usize..=i1 as usize {
                    if !ok(self.idx(i, j)) {
                        return false;
                    }
                }
            }
        }
        true
    }
}

/// One connected region of free cells.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Region {
    /// Its cells.
    pub cells: Vec<usize>,
    /// Whether it touches the grid's border (the outside of a closed map).
    pub border: bool,
}

/// Squared 1-D distance transform of `f` (in cells²) into `d`: the lower
/// envelope of the parabolas `(q − p)² + f[p]`.
fn edt_1d(f: &[f64], d: &mut [f64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    let sep = |p: usize, q: usize| ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        let mut s = sep(v[k], q);
        // z[0] is −∞: the loop stops at k = 0 at the latest.
        while s <= z[k] {
            k -= 1;
            s = sep(v[k], q);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, dq) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let dx = q as f64 - p as f64;
        *dq = dx * dx + f[p];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edt_matches_brute_force() {
        let g = Grid { x0: 0.0, y0: 0.0, nx: 37, ny: 23 };
        let mut occ = vec![false; g.len()];
        for k in [5usize, 100, 101, 400, 777, 850] {
            occ[k] = true;
        }
        let d = g.edt(&occ);
        for (k, &dk) in d.iter().enumerate() {
            let c = g.centre(k);
            let brute = (0..g.len())
                .filter(|&q| occ[q])
                .map(|q| {
                    let o = g.centre(q);
                    (c.0 - o.0).hypot(c.1 - o.1)
                })
                .fold(f64::INFINITY, f64::min);
            assert!((dk - brute).abs() < 1e-9, "cell {k}: {dk} vs {brute}");
        }
        assert!(g.edt(&vec![false; g.len()]).iter().all(|v| v.is_infinite()));
    }
}
