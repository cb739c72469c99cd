//! The grid peers: the map rasterised into an occupancy grid, and the two
//! ways robots cast rays on one: Bresenham's line (ROS amcl's beam model,
//! `map_calc_range`) and ray marching on a Euclidean distance transform
//! (range_libc's "RM", `RayMarching::calc_range`).
//!
//! Written from those programs' descriptions, in `f64` and plain cells, not
//! from echoloc's geometry: the grid is made from the true pieces' vertices
//! by a separating-axis test per cell.

/// An occupancy grid: `true` = occupied. Cell `(i, j)` covers
/// `[x0 + i·res, x0 + (i+1)·res) × [y0 + j·res, …)`, metres.
pub struct Grid {
    pub w: usize,
    pub h: usize,
    pub res: f64,
    pub x0: f64,
    pub y0: f64,
    cells: Vec<u8>,
}

impl Grid {
    /// Rasterises convex outlines (m, counter-clockwise; two points for a
    /// thin wall): a cell is occupied when its square meets a piece
    /// (separating axes: the square's two, and each edge's normal). The
    /// grid covers the outlines' bounds plus `margin` cells.
    pub fn rasterise(outlines: &[Vec<(f64, f64)>], res: f64, margin: usize) -> Self {
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for p in outlines.iter().flatten() {
            lo = (lo.0.min(p.0), lo.1.min(p.1));
            hi = (hi.0.max(p.0), hi.1.max(p.1));
        }
        if lo.0 > hi.0 {
            lo = (0.0, 0.0);
            hi = (0.0, 0.0);
        }
        let m = margin as f64 * res;
        let (x0, y0) = (lo.0 - m, lo.1 - m);
        let w = ((hi.0 + m - x0) / res).ceil() as usize + 1;
        let h = ((hi.1 + m - y0) / res).ceil() as usize + 1;
        let mut g = Self { w, h, res, x0, y0, cells: vec![0; w * h] };
        for pts in outlines {
            let (bl, bh) = pts.iter().fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(l, h), p| {
                ((l.0.min(p.0), l.1.min(p.1)), (h.0.max(p.0), h.1.max(p.1)))
            });
            let (i0, j0) = g.cell_of(bl);
            let (i1, j1) = g.cell_of(bh);
            for j in j0.max(0)..=j1.min(h as i64 - 1) {
                for i in i0.max(0)..=i1.min(w as i64 - 1) {
                    let sq = (x0 + i as f64 * res, y0 + j as f64 * res);
                    if square_meets(sq, res, pts) {
                        g.cells[j as usize * w + i as usize] = 1;
                    }
                }
            }
        }
        g
    }

    /// The cell holding `p` (may be outside the grid).
    pub fn cell_of(&self, p: (f64, f64)) -> (i64, i64) {
        (((p.0 - self.x0) / self.res).floor() as i64, ((p.1 - self.y0) / self.res).floor() as i64)
    }

    /// Occupied (outside the grid counts as occupied, as amcl's map does).
    pub fn occupied(&self, i: i64, j: i64) -> bool {
        if i < 0 || j < 0 || i >= self.w as i64 || j >= self.h as i64 {
            return true;
        }
        self.cells[j as usize * self.w + i as usize] != 0
    }

    /// The cells as bits, row-major, bit `k % 8` of byte `k / 8` for cell
    /// `k = j·w + i` (for the firmware's copy of the grid).
    pub fn packed_bits(&self) -> Vec<u8> {
        let mut out = vec![0u8; self.cells.len().div_ceil(8)];
        for (k, &c) in self.cells.iter().enumerate() {
            if c != 0 {
                out[k / 8] |= 1 << (k % 8);
            }
        }
        out
    }

    /// Bytes of the grid (one per cell, as a ROS occupancy grid).
    pub fn bytes(&self) -> usize {
        self.cells.len()
    }

    /// amcl's `map_calc_range`: Bresenham from the cell of `o` towards the
    /// point `max` metres along `dir`; the range to the first occupied cell
    /// (cell count along the line × resolution, as amcl computes it), or
    /// `None` if none within `max`.
    pub fn bresenham(&self, o: (f64, f64), dir: (f64, f64), max: f64) -> Option<f64> {
        self.bresenham_steps(o, dir, max, i64::MAX)
    }

    /// [`Self::bresenham`]'s line (to `max`: the same cells), walked only
    /// while its cells are within `limit` (≤ `max`) of the start, by the
    /// range amcl reports (cells' offsets `(dx, dy)`, `dx² + dy² ≤
    /// (limit / res)²`; it only grows along the walk). Any hit within
    /// `limit` is the unpruned answer; `None` means none within `limit`.
    pub fn bresenham_within(&self, o: (f64, f64), dir: (f64, f64), max: f64, limit: f64) -> Option<f64> {
        let l = limit / self.res;
        self.bresenham_steps(o, dir, max, (l * l).floor() as i64)
    }

    #[inline(always)]
    fn bresenham_steps(&self, o: (f64, f64), dir: (f64, f64), max: f64, max_d2: i64) -> Option<f64> {
        let (ax, ay) = self.cell_of(o);
        let (bx, by) = self.cell_of((o.0 + dir.0 * max, o.1 + dir.1 * max));
        let steep = (by - ay).abs() > (bx - ax).abs();
        let (x0, y0, x1, y1) = if steep { (ay, ax, by, bx) } else { (ax, ay, bx, by) };
        let (dx, dy) = ((x1 - x0).abs(), (y1 - y0).abs());
        let xstep = if x0 < x1 { 1 } else { -1 };
        let ystep = if y0 < y1 { 1 } else { -1 };
        let hit = |x: i64, y: i64| if steep { self.occupied(y, x) } else { self.occupied(x, y) };
        let (mut x, mut y, mut error) = (x0, y0, 0);
        loop {
            if max_d2 != i64::MAX && (x - x0) * (x - x0) + (y - y0) * (y - y0) > max_d2 {
                return None;
            }
            if hit(x, y) {
                let r = ((x - x0) as f64).hypot((y - y0) as f64) * self.res;
                return (r <= max).then_some(r);
            }
            if x == x1 {
                return None;
            }
            x += xstep;
            error += dy;
            if 2 * error >= dx {
                y += ystep;
                error -= dx;
            }
        }
    }
}

