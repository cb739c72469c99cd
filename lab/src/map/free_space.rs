//! Free space of a GeoJSON map: where the localization field's free nodes,
//! and so the particles, may be (`docs/maps.md`, "Free space").
//!
//! A ROS occupancy grid says itself where the robot can be (its known-free
//! cells). A GeoJSON map is only obstacles, so its free space is, in order:
//!
//! 1. **given**: the union of the map's `free` polygons (Features with
//!    `"kind": "free"`, Polygon or MultiPolygon, holes allowed), when it has any;
//! 2. **enclosed**: else the region the walls and outlines enclose: the points
//!    from which every path to far away crosses a wall or an obstacle's
//!    outline (the bounded faces of the map's drawing), less the obstacles'
//!    insides. Walls need not meet end to end: crossings, T-junctions and
//!    a room drawn as the hole of a solid all enclose;
//! 3. **bounding box**: else (a map of obstacles in the open, nothing
//!    enclosed) the old rule, the obstacles' bounding box, with a warning
//!    in the import's summary naming the fix.
//!
//! In every case the field then keeps its clearance from every obstacle.
//!
//! The enclosed region is found on a lattice of [`STEP_MM`] (coarser on maps
//! of more than [`MAX_LATTICE`] points): a flood from the lattice's border
//! along lattice edges that touch no wall (exact integer tests) reaches
//! everything outside; what it cannot reach is enclosed. A point between
//! lattice points takes the label of a lattice corner of its cell that it
//! sees without touching a wall. So a gap in the outer walls narrower than
//! a few lattice steps (0.15 m at 50 mm, far narrower than a robot) may
//! count as closed; a wider one never does, and such a map is open.

use std::collections::VecDeque;

use echoloc::geometry::Point;

use super::Shape;

