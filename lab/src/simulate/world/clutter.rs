//! What differs between the true world and the map: mapped obstacles taken
//! away, furniture moved in, people walking about.
//!
//! For each seed the candidates are drawn once, in order (obstacles to
//! remove, smallest first; furniture placements; people); a density knob
//! `k` in 0..=1 takes the first `k·max` of each list, so more density only
//! ever adds clutter and the inconsistency it causes grows with `k`.

use super::geom::{polygon_area, rectangle, P};
use super::grid::{Grid, CELL_M};
use super::motion::Trajectory;
use crate::credence::rng::Rng;

/// Largest solid obstacle that may be removed, m²: furniture, boxes,
/// pallets; not rooms' walls or racks, so the map's structure stays.
pub const REMOVABLE_MAX_AREA_M2: f64 = 3.0;
/// At full density, this fraction of the removable obstacles is gone.
pub const REMOVED_MAX_FRACTION: f64 = 1.0;
/// At full density, pieces of furniture per m² of free floor near the route.
pub const FURNITURE_PER_M2: f64 = 0.15;
/// At full density, people per m² of free floor near the route.
pub const PEOPLE_PER_M2: f64 = 0.25;
/// Furniture and people are placed this close to the route at most, m:
/// farther the sonar (5.5 m) would hardly hear them.
pub const NEAR_ROUTE_M: f64 = 4.0;
/// Furniture side lengths, m (chairs to desks and cabinets).
pub const FURNITURE_SIDE_M: (f64, f64) = (0.4, 1.2);
/// Furniture keeps this much more than the robot's footprint from the route, m.
pub const FURNITURE_ROUTE_GAP_M: f64 = 0.3;
/// Furniture keeps this far from mapped obstacles and other furniture, m, so
/// it makes no new inside corner with them.
pub const FURNITURE_GAP_M: f64 = 0.05;
/// Person radius, m (shoulders of an adult, seen from above).
pub const PERSON_RADIUS_M: (f64, f64) = (0.2, 0.25);
/// Walking speed, m/s (a slow indoor walk to a brisk one).
pub const PERSON_SPEED_M_S: (f64, f64) = (0.5, 1.3);
/// People keep this far from the robot's footprint, m.
pub const PERSON_ROBOT_GAP_M: f64 = 0.2;
/// People keep this far from obstacles, m.
pub const PERSON_GAP_M: f64 = 0.05;
/// Time step of the people's walk, s (13 cm at the fastest).
pub const PEOPLE_DT_S: f64 = 0.1;
/// Tries to place one piece of furniture, or to find a free heading.
const TRIES: usize = 40;

/// One person's walk.
#[derive(Clone, Debug, PartialEq)]
pub struct Person {
    /// Radius, m.
    pub radius: f64,
    speed: f64,
    heading: f64,
    start_stream: u64,
    /// Position every [`PEOPLE_DT_S`] from the start (filled by [`Candidates::walk`]).
    pub track: Vec<P>,
    /// The person leaves at this time, s (infinite: stays the whole run).
    pub until_s: f64,
}

impl Person {
    /// The path sampled every `dt_s` (a multiple of [`PEOPLE_DT_S`]) while the person is there.
    pub fn path(&self, dt_s: f64) -> Vec<P> {
        let every = libm::round(dt_s / PEOPLE_DT_S).max(1.0) as usize;
        let n = self.track.len().min(libm::ceil(self.until_s / PEOPLE_DT_S).min(usize::MAX as f64) as usize);
        self.track[..n].iter().step_by(every).copied().collect()
    }

    /// The position at `t`, s (interpolated, clamped to the walk), if the
    /// person is there.
    pub fn at(&self, t: f64) -> Option<P> {
        if t >= self.until_s {
            return None;
        }
        let f = (t / PEOPLE_DT_S).max(0.0);
        let i = f.floor() as usize;
        match (self.track.get(i), self.track.get(i + 1)) {
            (Some(a), Some(b)) => {
                let s = f - i as f64;
                Some((a.0 + (b.0 - a.0) * s, a.1 + (b.1 - a.1) * s))
            }
            (Some(&a), None) => Some(a),
            _ => self.track.last().copied(),
        }
    }
}

