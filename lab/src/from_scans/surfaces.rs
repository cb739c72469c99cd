//! A laser scan as a sonar hears it: the returns joined into surfaces, each
//! point's normal over the sonar's footprint, the corners and edges, and
//! which space the laser saw to be free.
//!
//! - **Surfaces.** Neighbouring returns are one surface unless the step
//!   between them runs within [`SHADOW_DEG`] of the beam (an occlusion
//!   boundary: the laser jumped from a near object to what lies behind)
//!   or is longer than [`JOIN_MAX_M`].
//! - **Normals.** A line fitted to a point's surface neighbours within
//!   [`NORMAL_HALF_M`] each side: about the first Fresnel zone of a 49 kHz
//!   ping at 1–3 m (√(λr/2) ≈ 6–10 cm), the patch a sonar averages over,
//!   so the laser's centimetre of noise does not turn a wall into gravel.
//! - **Corners and edges.** Where the lines fitted on either side of a
//!   point turn by more than [`CORNER_TURN_DEG`], the free wedge between
//!   them (on the laser's side) says what it is, as the simulator's wedges
//!   do: 60–120° an inside corner, 200° or more an outside edge. A surface
//!   that ends nearer than what the next beam saw ends on an outside edge
//!   (the near side of a jump); one that ends behind an occluder does not
//!   end at all. A lone return (a chair leg, a post) is an edge.
//! - **Seen free.** A point is seen free by the scan if it lies in the
//!   laser's field and nearer than both beams either side of it returned
//!   (no return: free to [`NO_RETURN_FREE_M`]).
//!
//! *Model assumptions*, as optimistic as the laser: what the laser does
//! not see (glass, table tops under its plane, the beam's vertical spread)
//! the sonar does not hear.

use parry2d_f64::math::Vector;
use parry2d_f64::query::Ray;
use parry2d_f64::shape::{CompositeShapeRef, Polyline};

use crate::lidar::Scan;
use crate::simulate::world::wrap;

/// A point, m.
pub type P = (f64, f64);

/// A step that runs within this angle of its beam is an occlusion boundary, degrees.
pub const SHADOW_DEG: f64 = 10.0;
/// Longest step joined into one surface, m.
pub const JOIN_MAX_M: f64 = 0.5;
/// Half the patch a normal is fitted over, m.
pub const NORMAL_HALF_M: f64 = 0.08;
/// Half the span the lines either side of a corner are fitted over, m.
const CORNER_HALF_M: f64 = 0.15;
/// A turn sharper than this between the lines either side is a corner or an edge, degrees.
pub const CORNER_TURN_DEG: f64 = 35.0;
/// A beam with no return saw free space this far, m (beyond the sonar's reach).
pub const NO_RETURN_FREE_M: f64 = 8.0;
/// A point this much nearer than the laser's return still counts as seen free, m.
const SEEN_MARGIN_M: f64 = 0.03;

/// A point reflector: a corner or an edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointEcho {
    /// Where, m.
    pub at: P,
    /// Its free wedge, degrees (360 for a lone return; 270 for a surface's end).
    pub wedge_deg: f64,
}

/// One scan, ready for the sonar.
pub struct Surfaces {
    /// When the robot was there, s on the path's clock.
    pub time_s: f64,
    origin: P,
    heading: f64,
    angle_min: f64,
    angle_step: f64,
    ranges: Vec<f32>,
    verts: Vec<P>,
    normals: Vec<P>,
    segs: Vec<[u32; 2]>,
    poly: Option<Polyline>,
    /// The corners and edges.
    pub points: Vec<PointEcho>,
    /// Keys the scan's surfaces' fluctuation.
    pub key: u64,
}

/// A ray's hit on a scan's surfaces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Range, m.
    pub r: f64,
    /// Unit normal (the smoothed one).
    pub normal: P,
    /// The surface (its first vertex), for the fluctuation's key.
    pub surface: u32,
}