/// The lattice step, mm (before coarsening).
pub const STEP_MM: i64 = 50;

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
    /// The free space of a map of `shapes` with the `free` polygons `free`.
    pub fn of(shapes: &[Shape], free: &[Area]) -> FreeSpace {
        if !free.is_empty() {
            return FreeSpace::Given(free.to_vec());
        }
        match Enclosure::new(shapes) {
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
        obstacles' bounding box, outside the building too; close the outer walls, or give a `free` polygon \
        (a Feature with \"kind\": \"free\")";

    /// For the import's summary: `{"from": …}` and what it covers.
    pub fn summary(&self) -> serde_json::Value {
        match self {
            FreeSpace::Given(a) => serde_json::json!({"from": "free polygons", "polygons": a.len()}),
            FreeSpace::Enclosed(e) => serde_json::json!({
                "from": "enclosed by the walls",
                "enclosed_m2": (e.inside as f64 * (e.step * e.step) as f64 / 1e4).round() / 100.0,
                "lattice_mm": e.step,
            }),
            FreeSpace::BoundingBox => serde_json::json!({"from": "bounding box", "warning": Self::OPEN}),
        }
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
}

/// Whether the closed segments `ab` and `cd` share a point (either may be
/// a point): the core's exact predicate, on lattice points (mm, within the
/// map's `i32` extent and its margin).
fn touch(a: (i64, i64), b: (i64, i64), c: (i64, i64), d: (i64, i64)) -> bool {
    let p = |q: (i64, i64)| Point::new(q.0 as i32, q.1 as i32);
    echoloc::geometry::segments_intersect(p(a), p(b), p(c), p(d))
}

impl Enclosure {
    /// The lattice, flooded; `None` for a map with no segment.
    pub fn new(shapes: &[Shape]) -> Option<Enclosure> {
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
        // Two steps of margin: the border is outside everything.
        let mut step = STEP_MM;
        let (x0, y0, nx, ny) = loop {
            let x0 = lo.0.div_euclid(step) * step - 2 * step;
            let y0 = lo.1.div_euclid(step) * step - 2 * step;
            let nx = ((hi.0 - x0).div_euclid(step) + 3) as usize;
            let ny = ((hi.1 - y0).div_euclid(step) + 3) as usize;
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
        let mut e = Enclosure { x0, y0, step, nx, ny, label: vec![UNSEEN; nx * ny], segs, bnx, buckets, inside: 0 };
        e.flood(shapes);
        Some(e)
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

    /// Labels every lattice point: reached from the border (outside), on a
    /// wall, or enclosed (inside an obstacle, or inside the building).
    fn flood(&mut self, shapes: &[Shape]) {
        let (nx, ny) = (self.nx, self.ny);
        let mut queue = VecDeque::new();
        for n in 0..nx * ny {
            let (i, j) = (n % nx, n / nx);
            if i == 0 || j == 0 || i + 1 == nx || j + 1 == ny {
                self.label[n] = OUTSIDE;
                queue.push_back(n);
            }
        }
        self.spread(&mut queue, OUTSIDE);
        for n in 0..nx * ny {
            if self.label[n] == UNSEEN {
                let p = self.at(n % nx, n / nx);
                if self.blocked(p, p, (n % nx, n % nx), (n / nx, n / nx)) {
                    self.label[n] = ON_WALL;
                }
            }
        }
        // Each enclosed component lies in one face of the drawing: inside
        // an obstacle or not, as any of its points is.
        let solids: Vec<Vec<&[Point]>> = shapes
            .iter()
            .filter_map(|s| match s {
                Shape::Solid { outer, holes } => {
                    Some(std::iter::once(outer.as_slice()).chain(holes.iter().map(Vec::as_slice)).collect())
                }
                Shape::Wall(_) => None,
            })
            .collect();
        for n in 0..nx * ny {
            if self.label[n] != UNSEEN {
                continue;
            }
            let (px, py) = self.at(n % nx, n / nx);
            let p = (i128::from(px), i128::from(py));
            let in_solid = solids.iter().any(|rings| {
                rings.iter().fold(false, |odd, r| odd ^ ring_crossings(r, |q| (i128::from(q.x), i128::from(q.y)), p))
            });
            let l = if in_solid { IN_SOLID } else { INSIDE };
            self.label[n] = l;
            queue.push_back(n);
            let spread = self.spread(&mut queue, l);
            if l == INSIDE {
                self.inside += 1 + spread;
            }
        }
    }

    /// Floods `l` from the queue over unseen points along clear edges;
    /// returns how many it labelled.
    fn spread(&mut self, queue: &mut VecDeque<usize>, l: u8) -> usize {
        let mut count = 0;
        while let Some(n) = queue.pop_front() {
            let next: Vec<usize> =
                self.neighbours(n).filter(|&m| self.label[m] == UNSEEN && !self.edge_blocked(n, m)).collect();
            for m in next {
                self.label[m] = l;
                queue.push_back(m);
                count += 1;
            }
        }
        count
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
        let m = geojson::parse_map(text).unwrap();
        FreeSpace::of(&m.shapes, &m.free)
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
        // An open box (the top wall 0.3 m short) and a lone square obstacle:
        // nothing enclosed but the obstacle's inside. The box is the free
        // space, as before, and the summary warns.
        let open = r#"{"type":"FeatureCollection","features":[
            {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[3.7,4],[4,4],[4,0],[0,0],[0,4],[3.4,4]]}},
            {"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[[1,1],[2,1],[2,2],[1,2],[1,1]]]}}]}"#;
        let s = space(open);
        assert!(matches!(s, FreeSpace::BoundingBox), "{s:?}");
        assert!(s.contains(-5000.0, -5000.0));
        let (_, fs) = free_nodes(open);
        assert_eq!(fs["from"], "bounding box");
        assert!(fs["warning"].as_str().unwrap().contains("give a `free` polygon"), "{fs}");
        // A 20 mm gap (a drawing's sloppy corner) closes: the box is enclosed.
        let sloppy = open.replace("[3.7,4]", "[3.42,4]");
        let FreeSpace::Enclosed(e) = space(&sloppy) else { panic!() };
        assert!(e.contains(3000.0, 3000.0) && !e.contains(3000.0, 5000.0) && !e.contains(1500.0, 1500.0));
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
