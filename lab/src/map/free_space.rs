//! Free space of a GeoJSON map: where the localization field's free nodes,
//! and so the particles, may be (`docs/maps.md`, "Free space").
//!
//! A ROS occupancy grid says itself where the robot can be (its known-free
//! cells). A GeoJSON map is only obstacles, so its free space is, in order:
//!
//! 1. **given**: the union of the map's `free` polygons (Features with
//!    `"kind": "free"`, Polygon or MultiPolygon, holes allowed), when it has any;
//! 2. **enclosed**: else the region the walls and outlines enclose, with
//!    every gap up to a door's width ([`DEFAULT_DOOR_MM`], `--door-mm`)
//!    counted as closed: the points from which every path to far away
//!    crosses a wall or an obstacle's outline or squeezes through a gap no
//!    wider than a door, less the obstacles' insides. Walls need not meet
//!    end to end: crossings, T-junctions, a room drawn as the hole of a
//!    solid, and a building drawn with its doorways and entrance open all
//!    enclose;
//! 3. **bounding box**: else (a map of obstacles in the open, nothing
//!    enclosed) the old rule, the obstacles' bounding box, with a warning
//!    in the import's summary naming the fix.
//!
//! In every case the field then keeps its clearance from every obstacle.
//!
//! The enclosed region is found on a lattice of [`STEP_MM`] (coarser on maps
//! of more than [`MAX_LATTICE`] points), a morphological closing of the
//! drawing by a disc of the door's width:
//!
//! 1. the lattice points within half a door and half a lattice step of a
//!    wall (exact integer distances) are *near*; the rest are *deep* (the
//!    half step: a path between lattice points crosses a gap's line within
//!    half a step of one of them, so no gap up to a door wide lets deep
//!    points through, wherever it lies on the lattice);
//! 2. a flood from the lattice's border over deep points, along lattice
//!    edges that touch no wall, reaches the outside's deep points: no path
//!    of them passes a gap up to a door wide, whose middle is near;
//! 3. every other component of deep points is a room's core (or a solid's
//!    inside, by an exact point-in-polygon test of one of its points);
//! 4. the near points are shared out by one breadth-first flood from all
//!    the cores at once, along edges that touch no wall, so a doorway is
//!    split where the two floods meet (about its middle) and the strip
//!    along a wall goes to the side of the wall it is on;
//! 5. what no flood reached is wholly walled in: enclosed, as before.
//!
//! With `door_mm = 0` this is the plain flood of #37: only the walls
//! themselves block. A point between lattice points takes the label of a
//! lattice corner of its cell that it sees without touching a wall. A gap
//! wider than a door by four lattice steps (0.2 m) or more stays open (one
//! within that of the door's width may close, as the lattice falls; both
//! tested), and a map whose outer walls have one is open there.

use std::collections::VecDeque;

use echoloc::geometry::Point;

use super::Shape;

/// The lattice step, mm (before coarsening).
pub const STEP_MM: i64 = 50;

/// The widest gap in the walls counted as closed by default, mm: a wide
/// single door (0.8–1.0 m leaves) with its frame, or a narrow entrance.
pub const DEFAULT_DOOR_MM: u32 = 1200;

/// The widest `--door-mm` taken, mm: a loading bay's door; wider gaps are
/// open sides, for a `free` polygon to close.
pub const MAX_DOOR_MM: u32 = 10_000;

/// Most lattice points; the step doubles until the map fits.
pub const MAX_LATTICE: usize = 1 << 24;

/// Lattice buckets of the walls' index: this many steps a side.
const BUCKET: usize = 16;

const UNSEEN: u8 = 0;
const OUTSIDE: u8 = 1;
const ON_WALL: u8 = 2;
const IN_SOLID: u8 = 3;
const INSIDE: u8 = 4;

/// A polygon with holes (mm), as a `free` feature gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct Area {
    pub outer: Vec<Point>,
    pub holes: Vec<Vec<Point>>,
}

impl Area {
    /// Whether `(x, y)` (mm) is inside: inside the outer ring and in no hole
    /// (even-odd over all rings; on a ring, either).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let mut odd = false;
        for r in std::iter::once(&self.outer).chain(&self.holes) {
            odd ^= ring_crossings(r, |p| (f64::from(p.x), f64::from(p.y)), (x, y));
        }
        odd
    }
}

