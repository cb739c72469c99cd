//! The scene the sonar hears, in `parry2d`: convex polygons and segments in
//! one `Compound` (its BVH answers every ray), people as balls, and, for
//! every vertex, the free wedges around it (inside corners reflect back,
//! outside edges diffract).

use parry2d_f64::math::{Pose, Vector};
use parry2d_f64::query::{PointQuery, Ray, RayCast};
use parry2d_f64::shape::{Ball, CompositeShapeRef, Compound, SharedShape};

use super::geom::{Outline, P};

/// Directions sampled around a vertex for its free wedges: 5° apart, at
/// 2.5° + k·5° so that none lies along an axis-aligned face.
const WEDGE_SAMPLES: usize = 72;
/// Radius of the circle sampled around a vertex, m: small beside a piece
/// (the maps are simplified to a few cm) yet far above rounding.
const WEDGE_PROBE_M: f64 = 0.03;

/// Who a scene shape belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Owner {
    /// A map piece: its obstacle and piece index.
    Mapped {
        /// The map obstacle.
        obstacle: u16,
        /// The map piece.
        piece: u32,
    },
    /// Furniture moved in: its index.
    Furniture(u32),
}

impl Owner {
    /// A key for the echo's random fluctuation: the same surface in the
    /// true world and in the map's world draws the same.
    pub fn key(self) -> u64 {
        match self {
            Owner::Mapped { piece, .. } => u64::from(piece),
            Owner::Furniture(i) => (1 << 32) | u64::from(i),
        }
    }
}

/// One ray's hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray, m.
    pub r: f64,
    /// Unit surface normal at the hit.
    pub normal: P,
    /// What was hit.
    pub target: Target,
}

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Shape `.0` of a static scene.
    Shape(usize),
    /// Person `.0`.
    Person(usize),
}

/// A free wedge around a vertex, in direction samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Wedge {
    start: u8,
    len: u8,
}

/// Static shapes in one `parry2d` compound.
pub struct StaticScene {
    compound: Option<Compound>,
    shapes: Vec<(Owner, Vec<P>)>,
    /// Per shape, per vertex: its free wedges.
    wedges: Vec<Vec<Vec<Wedge>>>,
}

impl StaticScene {
    /// The scene of `shapes` (convex outlines, counter-clockwise, or two-point walls).
    pub fn new(shapes: Vec<(Owner, Vec<P>)>) -> Self {
        let parts: Vec<(Pose, SharedShape)> =
            shapes.iter().filter_map(|(_, pts)| Some((Pose::IDENTITY, shape(pts)?))).collect();
        // A shape parry refuses (degenerate) would shift the indices: keep
        // only the accepted ones, in order.
        let shapes: Vec<(Owner, Vec<P>)> = shapes.into_iter().filter(|(_, pts)| shape(pts).is_some()).collect();
        let compound = (!parts.is_empty()).then(|| Compound::new(parts));
        let mut s = Self { compound, shapes, wedges: Vec::new() };
        s.wedges = s.shapes.iter().map(|(_, pts)| pts.iter().map(|&v| s.free_wedges(v)).collect()).collect();
        s
    }