/// Whether the square at `sq` (lower-left corner) of side `s` meets the
/// convex outline `pts` (two points: a segment).
fn square_meets(sq: (f64, f64), s: f64, pts: &[(f64, f64)]) -> bool {
    let corners = [sq, (sq.0 + s, sq.1), (sq.0 + s, sq.1 + s), (sq.0, sq.1 + s)];
    let mut axes: Vec<(f64, f64)> = vec![(1.0, 0.0), (0.0, 1.0)];
    let n = pts.len();
    for k in 0..n {
        let (a, b) = (pts[k], pts[(k + 1) % n]);
        if a != b {
            axes.push((-(b.1 - a.1), b.0 - a.0));
        }
        if n == 2 {
            break;
        }
    }
    axes.iter().all(|&ax| {
        let proj = |p: &(f64, f64)| p.0 * ax.0 + p.1 * ax.1;
        let (a0, a1) = corners.iter().map(proj).fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
        let (b0, b1) = pts.iter().map(proj).fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
        a0 <= b1 && b0 <= a1
    })
}

/// The Euclidean distance transform of a grid (Felzenszwalb and
/// Huttenlocher's two-pass lower envelope of parabolas): per cell, the
/// distance in cells from its centre to the nearest occupied cell's centre.
pub struct DistanceMap {
    w: usize,
    h: usize,
    d: Vec<f32>,
}

impl DistanceMap {
    pub fn of(g: &Grid) -> Self {
        let (w, h) = (g.w, g.h);
        const INF: f64 = 1e20;
        let mut f: Vec<f64> = (0..w * h).map(|k| if g.cells[k] != 0 { 0.0 } else { INF }).collect();
        // Columns, then rows: squared distances.
        let mut col = vec![0.0; h];
        for i in 0..w {
            for j in 0..h {
                col[j] = f[j * w + i];
            }
            let out = dt1(&col);
            for j in 0..h {
                f[j * w + i] = out[j];
            }
        }
        for j in 0..h {
            let out = dt1(&f[j * w..(j + 1) * w]);
            f[j * w..(j + 1) * w].copy_from_slice(&out);
        }
        Self { w, h, d: f.into_iter().map(|v| v.sqrt() as f32).collect() }
    }