/// Whether a ray from `q` towards +x crosses the closed ring `r` an odd
/// number of times (half-open in y, so a vertex on the ray counts once).
fn ring_crossings<T: Copy + PartialOrd + std::ops::Sub<Output = T> + std::ops::Mul<Output = T>>(
    r: &[Point],
    at: impl Fn(Point) -> (T, T),
    q: (T, T),
) -> bool {
    let mut odd = false;
    for k in 0..r.len() {
        let (a, b) = (at(r[k]), at(r[(k + 1) % r.len()]));
        if (a.1 > q.1) != (b.1 > q.1) {
            // q is left of the edge's crossing with y = q.y.
            let lhs = (q.0 - a.0) * (b.1 - a.1);
            let rhs = (q.1 - a.1) * (b.0 - a.0);
            if (b.1 > a.1 && lhs < rhs) || (b.1 < a.1 && lhs > rhs) {
                odd = !odd;
            }
        }
    }
    odd
}

/// Where a GeoJSON map's free space is.
#[derive(Debug)]
pub enum FreeSpace {
    /// The map's `free` polygons.
    Given(Vec<Area>),
    /// The region the walls enclose.
    Enclosed(Enclosure),
    /// Nothing enclosed, nothing given: the obstacles' bounding box.
    BoundingBox,
}

impl FreeSpace {
    /// The free space of a map of `shapes` with the `free` polygons `free`,
    /// gaps in the walls up to `door_mm` wide counted as closed.
    pub fn of(shapes: &[Shape], free: &[Area], door_mm: u32) -> FreeSpace {
        if !free.is_empty() {
            return FreeSpace::Given(free.to_vec());
        }
        match Enclosure::new(shapes, door_mm) {
            Some(e) if e.inside > 0 => FreeSpace::Enclosed(e),
            _ => FreeSpace::BoundingBox,
        }
    }

    /// Whether the point (mm) may be free (the field adds the clearance and
    /// its own box).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        match self {
            FreeSpace::Given(a) => a.iter().any(|a| a.contains(x, y)),
            FreeSpace::Enclosed(e) => e.contains(x, y),
            FreeSpace::BoundingBox => true,
        }
    }

    /// The warning a map without an enclosed region gets.
    pub const OPEN: &'static str = "the walls enclose no region: free space (where particles are drawn) is the \
        obstacles' bounding box, outside the building too; close the outer walls (gaps up to --door-mm count as \
        closed), give a larger --door-mm, or give a `free` polygon (a Feature with \"kind\": \"free\")";

    /// Where it came from, in words, for a message.
    pub fn describe(&self) -> String {
        match self {
            FreeSpace::Given(_) => "the map's `free` polygons".into(),
            FreeSpace::Enclosed(e) => format!(
                "what the walls enclose ({:.2} m² of their {:.2} m² box, gaps up to {} mm closed)",
                e.enclosed_m2(),
                e.walls_box_m2(),
                e.door_mm()
            ),
            FreeSpace::BoundingBox => "the obstacles' bounding box".into(),
        }
    }

    /// The enclosed region is under this share of the walls' bounding box:
    /// the import warns (a doorway or entrance wider than a door, most
    /// likely).
    pub const SMALL_SHARE: f64 = 0.25;

    /// For the import's summary: `{"from": …}`, what it covers, and a
    /// `warning` when the free space is likely not what the drawing means.
    pub fn summary(&self) -> serde_json::Value {
        match self {
            FreeSpace::Given(a) => serde_json::json!({"from": "free polygons", "polygons": a.len()}),
            FreeSpace::Enclosed(e) => {
                let (area, walls) = (e.enclosed_m2(), e.walls_box_m2());
                let mut v = serde_json::json!({
                    "from": "enclosed by the walls",
                    "enclosed_m2": (area * 100.0).round() / 100.0,
                    "walls_box_m2": (walls * 100.0).round() / 100.0,
                    "door_mm": e.door_mm(),
                    "lattice_mm": e.step_mm(),
                });
                if area < Self::SMALL_SHARE * walls {
                    v["warning"] = Self::small(area, walls, e.door_mm()).into();
                }
                v
            }
            FreeSpace::BoundingBox => serde_json::json!({"from": "bounding box", "warning": Self::OPEN}),
        }
    }

    /// The warning an enclosed region under [`Self::SMALL_SHARE`] of the
    /// walls' box gets: the figures and the fixes.
    pub fn small(area_m2: f64, walls_m2: f64, door_mm: u32) -> String {
        format!(
            "the walls enclose only {area_m2:.2} m², {:.1} % of their bounding box ({walls_m2:.2} m²), with gaps up to \
             {door_mm} mm closed: free space (where particles are drawn) is that region only; if the building's \
             entrance or a doorway is wider, give a larger --door-mm, or give a `free` polygon (a Feature with \
             \"kind\": \"free\")",
            100.0 * area_m2 / walls_m2.max(f64::MIN_POSITIVE)
        )
    }
}