/// The clutter candidates of one seed.
pub struct Candidates {
    /// Removable map obstacles in removal order.
    pub removable: Vec<u16>,
    /// How many of them go at full density.
    pub removed_max: usize,
    /// Furniture rectangles in placement order (all placeable together).
    pub furniture: Vec<Vec<P>>,
    /// How many pieces of furniture at full density (≤ `furniture.len()` may fall short).
    pub furniture_max: usize,
    /// People, not yet walked.
    pub people: Vec<Person>,
    /// Cells where people may start (near the route, in the robot's region).
    starts: Vec<usize>,
}

/// What the candidates are drawn against.
pub struct Ground<'a> {
    /// The grid.
    pub grid: &'a Grid,
    /// Distance from each cell centre to the full map's obstacles, m.
    pub map_dist: &'a [f64],
    /// Distance from each cell centre to the route, m.
    pub route_dist: &'a [f64],
    /// Cells of the floor region the robot drives in (zero clearance).
    pub floor: &'a [bool],
    /// The robot's footprint radius, m.
    pub footprint_m: f64,
}

impl Candidates {
    /// Draws the candidates; obstacles marked `fixed` (walls, the building's
    /// shell) are never removed.
    pub fn draw(g: &Ground<'_>, areas: &[f64], fixed: &[bool], rng: &mut Rng) -> Self {
        // Obstacles: small solids, smallest first with some shuffling.
        let mut keyed: Vec<(f64, u16)> = (0..areas.len())
            .filter(|&i| !fixed[i] && areas[i] > 0.0 && areas[i] <= REMOVABLE_MAX_AREA_M2)
            .map(|i| (areas[i] * rng.uniform(0.5, 2.0), i as u16))
            .collect();
        keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let removable: Vec<u16> = keyed.into_iter().map(|(_, i)| i).collect();
        let removed_max = libm::ceil(REMOVED_MAX_FRACTION * removable.len() as f64) as usize;

        // Floor near the route.
        let near: Vec<usize> = (0..g.grid.len())
            .filter(|&k| g.floor[k] && g.route_dist[k] <= NEAR_ROUTE_M && g.map_dist[k] > Grid::MARGIN)
            .collect();
        let area = near.len() as f64 * CELL_M * CELL_M;
        let furniture_max = libm::round(FURNITURE_PER_M2 * area) as usize;
        let people_max = libm::round(PEOPLE_PER_M2 * area) as usize;

        let furniture = place_furniture(g, &near, furniture_max, rng);
        let starts: Vec<usize> = near
            .iter()
            .copied()
            .filter(|&k| g.route_dist[k] >= g.footprint_m + PERSON_ROBOT_GAP_M + PERSON_RADIUS_M.1 + Grid::MARGIN)
            .collect();
        let people = (0..people_max)
            .map(|i| Person {
                radius: rng.uniform(PERSON_RADIUS_M.0, PERSON_RADIUS_M.1),
                speed: rng.uniform(PERSON_SPEED_M_S.0, PERSON_SPEED_M_S.1),
                heading: rng.uniform(-std::f64::consts::PI, std::f64::consts::PI),
                start_stream: STREAM_PEOPLE + i as u64,
                track: Vec::new(),
                until_s: f64::INFINITY,
            })
            .collect();
        Self { removable, removed_max, furniture, furniture_max, people, starts }
    }

    /// The counts at density `k`, each as whole items and the fraction of
    /// one more: removed obstacles, furniture, people.
    pub fn counts(&self, k: f64) -> [(usize, f64); 3] {
        let n = |max: usize, have: usize| {
            let x = k.clamp(0.0, 1.0) * max.min(have) as f64;
            let whole = libm::floor(x);
            (whole as usize, x - whole)
        };
        [
            n(self.removed_max, self.removable.len()),
            n(self.furniture_max, self.furniture.len()),
            n(self.people.len(), self.people.len()),
        ]
    }