    pub fn bytes(&self) -> usize {
        self.d.len() * 4
    }

    fn at(&self, i: i64, j: i64) -> f32 {
        if i < 0 || j < 0 || i >= self.w as i64 || j >= self.h as i64 {
            return 0.0;
        }
        self.d[j as usize * self.w + i as usize]
    }

    /// range_libc's ray marching: from `o` along `dir`, step by the
    /// distance to the nearest obstacle (at least one cell) until it is
    /// under half a cell; the travelled distance, or `None` past `max`.
    pub fn march(&self, g: &Grid, o: (f64, f64), dir: (f64, f64), max: f64) -> Option<f64> {
        let max_cells = max / g.res;
        let (mut x, mut y) = ((o.0 - g.x0) / g.res, (o.1 - g.y0) / g.res);
        let mut t = 0.0;
        while t <= max_cells {
            let d = f64::from(self.at(x.floor() as i64, y.floor() as i64));
            if d <= 0.5 {
                return Some(t * g.res);
            }
            let step = (d * 0.999).max(1.0);
            t += step;
            x += dir.0 * step;
            y += dir.1 * step;
        }
        None
    }
}

/// One dimension of the squared distance transform.
fn dt1(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut d = vec![0.0; n];
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * q as f64 - 2.0 * p as f64);
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            if s <= z[k] {
                // k == 0: replace the only parabola.
                v[0] = q;
                z[0] = f64::NEG_INFINITY;
                z[1] = f64::INFINITY;
                break;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    k = 0;
    for (q, out) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        *out = (q as f64 - p as f64).powi(2) + f[p];
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_transform_matches_brute_force() {
        let outlines = vec![
            vec![(0.3, 0.3), (0.5, 0.3), (0.5, 0.45), (0.3, 0.45)],
            vec![(1.0, 0.2), (1.2, 0.9)],
            vec![(0.1, 1.0), (0.6, 0.9), (0.4, 1.2)],
        ];
        let g = Grid::rasterise(&outlines, 0.05, 3);
        let dm = DistanceMap::of(&g);
        let occ: Vec<(usize, usize)> =
            (0..g.h).flat_map(|j| (0..g.w).map(move |i| (i, j))).filter(|&(i, j)| g.cells[j * g.w + i] != 0).collect();
        assert!(!occ.is_empty());
        for j in 0..g.h {
            for i in 0..g.w {
                let brute = occ
                    .iter()
                    .map(|&(a, b)| ((a as f64 - i as f64).powi(2) + (b as f64 - j as f64).powi(2)).sqrt())
                    .fold(f64::MAX, f64::min);
                assert!((f64::from(dm.at(i as i64, j as i64)) - brute).abs() < 1e-4, "({i}, {j})");
            }
        }
    }

    #[test]
    fn bresenham_and_marching_find_a_wall_ahead() {
        let wall = vec![vec![(2.0, -1.0), (2.0, 1.0)]];
        let g = Grid::rasterise(&wall, 0.05, 60);
        let dm = DistanceMap::of(&g);
        let o = (0.0, 0.0);
        let b = g.bresenham(o, (1.0, 0.0), 5.5).unwrap();
        let m = dm.march(&g, o, (1.0, 0.0), 5.5).unwrap();
        for r in [b, m] {
            assert!((r - 2.0).abs() <= 0.05 * 2f64.sqrt() + 1e-9, "{r}");
        }
        // Backwards, within the grid (it starts 1 m behind the sensor): nothing.
        assert_eq!(g.bresenham(o, (-1.0, 0.0), 0.9), None);
        assert_eq!(dm.march(&g, o, (-1.0, 0.0), 0.9), None);
    }
}