/// The region a map's walls and outlines enclose, on a lattice.
#[derive(Debug)]
pub struct Enclosure {
    x0: i64,
    y0: i64,
    step: i64,
    nx: usize,
    ny: usize,
    label: Vec<u8>,
    segs: Vec<[i64; 4]>,
    bnx: usize,
    buckets: Vec<Vec<u32>>,
    /// Lattice points enclosed and outside every obstacle.
    inside: usize,
    /// Gaps up to this wide counted as closed, mm.
    door_mm: u32,
    /// The walls' and outlines' bounding box, mm: (min x, min y, max x, max y).
    walls_box: [i64; 4],
}

/// Whether the closed segments `ab` and `cd` share a point (either may be
/// a point): the core's exact predicate, on lattice points (mm, within the
/// map's `i32` extent and its margin).
fn touch(a: (i64, i64), b: (i64, i64), c: (i64, i64), d: (i64, i64)) -> bool {
    let p = |q: (i64, i64)| Point::new(q.0 as i32, q.1 as i32);
    echoloc::geometry::segments_intersect(p(a), p(b), p(c), p(d))
}

/// Whether `p` is within `r` of the closed segment `s` (a point if its
/// ends meet), exactly: squared distances in `i128`.
fn within(p: (i64, i64), s: &[i64; 4], r: i64) -> bool {
    let (ax, ay, bx, by) = (i128::from(s[0]), i128::from(s[1]), i128::from(s[2]), i128::from(s[3]));
    let (px, py, r2) = (i128::from(p.0), i128::from(p.1), i128::from(r) * i128::from(r));
    let (dx, dy) = (bx - ax, by - ay);
    let len2 = dx * dx + dy * dy;
    let t = (px - ax) * dx + (py - ay) * dy;
    if t <= 0 || len2 == 0 {
        (px - ax).pow(2) + (py - ay).pow(2) <= r2
    } else if t >= len2 {
        (px - bx).pow(2) + (py - by).pow(2) <= r2
    } else {
        // The distance to the line: |cross| / |ab|.
        let cross = (px - ax) * dy - (py - ay) * dx;
        cross * cross <= r2 * len2
    }
}

impl Enclosure {
    /// The lattice, flooded, with gaps up to `door_mm` closed; `None` for a
    /// map with no segment.
    pub fn new(shapes: &[Shape], door_mm: u32) -> Option<Enclosure> {
        let mut segs: Vec<[i64; 4]> = Vec::new();
        let mut push_ring = |r: &[Point], closed: bool| {
            let n = r.len();
            let m = if closed { n } else { n.saturating_sub(1) };
            for k in 0..m {
                let (a, b) = (r[k], r[(k + 1) % n]);
                if a != b {
                    segs.push([a.x.into(), a.y.into(), b.x.into(), b.y.into()]);
                }
            }
        };
        for s in shapes {
            match s {
                Shape::Solid { outer, holes } => {
                    push_ring(outer, true);
                    holes.iter().for_each(|h| push_ring(h, true));
                }
                Shape::Wall(w) => push_ring(w, false),
            }
        }
        if segs.is_empty() {
            return None;
        }
        let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
        for s in &segs {
            lo = (lo.0.min(s[0]).min(s[2]), lo.1.min(s[1]).min(s[3]));
            hi = (hi.0.max(s[0]).max(s[2]), hi.1.max(s[1]).max(s[3]));
        }
        // Half a door, and two steps beyond it of margin: the border is
        // deep and outside everything.
        let r = i64::from(door_mm / 2);
        let mut step = STEP_MM;
        let (x0, y0, nx, ny) = loop {
            let m = r.div_euclid(step) + 3;
            let x0 = lo.0.div_euclid(step) * step - m * step;
            let y0 = lo.1.div_euclid(step) * step - m * step;
            let nx = ((hi.0 - x0).div_euclid(step) + m + 1) as usize;
            let ny = ((hi.1 - y0).div_euclid(step) + m + 1) as usize;
            if nx.saturating_mul(ny) <= MAX_LATTICE {
                break (x0, y0, nx, ny);
            }
            step *= 2;
        };
        let (bnx, bny) = ((nx - 1) / BUCKET + 1, (ny - 1) / BUCKET + 1);
        let mut buckets = vec![Vec::new(); bnx * bny];
        let cell = |v: i64, o: i64| (v - o).div_euclid(step) as usize / BUCKET;
        for (k, s) in segs.iter().enumerate() {
            let (bx0, bx1) = (cell(s[0].min(s[2]), x0), cell(s[0].max(s[2]), x0));
            let (by0, by1) = (cell(s[1].min(s[3]), y0), cell(s[1].max(s[3]), y0));
            for by in by0..=by1.min(bny - 1) {
                for bx in bx0..=bx1.min(bnx - 1) {
                    buckets[by * bnx + bx].push(k as u32);
                }
            }
        }
        let mut e = Enclosure {
            x0,
            y0,
            step,
            nx,
            ny,
            label: vec![UNSEEN; nx * ny],
            segs,
            bnx,
            buckets,
            inside: 0,
            door_mm,
            walls_box: [lo.0, lo.1, hi.0, hi.1],
        };
        // Half a step more: a path between lattice points crosses a gap's
        // line within half a step of one of them, so no gap up to a door
        // wide lets a path of deep points through, wherever it lies on the
        // lattice.
        let near = e.near(if r > 0 { r + step / 2 } else { 0 });
        e.flood(shapes, &near);
        Some(e)
    }