    /// The scene of map outlines, with their piece indices.
    pub fn of_outlines<'a>(outlines: impl IntoIterator<Item = (usize, &'a Outline)>) -> Self {
        Self::new(
            outlines
                .into_iter()
                .map(|(i, o)| (Owner::Mapped { obstacle: o.obstacle, piece: i as u32 }, o.pts.clone()))
                .collect(),
        )
    }

    /// Number of shapes.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    /// The owner of shape `i`.
    pub fn owner(&self, i: usize) -> Owner {
        self.shapes[i].0
    }

    /// The vertices of shape `i`.
    pub fn vertices(&self, i: usize) -> &[P] {
        &self.shapes[i].1
    }

    /// The nearest hit of the ray from `o` along the unit direction `d`, within `max`.
    pub fn cast(&self, o: P, d: P, max: f64) -> Option<Hit> {
        let c = self.compound.as_ref()?;
        let ray = Ray::new(Vector::new(o.0, o.1), Vector::new(d.0, d.1));
        let (id, h) = CompositeShapeRef(c).cast_local_ray_and_get_normal(&ray, max, true)?;
        Some(Hit { r: h.time_of_impact, normal: (h.normal.x, h.normal.y), target: Target::Shape(id as usize) })
    }

    /// The angular size, degrees, of the free wedge at vertex `v` of shape
    /// `shape` that contains the direction `dir` (radians, from the vertex),
    /// or `None` if that direction is blocked right at the vertex.
    pub fn wedge_deg(&self, shape: usize, v: usize, dir: f64) -> Option<f64> {
        let step = std::f64::consts::TAU / WEDGE_SAMPLES as f64;
        let k = (libm::floor(dir.rem_euclid(std::f64::consts::TAU) / step) as usize) % WEDGE_SAMPLES;
        let wedges = self.wedges.get(shape)?.get(v)?;
        wedges
            .iter()
            .find(|w| (k + WEDGE_SAMPLES - usize::from(w.start)) % WEDGE_SAMPLES < usize::from(w.len))
            .map(|w| f64::from(w.len) * 360.0 / WEDGE_SAMPLES as f64)
    }

    /// Whether `p` is inside a solid shape.
    pub fn contains(&self, p: P) -> bool {
        self.compound.as_ref().is_some_and(|c| c.contains_point(&Pose::IDENTITY, Vector::new(p.0, p.1)))
    }

    /// The free wedges around `v`: runs of free sample points on a small
    /// circle whose chords cross nothing.
    fn free_wedges(&self, v: P) -> Vec<Wedge> {
        let pts: Vec<P> = (0..WEDGE_SAMPLES)
            .map(|k| {
                let a = (k as f64 + 0.5) * std::f64::consts::TAU / WEDGE_SAMPLES as f64;
                (v.0 + WEDGE_PROBE_M * libm::cos(a), v.1 + WEDGE_PROBE_M * libm::sin(a))
            })
            .collect();
        let free: Vec<bool> = pts.iter().map(|&p| !self.contains(p)).collect();
        let linked: Vec<bool> = (0..WEDGE_SAMPLES)
            .map(|k| {
                let (a, b) = (pts[k], pts[(k + 1) % WEDGE_SAMPLES]);
                free[k] && free[(k + 1) % WEDGE_SAMPLES] && self.chord_clear(a, b)
            })
            .collect();
        if linked.iter().all(|&l| l) {
            return vec![Wedge { start: 0, len: WEDGE_SAMPLES as u8 }];
        }
        // Start just after a break, walk once round.
        let first = (0..WEDGE_SAMPLES).find(|&k| !linked[k]).map_or(0, |k| (k + 1) % WEDGE_SAMPLES);
        let mut out = Vec::new();
        let mut k = first;
        for _ in 0..WEDGE_SAMPLES {
            if !free[k] {
                k = (k + 1) % WEDGE_SAMPLES;
                continue;
            }
            let start = k;
            let mut len = 1;
            while linked[k] && len < WEDGE_SAMPLES {
                k = (k + 1) % WEDGE_SAMPLES;
                len += 1;
            }
            out.push(Wedge { start: start as u8, len: len as u8 });
            k = (k + 1) % WEDGE_SAMPLES;
            if (k + WEDGE_SAMPLES - first).is_multiple_of(WEDGE_SAMPLES) {
                break;
            }
        }
        out.dedup_by(|a, b| a.start == b.start);
        out
    }

    fn chord_clear(&self, a: P, b: P) -> bool {
        let Some(c) = self.compound.as_ref() else { return true };
        let ray = Ray::new(Vector::new(a.0, a.1), Vector::new(b.0 - a.0, b.1 - a.1));
        c.cast_local_ray(&ray, 1.0, true).is_none()
    }
}

/// The parry shape of a convex outline (a segment for two points).
fn shape(pts: &[P]) -> Option<SharedShape> {
    match pts {
        [a, b] => Some(SharedShape::segment(Vector::new(a.0, a.1), Vector::new(b.0, b.1))),
        _ if pts.len() >= 3 => SharedShape::convex_polyline(pts.iter().map(|p| Vector::new(p.0, p.1)).collect()),
        _ => None,
    }
}

