//! The true world at one clutter density, and one firing in it and in the
//! map's world.

use std::f64::consts::PI;

use super::clutter::Person;
use super::geom::{wrap, P};
use super::run::{consistent, Clutter, EchoSource, SimReading};
use super::scene::{cast_people, Hit, Owner, PersonAt, StaticScene, Target};
use super::setup::Setup;
use super::sonar::{Draws, Listener, Surf, FAN_HALF_DEG};

/// The true scene at one clutter density: the mapped pieces present, the
/// mapped obstacles removed, the furniture moved in and the people walking.
///
/// The density is continuous: the last item of each kind counts for a part
/// of the run only (an obstacle absent, a piece of furniture in place, a
/// person walking, until that fraction of the drive), so the inconsistency
/// grows smoothly with the density even on a small map.
pub struct World {
    /// Map obstacles absent in the truth (for the whole run, but see
    /// `removed_until_s`), ascending.
    pub removed: Vec<u16>,
    /// The one obstacle of `removed` that is absent only until this time, s.
    pub removed_until_s: Option<(u16, f64)>,
    /// Furniture outlines, m.
    pub furniture: Vec<Vec<P>>,
    /// The one piece of `furniture` (by index) in place only until this time, s.
    pub furniture_until_s: Option<(usize, f64)>,
    /// People and their walks.
    pub people: Vec<Person>,
    /// The clutter counts and density.
    pub clutter: Clutter,
    /// The mapped pieces present before and after `removed_until_s`.
    present: [Present; 2],
    /// The furniture before and after `furniture_until_s`.
    furniture_scenes: [StaticScene; 2],
}

/// The mapped pieces present in the truth.
struct Present {
    /// `None`: all of them (the map's own scene serves).
    scene: Option<StaticScene>,
    /// For each map piece, its shape in `scene` (`None`: removed).
    of_piece: Vec<Option<usize>>,
}

impl Present {
    fn new(setup: &Setup, removed: &[u16]) -> Self {
        let mut of_piece = vec![None; setup.outlines.len()];
        if removed.is_empty() {
            return Self { scene: None, of_piece };
        }
        let scene =
            StaticScene::of_outlines(setup.outlines.iter().enumerate().filter(|(_, o)| !removed.contains(&o.obstacle)));
        for s in 0..scene.len() {
            if let Owner::Mapped { piece, .. } = scene.owner(s) {
                of_piece[piece as usize] = Some(s);
            }
        }
        Self { scene: Some(scene), of_piece }
    }
}

impl World {
    /// The world at density `k` (0: exactly the map).
    pub fn new(setup: &Setup, k: f64) -> Self {
        let c = &setup.candidates;
        let end = setup.traj.duration();
        let [(nr, fr), (nf, ff), (np, fp)] = c.counts(k);
        // The whole items, then the partial one (if any) with its end time.
        let partial = |n: usize, frac: f64, have: usize| (frac > 0.0 && n < have).then_some((n, frac * end));
        let (pr, pf, pp) =
            (partial(nr, fr, c.removable.len()), partial(nf, ff, c.furniture.len()), partial(np, fp, c.people.len()));

        let whole: Vec<u16> = c.removable[..nr].to_vec();
        let mut early = whole.clone();
        early.extend(pr.map(|(i, _)| c.removable[i]));
        let present = [Present::new(setup, &early), Present::new(setup, &whole)];
        let mut removed = early;
        removed.sort_unstable();
        let removed_until_s = pr.map(|(i, t)| (c.removable[i], t));

        let furniture: Vec<Vec<P>> = c.furniture[..nf + usize::from(pf.is_some())].to_vec();
        let scene = |n: usize| {
            StaticScene::new(
                furniture[..n].iter().enumerate().map(|(j, f)| (Owner::Furniture(j as u32), f.clone())).collect(),
            )
        };
        let furniture_scenes = [scene(furniture.len()), scene(nf)];
        let furniture_until_s = pf;

        let walkers = np + usize::from(pp.is_some());
        let people = if walkers > 0 {
            // People walk around the whole items only (a partial one is there part of the time).
            let g = &setup.grid;
            let occ = g.rasterise(
                setup
                    .outlines
                    .iter()
                    .filter(|o| !whole.contains(&o.obstacle))
                    .map(|o| o.pts.as_slice())
                    .chain(furniture.iter().map(|f| f.as_slice())),
            );
            let mut people = c.walk(walkers, setup.cfg.seed, g, &g.edt(&occ), &setup.traj, setup.footprint_m);
            if let (Some((i, t)), Some(p)) = (pp, people.last_mut()) {
                debug_assert_eq!(i + 1, walkers);
                p.until_s = t;
            }
            people
        } else {
            Vec::new()
        };
        let clutter = Clutter { density: k, removed: removed.len(), furniture: furniture.len(), people: people.len() };
        Self { removed, removed_until_s, furniture, furniture_until_s, people, clutter, present, furniture_scenes }
    }