    /// The lattice points within `r` of a wall (`r = 0`: on one).
    fn near(&self, r: i64) -> Vec<bool> {
        let mut near = vec![false; self.nx * self.ny];
        let idx = |v: i64, o: i64, n: usize| ((v - o).div_euclid(self.step).clamp(0, n as i64 - 1)) as usize;
        for s in &self.segs {
            let (i0, i1) = (idx(s[0].min(s[2]) - r, self.x0, self.nx), idx(s[0].max(s[2]) + r, self.x0, self.nx));
            let (j0, j1) = (idx(s[1].min(s[3]) - r, self.y0, self.ny), idx(s[1].max(s[3]) + r, self.y0, self.ny));
            for j in j0..=(j1 + 1).min(self.ny - 1) {
                for i in i0..=(i1 + 1).min(self.nx - 1) {
                    let n = j * self.nx + i;
                    if !near[n] && within(self.at(i, j), s, r) {
                        near[n] = true;
                    }
                }
            }
        }
        near
    }

    fn at(&self, i: usize, j: usize) -> (i64, i64) {
        (self.x0 + i as i64 * self.step, self.y0 + j as i64 * self.step)
    }

    /// Whether the segment `a`–`b`, within the lattice cells `i..=i1` ×
    /// `j..=j1` (at most one cell apart), touches a wall.
    fn blocked(&self, a: (i64, i64), b: (i64, i64), (i, i1): (usize, usize), (j, j1): (usize, usize)) -> bool {
        let bny = self.buckets.len() / self.bnx;
        for by in j / BUCKET..=(j1 / BUCKET).min(bny - 1) {
            for bx in i / BUCKET..=(i1 / BUCKET).min(self.bnx - 1) {
                for &k in &self.buckets[by * self.bnx + bx] {
                    let s = self.segs[k as usize];
                    if touch(a, b, (s[0], s[1]), (s[2], s[3])) {
                        return true;
                    }
                }
            }
        }
        false
    }