    /// Walks the first `n` people for `duration` s through the free space
    /// `dist` (distance to the true obstacles), keeping clear of the robot.
    pub fn walk(
        &self,
        n: usize,
        seed: u64,
        grid: &Grid,
        dist: &[f64],
        traj: &Trajectory,
        footprint_m: f64,
    ) -> Vec<Person> {
        let steps = (traj.duration() / PEOPLE_DT_S).ceil() as usize + 1;
        let robot: Vec<P> = (0..=steps)
            .map(|s| {
                let p = traj.pose(s as f64 * PEOPLE_DT_S);
                (p.0, p.1)
            })
            .collect();
        self.people[..n.min(self.people.len())]
            .iter()
            .map(|spec| {
                let mut rng = Rng::substream(seed, spec.start_stream);
                let clear = |p: P, s: usize| {
                    let free = grid.cell_of(p).is_some_and(|k| dist[k] >= spec.radius + PERSON_GAP_M + Grid::MARGIN);
                    let r = robot[s.min(robot.len() - 1)];
                    free && libm::hypot(p.0 - r.0, p.1 - r.1) >= spec.radius + footprint_m + PERSON_ROBOT_GAP_M
                };
                // A start clear of the true obstacles (furniture included).
                let mut at = None;
                for _ in 0..TRIES {
                    if self.starts.is_empty() {
                        break;
                    }
                    let k =
                        self.starts[((rng.next_f64() * self.starts.len() as f64) as usize).min(self.starts.len() - 1)];
                    if clear(grid.centre(k), 0) {
                        at = Some(grid.centre(k));
                        break;
                    }
                }
                let Some(mut p) = at else {
                    return Person { track: Vec::new(), ..spec.clone() };
                };
                let mut heading = spec.heading;
                let mut track = Vec::with_capacity(steps + 1);
                track.push(p);
                for s in 1..=steps {
                    let step = spec.speed * PEOPLE_DT_S;
                    let ahead = |h: f64| (p.0 + step * libm::cos(h), p.1 + step * libm::sin(h));
                    if !clear(ahead(heading), s) {
                        // Bounce: a new heading that is clear, else wait.
                        for _ in 0..TRIES {
                            let h = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
                            if clear(ahead(h), s) {
                                heading = h;
                                break;
                            }
                        }
                    }
                    if clear(ahead(heading), s) {
                        p = ahead(heading);
                    }
                    track.push(p);
                }
                Person { track, ..spec.clone() }
            })
            .collect()
    }
}

/// Sub-stream numbers of the people's walks.
const STREAM_PEOPLE: u64 = 1 << 20;

/// Up to `max` rectangles near the route, each clear of the route by the
/// footprint and [`FURNITURE_ROUTE_GAP_M`], of the map and of each other by
/// [`FURNITURE_GAP_M`] (checked on the grid, conservatively).
fn place_furniture(g: &Ground<'_>, near: &[usize], max: usize, rng: &mut Rng) -> Vec<Vec<P>> {
    let mut taken = vec![false; g.grid.len()];
    let mut out = Vec::new();
    let route_need = g.footprint_m + FURNITURE_ROUTE_GAP_M + Grid::MARGIN;
    let centres: Vec<usize> = near.iter().copied().filter(|&k| g.route_dist[k] >= route_need).collect();
    if centres.is_empty() {
        return out;
    }
    while out.len() < max {
        let mut placed = false;
        for _ in 0..TRIES {
            let c = g.grid.centre(centres[((rng.next_f64() * centres.len() as f64) as usize).min(centres.len() - 1)]);
            let (w, h) = (
                rng.uniform(FURNITURE_SIDE_M.0, FURNITURE_SIDE_M.1),
                rng.uniform(FURNITURE_SIDE_M.0, FURNITURE_SIDE_M.1),
            );
            let rect = rectangle(c, w, h, rng.uniform(0.0, std::f64::consts::PI));
            // Every cell within half a diagonal of the rectangle.
            let mine = g.grid.outline_cells(&rect, Grid::MARGIN / 2.0);
            let ok = !mine.is_empty()
                && mine.iter().all(|&k| {
                    g.floor[k]
                        && !taken[k]
                        && g.route_dist[k] >= route_need
                        && g.map_dist[k] >= FURNITURE_GAP_M + Grid::MARGIN
                });
            if ok {
                g.grid.mark_outline(&mut taken, &rect, FURNITURE_GAP_M + Grid::MARGIN);
                out.push(rect);
                placed = true;
                break;
            }
        }
        if !placed {
            break;
        }
    }
    debug_assert!(out.iter().all(|r| polygon_area(r) > 0.0));
    out
}