/// A person at one moment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PersonAt {
    /// Index of the person.
    pub index: usize,
    /// Centre, m.
    pub c: P,
    /// Radius, m.
    pub radius: f64,
}

/// The nearest hit of a ray on the people, within `max`.
pub fn cast_people(people: &[PersonAt], o: P, d: P, max: f64) -> Option<Hit> {
    let ray = Ray::new(Vector::new(o.0, o.1), Vector::new(d.0, d.1));
    let mut best: Option<Hit> = None;
    for p in people {
        let lim = best.map_or(max, |b| b.r);
        let pose = Pose::from_translation(Vector::new(p.c.0, p.c.1));
        if let Some(h) = Ball::new(p.radius).cast_ray_and_get_normal(&pose, &ray, lim, true) {
            if h.time_of_impact < lim {
                best = Some(Hit {
                    r: h.time_of_impact,
                    normal: (h.normal.x, h.normal.y),
                    target: Target::Person(p.index),
                });
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> StaticScene {
        // A 1 m square, x 2..3, y −0.5..0.5, and a wall x = 0..1 at y = 2.
        StaticScene::new(vec![
            (Owner::Furniture(0), vec![(2.0, -0.5), (3.0, -0.5), (3.0, 0.5), (2.0, 0.5)]),
            (Owner::Furniture(1), vec![(0.0, 2.0), (1.0, 2.0)]),
        ])
    }

    #[test]
    fn parry_ray_hits_the_square_where_hand_computed() {
        let s = square();
        // From the origin at 10° up: x = 2 at r = 2 / cos 10°, face normal −x.
        let a = 10f64.to_radians();
        let h = s.cast((0.0, 0.0), (a.cos(), a.sin()), 10.0).unwrap();
        assert!((h.r - 2.0 / a.cos()).abs() < 1e-9, "{}", h.r);
        assert!((h.normal.0 + 1.0).abs() < 1e-9 && h.normal.1.abs() < 1e-9);
        assert_eq!(h.target, Target::Shape(0));
        // Straight up hits the wall at 2 m; beyond max, nothing.
        let h = s.cast((0.5, 0.0), (0.0, 1.0), 10.0).unwrap();
        assert!((h.r - 2.0).abs() < 1e-9 && h.target == Target::Shape(1));
        assert!(s.cast((0.5, 0.0), (0.0, 1.0), 1.9).is_none());
        // Past the square's corner: nothing.
        let a = 20f64.to_radians();
        assert!(s.cast((0.0, 0.0), (a.cos(), a.sin()), 10.0).is_none());
        // A person 1 m ahead, radius 0.25: hit at 0.75.
        let p = [PersonAt { index: 3, c: (1.0, 0.0), radius: 0.25 }];
        let h = cast_people(&p, (0.0, 0.0), (1.0, 0.0), 10.0).unwrap();
        assert!((h.r - 0.75).abs() < 1e-9 && h.target == Target::Person(3));
    }

    #[test]
    fn wedges_of_corners() {
        let s = square();
        // The square's corner (2, −0.5): 270° free; the wall's end: 360°.
        let w = s.wedge_deg(0, 0, (-1f64).atan2(-1.0)).unwrap();
        assert!((w - 270.0).abs() <= 10.0, "{w}");
        assert!(s.wedge_deg(0, 0, 0.3).is_none(), "into the square");
        assert!((s.wedge_deg(1, 0, 2.0).unwrap() - 360.0).abs() < 1e-9);
        // An inside corner: a wall up from the square's top-left corner
        // (2, 0.5) leaves 90° free to the north-east, 180° to the west.
        let c = StaticScene::new(vec![
            (Owner::Furniture(0), vec![(2.0, -0.5), (3.0, -0.5), (3.0, 0.5), (2.0, 0.5)]),
            (Owner::Furniture(1), vec![(2.0, 0.5), (2.0, 2.0)]),
        ]);
        let w = c.wedge_deg(1, 0, 45f64.to_radians()).unwrap();
        assert!((w - 90.0).abs() <= 1e-9, "{w}");
        let w = c.wedge_deg(1, 0, 135f64.to_radians()).unwrap();
        assert!((w - 180.0).abs() <= 1e-9, "{w}");
    }
}