    fn neighbours(&self, n: usize) -> impl Iterator<Item = usize> + '_ {
        let (i, j) = (n % self.nx, n / self.nx);
        [(i > 0).then(|| n - 1), (i + 1 < self.nx).then(|| n + 1), (j > 0).then(|| n - self.nx)]
            .into_iter()
            .chain([(j + 1 < self.ny).then(|| n + self.nx)])
            .flatten()
    }

    fn edge_blocked(&self, n: usize, m: usize) -> bool {
        let (i, j, i2, j2) = (n % self.nx, n / self.nx, m % self.nx, m / self.nx);
        self.blocked(self.at(i, j), self.at(i2, j2), (i.min(i2), i.max(i2)), (j.min(j2), j.max(j2)))
    }

    /// Labels every lattice point: outside, on a wall, or enclosed (inside
    /// an obstacle, or inside the building); `near` marks the points within
    /// half a door of a wall (the module's steps 1–5).
    fn flood(&mut self, shapes: &[Shape], near: &[bool]) {
        let (nx, ny) = (self.nx, self.ny);
        // 2: the outside's deep points, from the border (deep by its margin).
        let mut queue = VecDeque::new();
        for n in 0..nx * ny {
            let (i, j) = (n % nx, n / nx);
            if i == 0 || j == 0 || i + 1 == nx || j + 1 == ny {
                self.label[n] = OUTSIDE;
                queue.push_back(n);
            }
        }
        self.spread(&mut queue, OUTSIDE, Some(near));
        // 3: every other component of deep points, labelled as its first
        // point is.
        let solids = solids(shapes);
        for n in 0..nx * ny {
            if self.label[n] == UNSEEN && !near[n] {
                let l = self.face(&solids, n);
                self.label[n] = l;
                queue.push_back(n);
                self.spread(&mut queue, l, Some(near));
            }
        }
        // 4: the near points to the nearest core, all floods at once (the
        // cores are every point labelled so far).
        queue.extend((0..nx * ny).filter(|&n| self.label[n] != UNSEEN));
        self.spread(&mut queue, UNSEEN, None);
        for n in 0..nx * ny {
            if self.label[n] == UNSEEN {
                let p = self.at(n % nx, n / nx);
                if self.blocked(p, p, (n % nx, n % nx), (n / nx, n / nx)) {
                    self.label[n] = ON_WALL;
                }
            }
        }
        // 5: what is walled in all round, each component as one of its points.
        for n in 0..nx * ny {
            if self.label[n] == UNSEEN {
                let l = self.face(&solids, n);
                self.label[n] = l;
                queue.push_back(n);
                self.spread(&mut queue, l, None);
            }
        }
        self.inside = self.label.iter().filter(|&&l| l == INSIDE).count();
    }

    /// Inside an obstacle or not, at lattice point `n` (exact even-odd test).
    fn face(&self, solids: &[Vec<&[Point]>], n: usize) -> u8 {
        let (px, py) = self.at(n % self.nx, n / self.nx);
        let p = (i128::from(px), i128::from(py));
        let in_solid = solids.iter().any(|rings| {
            rings.iter().fold(false, |odd, r| odd ^ ring_crossings(r, |q| (i128::from(q.x), i128::from(q.y)), p))
        });
        if in_solid {
            IN_SOLID
        } else {
            INSIDE
        }
    }

    /// Floods from the queue over unseen points along clear edges (and,
    /// with `deep`, only onto points it does not mark near), each point
    /// taking `l`, or with `l = UNSEEN` the label of the point it came from.
    fn spread(&mut self, queue: &mut VecDeque<usize>, l: u8, deep: Option<&[bool]>) {
        while let Some(n) = queue.pop_front() {
            let here = if l == UNSEEN { self.label[n] } else { l };
            let next: Vec<usize> = self
                .neighbours(n)
                .filter(|&m| self.label[m] == UNSEEN && deep.is_none_or(|d| !d[m]) && !self.edge_blocked(n, m))
                .collect();
            for m in next {
                self.label[m] = here;
                queue.push_back(m);
            }
        }
    }

    /// Whether `(x, y)` (mm, rounded) is enclosed and outside every
    /// obstacle: it sees a lattice corner of its cell labelled so, and none
    /// reached from outside, without touching a wall.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let p = (x.round() as i64, y.round() as i64);
        let (u, v) = ((p.0 - self.x0).div_euclid(self.step), (p.1 - self.y0).div_euclid(self.step));
        if u < 0 || v < 0 || u as usize >= self.nx || v as usize >= self.ny {
            return false;
        }
        let (i, j) = ((u as usize).min(self.nx - 2), (v as usize).min(self.ny - 2));
        let mut inside = false;
        for (ci, cj) in [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)] {
            let l = self.label[cj * self.nx + ci];
            if l == ON_WALL || self.blocked(p, self.at(ci, cj), (i, i + 1), (j, j + 1)) {
                continue;
            }
            match l {
                OUTSIDE => return false,
                INSIDE => inside = true,
                _ => {}
            }
        }
        inside
    }

    /// Lattice points enclosed and outside every obstacle.
    pub fn inside_points(&self) -> usize {
        self.inside
    }

    /// The lattice step, mm.
    pub fn step_mm(&self) -> i64 {
        self.step
    }

    /// The enclosed area, m² (a little under the region's: lattice points).
    pub fn enclosed_m2(&self) -> f64 {
        self.inside as f64 * (self.step * self.step) as f64 / 1e6
    }

    /// The walls' bounding box's area, m².
    pub fn walls_box_m2(&self) -> f64 {
        let b = self.walls_box;
        (b[2] - b[0]) as f64 * (b[3] - b[1]) as f64 / 1e6
    }

    /// Gaps up to this wide counted as closed, mm.
    pub fn door_mm(&self) -> u32 {
        self.door_mm
    }
}