impl Surfaces {
    /// The surfaces of `scan` seen at `time_s`, keeping only the returns
    /// `keep` accepts (all of them, or those on the map's walls); `key`
    /// tells it apart from other scans.
    pub fn of_scan(scan: &Scan, time_s: f64, key: u64, keep: &dyn Fn(P) -> bool) -> Self {
        let origin = (scan.laser[0], scan.laser[1]);
        let n = scan.ranges.len();
        let pts: Vec<Option<P>> = (0..n).map(|i| scan.point(i).filter(|&p| keep(p))).collect();
        // Surfaces: runs of joined returns.
        let joined = |i: usize| match (pts[i], pts.get(i + 1).copied().flatten()) {
            (Some(a), Some(b)) => join(origin, a, b),
            _ => false,
        };
        let mut chains: Vec<Vec<usize>> = Vec::new();
        let mut cur: Vec<usize> = Vec::new();
        for (i, p) in pts.iter().enumerate() {
            if p.is_none() {
                continue;
            }
            cur.push(i);
            if !joined(i) {
                chains.push(std::mem::take(&mut cur));
            }
        }
        let mut verts = Vec::new();
        let mut normals = Vec::new();
        let mut segs = Vec::new();
        let mut points = Vec::new();
        let range_of = |i: isize| -> f64 {
            if i < 0 || i as usize >= n {
                return f64::INFINITY;
            }
            let r = f64::from(scan.ranges[i as usize]);
            if r.is_finite() {
                r
            } else {
                f64::INFINITY
            }
        };
        for c in &chains {
            let p: Vec<P> = c.iter().filter_map(|&i| pts[i]).collect();
            if p.len() == 1 {
                points.push(PointEcho { at: p[0], wedge_deg: 360.0 });
                continue;
            }
            let base = verts.len() as u32;
            let arc = arc_lengths(&p);
            for k in 0..p.len() {
                normals.push(fit_normal(&p, &arc, k, NORMAL_HALF_M, origin));
            }
            verts.extend_from_slice(&p);
            for k in 0..p.len() - 1 {
                segs.push([base + k as u32, base + k as u32 + 1]);
            }
            points.extend(corners(&p, &arc, origin));
            // Ends: an outside edge where the surface is the near side of a jump.
            for (end, beam, next) in
                [(p[0], c[0], c[0] as isize - 1), (p[p.len() - 1], c[c.len() - 1], c[c.len() - 1] as isize + 1)]
            {
                let r_here = f64::from(scan.ranges[beam]);
                if range_of(next) > r_here + 0.1 {
                    points.push(PointEcho { at: end, wedge_deg: 270.0 });
                }
            }
        }
        let poly = (!segs.is_empty())
            .then(|| Polyline::new(verts.iter().map(|v| Vector::new(v.0, v.1)).collect(), Some(segs.clone())));
        Self {
            time_s,
            origin,
            heading: scan.laser[2],
            angle_min: scan.angle_min,
            angle_step: scan.angle_step,
            ranges: scan.ranges.clone(),
            verts,
            normals,
            segs,
            poly,
            points,
            key,
        }
    }