    /// One firing: the reading in this world and in the map's.
    pub fn fire(&self, setup: &Setup, index: usize) -> SimReading {
        let f = setup.firings[index];
        let (x, y, h) = setup.traj.pose(f.t);
        let m = setup.mounts[usize::from(f.transducer)];
        let o = (x + libm::cos(h) * m.0 - libm::sin(h) * m.1, y + libm::sin(h) * m.0 + libm::cos(h) * m.1);
        let ((echo_us, source), (map_us, _)) = self.listen(setup, index as u64, f.t, o, h + m.2);
        let plan = &setup.plan;
        let range_mm = echo_us.map(|t| plan.range_mm(t));
        let map_only_range_mm = map_us.map(|t| plan.range_mm(t));
        let odo = setup.odometry.pose(f.t);
        SimReading {
            cycle: f.cycle,
            slot: f.slot,
            transducer: f.transducer,
            time_s: f.t,
            truth: (x, y, wrap(h)),
            odometry: (odo.0, odo.1, wrap(odo.2)),
            echo_us,
            range_mm,
            source,
            map_only_range_mm,
            consistent: consistent(range_mm, map_only_range_mm),
        }
    }

    /// A ping at time `t` of a transducer at `o` facing `axis` (rad), with
    /// the draws of firing `draw_index`: the reading (driver µs) and its
    /// source in this world, and in the map's world.
    pub fn listen(
        &self,
        setup: &Setup,
        draw_index: u64,
        t: f64,
        o: P,
        axis: f64,
    ) -> ((Option<u32>, EchoSource), (Option<u32>, EchoSource)) {
        let plan = &setup.plan;
        let beam = &setup.beam;
        let rmax = beam.max_range(plan);
        let people: Vec<PersonAt> = self
            .people
            .iter()
            .enumerate()
            .filter_map(|(i, p)| {
                let c = p.at(t)?;
                let dist = libm::hypot(c.0 - o.0, c.1 - o.1);
                // Within range and within the fan (widened by the person's own angular size).
                let off = wrap(libm::atan2(c.1 - o.1, c.0 - o.0) - axis).abs();
                let half = FAN_HALF_DEG.to_radians() + if dist > p.radius { libm::asin(p.radius / dist) } else { PI };
                (dist <= rmax + p.radius && off <= half).then_some(PersonAt { index: i, c, radius: p.radius })
            })
            .collect();
        let draws = Draws::new(setup.cfg.seed, draw_index, plan);
        let mut truth = Listener::new(beam, &draws, plan, o, axis);
        let mut map_only = Listener::new(beam, &draws, plan, o, axis);
        let map = &setup.map_scene;
        let rays: Vec<(P, usize)> = truth.rays().collect();
        let late = |u: Option<f64>| usize::from(u.is_none_or(|end| t >= end));
        let present = &self.present[late(self.removed_until_s.map(|u| u.1))];
        let furniture = &self.furniture_scenes[late(self.furniture_until_s.map(|u| u.1))];
        for (d, i) in rays {
            let hm = map.cast(o, d, rmax);
            if let Some(hit) = hm {
                map_only.hear(i, d, Surf { hit, scene: Some(map) });
            }
            // The mapped pieces present in the truth.
            let mut best: Option<Surf<'_>> = match (&present.scene, hm) {
                (None, hm) => hm.map(|hit| Surf { hit, scene: Some(map) }),
                (Some(p), Some(hit)) => match hit.target {
                    Target::Shape(s) => match map.owner(s) {
                        Owner::Mapped { piece, .. } => match present.of_piece.get(piece as usize).copied().flatten() {
                            Some(ps) => Some(Surf { hit: Hit { target: Target::Shape(ps), ..hit }, scene: Some(p) }),
                            None => p.cast(o, d, rmax).map(|hit| Surf { hit, scene: Some(p) }),
                        },
                        Owner::Furniture(_) => None,
                    },
                    Target::Person(_) => None,
                },
                (Some(_), None) => None,
            };
            let lim = best.map_or(rmax, |b| b.hit.r);
            if let Some(hit) = furniture.cast(o, d, lim) {
                best = Some(Surf { hit, scene: Some(furniture) });
            }
            let lim = best.map_or(rmax, |b| b.hit.r);
            if let Some(hit) = cast_people(&people, o, d, lim) {
                best = Some(Surf { hit, scene: None });
            }
            if let Some(s) = best {
                truth.hear(i, d, s);
            }
        }
        (truth.reading(plan), map_only.reading(plan))
    }
}

/// Fraction of readings not consistent with the map.
pub fn inconsistent_fraction(readings: &[SimReading]) -> f64 {
    if readings.is_empty() {
        return 0.0;
    }
    readings.iter().filter(|r| !r.consistent).count() as f64 / readings.len() as f64
}