/// Each solid's rings (outer and holes), for the even-odd test.
fn solids(shapes: &[Shape]) -> Vec<Vec<&[Point]>> {
    shapes
        .iter()
        .filter_map(|s| match s {
            Shape::Solid { outer, holes } => {
                Some(std::iter::once(outer.as_slice()).chain(holes.iter().map(Vec::as_slice)).collect())
            }
            Shape::Wall(_) => None,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::{compile_source, geojson, AlignedBytes, ImportOptions, Source};
    use echoloc::map::MapView;

    /// A 4 m × 4 m building drawn as one closed wall, an interior wall from
    /// (2, 0) to (2, 3) (a 1 m door at the top), and a lone wall 2 m below
    /// it, outside, that stretches the obstacles' box down to y = -2 m.
    const BUILDING: &str = r#"{"type":"FeatureCollection","features":[
        {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[0,0],[4,0],[4,4],[0,4],[0,0]]}},
        {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[2,0],[2,3]]}},
        {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[0,-2],[4,-2]]}}"#;

    fn map(extra: &str) -> String {
        format!("{BUILDING}{extra}]}}")
    }

    fn space(text: &str) -> FreeSpace {
        space_with(text, DEFAULT_DOOR_MM)
    }

    fn space_with(text: &str, door_mm: u32) -> FreeSpace {
        let m = geojson::parse_map(text).unwrap();
        FreeSpace::of(&m.shapes, &m.free, door_mm)
    }

    /// (free nodes of the default field, the summary's `free_space`).
    fn free_nodes(text: &str) -> (u32, serde_json::Value) {
        let m = geojson::parse_map(text).unwrap();
        let src = Source { shapes: m.shapes, grid: None, free_polygons: Some(m.free), extra: Default::default() };
        let (blob, summary) = compile_source(&src, 100, 1000, &ImportOptions::default()).unwrap();
        let a = AlignedBytes::new(&blob);
        let v = MapView::new(a.bytes()).unwrap();
        (v.field().free_nodes(), summary.extra.get("free_space").cloned().unwrap_or_default())
    }

    #[test]
    fn the_building_is_what_the_walls_enclose() {
        let s = space(&map(""));
        let FreeSpace::Enclosed(e) = &s else { panic!("{s:?}") };
        assert_eq!(e.step_mm(), 50);
        // Against the building drawn by hand: inside the square, not on a
        // wall. Points on a 7 mm × 11 mm raster (not the lattice's), from
        // 1 m outside the square to 1 m beyond it.
        let mut checked = 0;
        for i in 0..=857 {
            for j in 0..=545 {
                let (x, y) = (-1000 + 7 * i, -1000 + 11 * j);
                let on_wall = ((x == 0 || x == 4000) && (0..=4000).contains(&y))
                    || ((y == 0 || y == 4000 || y == -2000) && (0..=4000).contains(&x))
                    || (x == 2000 && (0..=3000).contains(&y));
                let inside = x > 0 && x < 4000 && y > 0 && y < 4000 && !on_wall;
                assert_eq!(s.contains(f64::from(x), f64::from(y)), inside, "({x}, {y})");
                checked += 1;
            }
        }
        assert_eq!(checked, 858 * 546);
        // Enclosed lattice points: 79 × 79 inside the square, less the 60
        // on the interior wall (y = 50 … 3000).
        assert_eq!(e.inside_points(), 79 * 79 - 60);
    }

    #[test]
    fn the_field_draws_free_nodes_inside_the_building_only() {
        // Nodes every 250 mm, 200 mm clear of every wall. Inside: x and y in
        // 250 … 3750 (15 × 15), less x = 2000 for y = 250 … 3000 (12 nodes
        // on the interior wall): 213. The old free space (the box, down to
        // y = -2 m) had also the 7 rows y = -1750 … -250 for x = 0 … 4000
        // (17 nodes, x = 0 and 4000 clear of the wall ends by 250 mm): 119.
        let (n, fs) = free_nodes(&map(""));
        assert_eq!(n, 15 * 15 - 12, "{fs}");
        assert_eq!(fs["from"], "enclosed by the walls");
        let m = geojson::parse_map(&map("")).unwrap();
        let (blob, _) = crate::map::build_map_with(&m.shapes, 100, 1000, Some((&Default::default(), None))).unwrap();
        let a = AlignedBytes::new(&blob);
        assert_eq!(MapView::new(a.bytes()).unwrap().field().free_nodes(), 15 * 15 - 12 + 17 * 7);
    }

    #[test]
    fn a_free_polygon_overrides_the_walls() {
        // The left room and the strip below it, outside the building: x in
        // 0 … 1750 (8 columns; x = 0 is clear only below the building) ...
        let free = r#",{"type":"Feature","properties":{"kind":"free"},"geometry":{"type":"Polygon",
            "coordinates":[[[-0.1,-2.1],[1.9,-2.1],[1.9,4.1],[-0.1,4.1],[-0.1,-2.1]]]}}"#;
        let (n, fs) = free_nodes(&map(free));
        // ... inside: 7 × 15; below: 8 × 7 (y = -1750 … -250).
        assert_eq!(n, 7 * 15 + 8 * 7, "{fs}");
        assert_eq!(fs, serde_json::json!({"from": "free polygons", "polygons": 1}));
        // It is no obstacle: the same pieces as without it.
        assert_eq!(geojson::parse_map(&map(free)).unwrap().shapes, geojson::parse(&map("")).unwrap());
        let e = geojson::parse_map(&map(
            r#",{"type":"Feature","properties":{"kind":"free"},"geometry":{"type":"LineString","coordinates":[[0,0],[1,1]]}}"#,
        ))
        .unwrap_err();
        assert_eq!(e, "features[3]: a \"free\" feature must be a Polygon or MultiPolygon, not \"LineString\"");
    }

    #[test]
    fn a_map_with_no_enclosed_region_says_so() {
        // An open box (a 2 m gap in its top wall, wider than a door) and a
        // lone square obstacle: nothing enclosed but the obstacle's inside.
        // The box is the free space, as before, and the summary warns.
        let open = r#"{"type":"FeatureCollection","features":[
            {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[3.4,4],[4,4],[4,0],[0,0],[0,4],[1.4,4]]}},
            {"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[[1,1],[2,1],[2,2],[1,2],[1,1]]]}}]}"#;
        let s = space(open);
        assert!(matches!(s, FreeSpace::BoundingBox), "{s:?}");
        assert!(s.contains(-5000.0, -5000.0));
        let (_, fs) = free_nodes(open);
        assert_eq!(fs["from"], "bounding box");
        let w = fs["warning"].as_str().unwrap();
        assert!(w.contains("give a `free` polygon") && w.contains("--door-mm"), "{fs}");
        // Gaps of 20 mm (a drawing's sloppy corner) and 0.3 m close, even
        // with no door (`door_mm = 0`: the walls alone) for the first.
        for (end, door_less) in [("[3.38,4]", true), ("[3.1,4]", false)] {
            let narrow = open.replace("[1.4,4]", end);
            let FreeSpace::Enclosed(e) = space(&narrow) else { panic!("{end}") };
            assert!(e.contains(3000.0, 3000.0) && !e.contains(3000.0, 5000.0) && !e.contains(1500.0, 1500.0));
            assert_eq!(matches!(space_with(&narrow, 0), FreeSpace::Enclosed(_)), door_less, "{end}");
        }
    }

    /// A 4 m box whose top wall (at `y` m) has a gap `w` m wide from `x` m;
    /// whether it is enclosed with doors up to `door_mm`.
    fn gap_closes(w: f64, x: f64, y: f64, door_mm: u32) -> bool {
        let text = format!(
            r#"{{"type":"FeatureCollection","features":[
            {{"type":"Feature","properties":{{}},"geometry":{{"type":"LineString","coordinates":[[{},{y}],[4,{y}],[4,0],[0,0],[0,{y}],[{x},{y}]]}}}}]}}"#,
            x + w
        );
        match space_with(&text, door_mm) {
            FreeSpace::Enclosed(e) => {
                // The whole box, the gap's middle a lattice step in.
                let inside = e.contains(2000.0, 2000.0) && e.contains((x + w / 2.0) * 1e3, y * 1e3 - 60.0);
                assert!(inside && !e.contains(2000.0, y * 1e3 + 700.0), "{w} {x} {y}");
                true
            }
            FreeSpace::BoundingBox => false,
            s => panic!("{s:?}"),
        }
    }

    #[test]
    fn gaps_up_to_a_door_close_and_wider_ones_do_not() {
        // Gaps at offsets on and off the 50 mm lattice, in a wall on and
        // off it: up to the door's width closed, four lattice steps (0.2 m)
        // beyond it open (within that it may close: module docs).
        for (x, y) in [(1.0, 4.0), (1.013, 4.021), (1.737, 3.988), (0.5, 4.049)] {
            for w in [0.3, 0.8, 0.9, 1.0, 1.1, 1.2] {
                assert!(gap_closes(w, x, y, DEFAULT_DOOR_MM), "{w} m at ({x}, {y})");
            }
            for w in [1.4, 1.5, 2.0, 3.0] {
                assert!(!gap_closes(w, x, y, DEFAULT_DOOR_MM), "{w} m at ({x}, {y})");
            }
            assert!(gap_closes(1.5, x, y, 1500) && !gap_closes(1.7, x, y, 1500), "({x}, {y})");
            // No door: only the walls close.
            assert!(!gap_closes(0.3, x, y, 0), "({x}, {y})");
        }
    }

    #[test]
    fn no_door_is_the_walls_alone() {
        // Without gaps, doors change nothing: the same lattice labels.
        for text in [
            map(""),
            map(
                r#",{"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[[1,1],[1.5,1],[1.5,1.5],[1,1.5],[1,1]]]}}"#,
            ),
        ] {
            let m = geojson::parse_map(&text).unwrap();
            let (a, b) = (Enclosure::new(&m.shapes, 0).unwrap(), Enclosure::new(&m.shapes, DEFAULT_DOOR_MM).unwrap());
            assert_eq!(a.inside_points(), b.inside_points());
            for i in 0..=200 {
                for j in 0..=160 {
                    let (x, y) = (f64::from(-500 + 27 * i), f64::from(-2500 + 43 * j));
                    assert_eq!(a.contains(x, y), b.contains(x, y), "({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn a_small_enclosure_warns_and_an_empty_field_is_refused() {
        // A 10 m × 6 m hall whose 3 m gate is open, with a closed 2 m × 2 m
        // store room inside: only the store is enclosed (4 m² of 60).
        let hall = r#"{"type":"FeatureCollection","features":[
            {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[3.5,0],[0,0],[0,6],[10,6],[10,0],[6.5,0]]}},
            {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[8,4],[8,6]]}},
            {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[8,4],[10,4]]}}]}"#;
        let (n, fs) = free_nodes(hall);
        assert_eq!(fs["from"], "enclosed by the walls", "{fs}");
        assert_eq!(fs["walls_box_m2"], 60.0);
        let area = fs["enclosed_m2"].as_f64().unwrap();
        assert!(area > 3.6 && area < 4.0, "{fs}");
        let w = fs["warning"].as_str().unwrap();
        assert!(w.contains(&format!("{area:.2} m²")) && w.contains("60.00 m²") && w.contains("1200 mm"), "{w}");
        assert!(w.contains("larger --door-mm") && w.contains("`free` polygon"), "{w}");
        // The store's nodes, 200 mm clear: x, y in 8.25 … 9.75 (7 × 7).
        assert_eq!(n, 7 * 7);
        // With a 3 m door the hall is inside: no warning.
        let m = geojson::parse_map(hall).unwrap();
        let src = Source { shapes: m.shapes, grid: None, free_polygons: Some(m.free), extra: Default::default() };
        let opt = ImportOptions { door_mm: 3000, ..Default::default() };
        let (_, summary) = compile_source(&src, 100, 1000, &opt).unwrap();
        assert!(summary.extra["free_space"].get("warning").is_none(), "{:?}", summary.extra);
        // A store 0.3 m across holds no node 200 mm clear: refused, saying so.
        let tiny =
            hall.replace("[[8,4],[8,6]]", "[[9.7,5.7],[9.7,6]]").replace("[[8,4],[10,4]]", "[[9.7,5.7],[10,5.7]]");
        let m = geojson::parse_map(&tiny).unwrap();
        let src = Source { shapes: m.shapes, grid: None, free_polygons: Some(m.free), extra: Default::default() };
        let e = compile_source(&src, 100, 1000, &ImportOptions::default()).unwrap_err();
        assert!(e.starts_with("the localization field has no free node: "), "{e}");
        assert!(
            e.contains("gaps up to 1200 mm closed") && e.contains("200 mm clear") && e.contains("--door-mm"),
            "{e}"
        );
        // Without a field there is nothing to refuse.
        let opt = ImportOptions { field: None, ..Default::default() };
        assert!(compile_source(&src, 100, 1000, &opt).is_ok());
    }

    #[test]
    fn a_room_drawn_as_the_hole_of_a_solid_is_enclosed() {
        // A 1 m thick frame around a 3 m × 3 m room; the solid is no room.
        let frame =
            r#"{"type":"Polygon","coordinates":[[[0,0],[5,0],[5,5],[0,5],[0,0]],[[1,1],[4,1],[4,4],[1,4],[1,1]]]}"#;
        let FreeSpace::Enclosed(e) = space(frame) else { panic!() };
        assert!(e.contains(2500.0, 2500.0) && e.contains(1010.0, 3990.0));
        assert!(!e.contains(500.0, 2500.0) && !e.contains(-500.0, 2500.0) && !e.contains(1000.0, 2500.0));
        // 59 × 59 lattice points strictly inside the hole.
        assert_eq!(e.inside_points(), 59 * 59);
    }
}