    /// The first surface the ray from `o` along unit `d` meets within `max` m.
    pub fn cast(&self, o: P, d: P, max: f64) -> Option<SurfaceHit> {
        let poly = self.poly.as_ref()?;
        let ray = Ray::new(Vector::new(o.0, o.1), Vector::new(d.0, d.1));
        let (seg, h) = CompositeShapeRef(poly).cast_local_ray_and_get_normal(&ray, max, true)?;
        let [a, b] = *self.segs.get(seg as usize)?;
        let (va, vb) = (self.verts[a as usize], self.verts[b as usize]);
        let hit = (o.0 + d.0 * h.time_of_impact, o.1 + d.1 * h.time_of_impact);
        let len2 = (vb.0 - va.0).powi(2) + (vb.1 - va.1).powi(2);
        let s = if len2 > 0.0 {
            (((hit.0 - va.0) * (vb.0 - va.0) + (hit.1 - va.1) * (vb.1 - va.1)) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (na, nb) = (self.normals[a as usize], self.normals[b as usize]);
        let n = (na.0 * (1.0 - s) + nb.0 * s, na.1 * (1.0 - s) + nb.1 * s);
        let l = n.0.hypot(n.1);
        let normal = if l > 1e-9 { (n.0 / l, n.1 / l) } else { (h.normal.x, h.normal.y) };
        Some(SurfaceHit { r: h.time_of_impact, normal, surface: a })
    }

    /// Whether the laser saw `q` to be free space.
    pub fn seen_free(&self, q: P) -> bool {
        let (dx, dy) = (q.0 - self.origin.0, q.1 - self.origin.1);
        let d = dx.hypot(dy);
        if d < 0.05 {
            return true;
        }
        let b = wrap(dy.atan2(dx) - self.heading - self.angle_min).rem_euclid(std::f64::consts::TAU);
        let f = b / self.angle_step;
        let n = self.ranges.len();
        // A scan over the whole turn wraps round from its last beam to its first.
        let round = n as f64 * self.angle_step >= std::f64::consts::TAU - 1e-9;
        let last = if round { n as f64 } else { (n - 1) as f64 };
        if !(f >= 0.0 && f <= last) {
            return false;
        }
        let i0 = (f.floor() as usize).min(n - 1);
        let i1 = if round { (i0 + 1) % n } else { (i0 + 1).min(n - 1) };
        let r = |i: usize| {
            let r = f64::from(self.ranges[i]);
            if r.is_finite() {
                r
            } else {
                NO_RETURN_FREE_M
            }
        };
        r(i0).min(r(i1)) > d + SEEN_MARGIN_M
    }

    /// Whether the laser saw the ray from `o` along `d` free up to `until` m
    /// (sampled every `step` m from `from` m).
    pub fn seen_free_along(&self, o: P, d: P, from: f64, until: f64, step: f64) -> bool {
        let mut s = from;
        while s < until {
            if !self.seen_free((o.0 + d.0 * s, o.1 + d.1 * s)) {
                return false;
            }
            s += step;
        }
        true
    }

    /// Returns kept, surfaces and corners: (returns, segments, points).
    pub fn counts(&self) -> (usize, usize, usize) {
        (self.verts.len(), self.segs.len(), self.points.len())
    }
}

/// Whether returns `a` and `b` (neighbouring beams from `o`) are one surface.
fn join(o: P, a: P, b: P) -> bool {
    let (sx, sy) = (b.0 - a.0, b.1 - a.1);
    let l = sx.hypot(sy);
    if l > JOIN_MAX_M {
        return false;
    }
    if l < 1e-9 {
        return true;
    }
    let m = ((a.0 + b.0) / 2.0 - o.0, (a.1 + b.1) / 2.0 - o.1);
    let ml = m.0.hypot(m.1).max(1e-9);
    let sin = (sx * m.1 - sy * m.0).abs() / (l * ml);
    sin >= SHADOW_DEG.to_radians().sin()
}

fn arc_lengths(p: &[P]) -> Vec<f64> {
    let mut acc = 0.0;
    let mut out = Vec::with_capacity(p.len());
    for (k, v) in p.iter().enumerate() {
        if k > 0 {
            acc += (v.0 - p[k - 1].0).hypot(v.1 - p[k - 1].1);
        }
        out.push(acc);
    }
    out
}

/// The direction of the line through `p[lo..=hi]` (principal axis).
fn direction(p: &[P]) -> Option<P> {
    if p.len() < 2 {
        return None;
    }
    let n = p.len() as f64;
    let (mx, my) = (p.iter().map(|v| v.0).sum::<f64>() / n, p.iter().map(|v| v.1).sum::<f64>() / n);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for v in p {
        let (x, y) = (v.0 - mx, v.1 - my);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let d = (th.cos(), th.sin());
    // Along the points' own order.
    let (first, last) = (p[0], p[p.len() - 1]);
    let sgn = if (last.0 - first.0) * d.0 + (last.1 - first.1) * d.1 >= 0.0 { 1.0 } else { -1.0 };
    Some((d.0 * sgn, d.1 * sgn))
}

/// The unit normal at `p[k]`: the line through the points within `half` m
/// of it along the surface (its neighbours at least), facing `o`.
fn fit_normal(p: &[P], arc: &[f64], k: usize, half: f64, o: P) -> P {
    let lo = (0..=k).rev().take_while(|&j| arc[k] - arc[j] <= half).last().unwrap_or(k).min(k.saturating_sub(1));
    let hi = (k..p.len()).take_while(|&j| arc[j] - arc[k] <= half).last().unwrap_or(k).max((k + 1).min(p.len() - 1));
    let d = direction(&p[lo..=hi]).unwrap_or((1.0, 0.0));
    let n = (-d.1, d.0);
    let to_o = (o.0 - p[k].0, o.1 - p[k].1);
    if n.0 * to_o.0 + n.1 * to_o.1 >= 0.0 {
        n
    } else {
        (-n.0, -n.1)
    }
}

/// The corners and edges along a surface: where the lines fitted on either
/// side turn by more than [`CORNER_TURN_DEG`], the sharpest point of each turn.
fn corners(p: &[P], arc: &[f64], o: P) -> Vec<PointEcho> {
    let mut cand: Vec<(usize, f64, f64)> = Vec::new(); // (index, turn, wedge)
    for k in 1..p.len().saturating_sub(1) {
        // The points within the span each side, and at least two beyond
        // the corner's own where the returns are sparse (not beyond twice it).
        let side = |js: &mut dyn Iterator<Item = usize>| -> Vec<P> {
            let mut v = vec![p[k]];
            for (n, j) in js.enumerate() {
                let d = (arc[j] - arc[k]).abs();
                if d > 2.0 * CORNER_HALF_M || (d > CORNER_HALF_M && n >= 2) {
                    break;
                }
                v.push(p[j]);
            }
            v
        };
        let mut before = side(&mut (0..k).rev());
        before.reverse();
        let after = side(&mut (k + 1..p.len()));
        if before.len() < 3 || after.len() < 3 {
            continue;
        }
        let (Some(d1), Some(d2)) = (direction(&before), direction(&after)) else { continue };
        let turn = wrap(d2.1.atan2(d2.0) - d1.1.atan2(d1.0)).to_degrees();
        if turn.abs() < CORNER_TURN_DEG {
            continue;
        }
        // The free wedge: between the way back (−d1) and the way on (d2),
        // on the side the laser is.
        let back = (-d1.1).atan2(-d1.0);
        let on = d2.1.atan2(d2.0);
        let to_o = (o.1 - p[k].1).atan2(o.0 - p[k].0);
        let ccw = (on - back).rem_euclid(std::f64::consts::TAU);
        let o_in = (to_o - back).rem_euclid(std::f64::consts::TAU) < ccw;
        let wedge = if o_in { ccw } else { std::f64::consts::TAU - ccw }.to_degrees();
        cand.push((k, turn.abs(), wedge));
    }
    // The sharpest point of each run of turning points.
    let mut out = Vec::new();
    let mut i = 0;
    while i < cand.len() {
        let mut j = i;
        while j + 1 < cand.len() && arc[cand[j + 1].0] - arc[cand[j].0] <= CORNER_HALF_M {
            j += 1;
        }
        if let Some(best) = cand[i..=j].iter().max_by(|a, b| a.1.total_cmp(&b.1)) {
            out.push(PointEcho { at: p[best.0], wedge_deg: best.2 });
        }
        i = j + 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A laser at `o` facing +x, 181 beams over 180°, in a room: the
    /// distance along each bearing to `walls` (segments), by brute force.
    fn scan_of(o: P, walls: &[(P, P)]) -> Scan {
        let ranges = (0..181)
            .map(|i| {
                let b = (-90.0 + f64::from(i)).to_radians();
                let d = (b.cos(), b.sin());
                // The bench's brute-force ray crossing (`bench::brute`), not this module's.
                walls
                    .iter()
                    .filter_map(|&(a, c)| crate::bench::brute::ray_cross(o, d, a, c))
                    .map(|p| (p.0 - o.0).hypot(p.1 - o.1))
                    .filter(|&t| t > 0.0)
                    .fold(f64::INFINITY, f64::min) as f32
            })
            .collect();
        Scan::taken_at([o.0, o.1, 0.0], -std::f64::consts::FRAC_PI_2, 1f64.to_radians(), ranges)
    }

    /// An inside corner at (3, 2) between walls x = 3 and y = 2, and a box
    /// whose near corner (1.5, −1) is an outside edge.
    fn scene() -> Surfaces {
        let walls = [
            ((3.0, -5.0), (3.0, 2.0)),
            ((3.0, 2.0), (-1.0, 2.0)),
            ((1.5, -1.0), (2.0, -1.0)),
            ((1.5, -1.0), (1.5, -1.5)),
        ];
        Surfaces::of_scan(&scan_of((0.0, 0.0), &walls), 0.0, 1, &|_| true)
    }

    #[test]
    fn walls_are_surfaces_with_their_normals() {
        let s = scene();
        // A ray along +x meets the wall x = 3, normal (−1, 0).
        let h = s.cast((0.0, 0.0), (1.0, 0.0), 10.0).unwrap();
        assert!((h.r - 3.0).abs() < 1e-6, "{h:?}");
        assert!((h.normal.0 + 1.0).abs() < 1e-6 && h.normal.1.abs() < 1e-6, "{h:?}");
        // Up the wall y = 2 from (0, 0) at 100°: normal (0, −1).
        let a = 80f64.to_radians();
        let h = s.cast((0.0, 0.0), (a.cos(), a.sin()), 10.0).unwrap();
        assert!((h.normal.1 + 1.0).abs() < 1e-3, "{h:?}");
    }

    #[test]
    fn corners_and_edges_are_found_where_the_walls_meet() {
        let s = scene();
        let near = |p: P, q: P| (p.0 - q.0).hypot(p.1 - q.1) < 0.1;
        let inside = s.points.iter().find(|e| near(e.at, (3.0, 2.0))).expect("the inside corner");
        assert!((60.0..=120.0).contains(&inside.wedge_deg), "{inside:?}");
        let edge = s.points.iter().find(|e| near(e.at, (1.5, -1.0))).expect("the box's corner");
        assert!(edge.wedge_deg >= 200.0, "{edge:?}");
        // Nothing else on the straight parts.
        assert!(s.points.iter().all(|e| near(e.at, (3.0, 2.0)) || e.wedge_deg >= 200.0), "{:?}", s.points);
    }

    #[test]
    fn the_laser_saw_free_what_lies_before_its_returns() {
        let s = scene();
        assert!(s.seen_free((2.0, 0.5)));
        assert!(!s.seen_free((3.5, 0.5)), "behind the wall");
        assert!(!s.seen_free((-1.0, 0.0)), "behind the laser");
        assert!(!s.seen_free((1.8, -1.8)), "behind the box");
        assert!(s.seen_free_along((0.0, 0.0), (1.0, 0.0), 0.1, 2.9, 0.1));
        // Straight down no beam returned: free as far as the laser could tell, not beyond.
        assert!(s.seen_free_along((0.0, 0.0), (0.0, -1.0), 0.1, 7.9, 0.1));
        assert!(!s.seen_free((0.0, -8.5)));
    }
}
