//! Everything a run shares whatever its clutter: the map's outlines and its
//! parry scene, the route, the true motion and the odometry, the clutter
//! candidates, the firing schedule.

use echoloc::map::MapSource;

use super::clutter::{Candidates, Ground};
use super::config::{WorldConfig, WorldError};
use super::geom::{bbox, is_wall_obstacle, map_outlines, obstacle_areas, Outline, P};
use super::grid::Grid;
use super::motion::{Odometry, OdometryErrors, Trajectory};
use super::route::{length, FreeSpace};
use super::scene::StaticScene;
use super::sonar::Beam;
use super::timing::FiringPlan;
use crate::credence::rng::Rng;

/// Sub-streams of the run's draws (the firings and people use their own ranges).
const STREAM_ROUTE: u64 = 1;
/// Odometry's systematic errors.
const STREAM_ODOMETRY_ERRORS: u64 = 2;
/// Odometry's random slip.
const STREAM_ODOMETRY_NOISE: u64 = 3;
/// The clutter candidates.
const STREAM_CLUTTER: u64 = 4;
/// Smallest footprint radius assumed, m (a ring with every transducer at the centre).
const MIN_FOOTPRINT_M: f64 = 0.15;

/// One scheduled firing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Firing {
    /// Cycle.
    pub cycle: u32,
    /// Slot.
    pub slot: u8,
    /// Transducer.
    pub transducer: u8,
    /// Time, s.
    pub t: f64,
}

/// Everything that does not depend on the clutter density.
pub struct Setup {
    /// The settings.
    pub cfg: WorldConfig,
    /// The map's true pieces, m.
    pub outlines: Vec<Outline>,
    /// The map's world in parry: every mapped piece.
    pub map_scene: StaticScene,
    /// The beam and the air.
    pub beam: Beam,
    /// The firing plan.
    pub plan: FiringPlan,
    /// The grid over the map.
    pub grid: Grid,
    /// The route, m.
    pub route: Vec<P>,
    /// The true motion.
    pub traj: Trajectory,
    /// The logged odometry.
    pub odometry: Odometry,
    /// Its systematic errors.
    pub odometry_errors: OdometryErrors,
    /// The clutter candidates.
    pub candidates: Candidates,
    /// The robot's footprint radius, m.
    pub footprint_m: f64,
    /// Every firing of the run.
    pub firings: Vec<Firing>,
    /// Transducer positions (m) and headings (rad) in the robot frame.
    pub mounts: Vec<(f64, f64, f64)>,
}

impl Setup {
    /// Plans the route, drives it, draws the odometry and the clutter candidates.
    pub fn new<M: MapSource>(map: &M, cfg: &WorldConfig) -> Result<Self, WorldError> {
        cfg.check()?;
        let outlines = map_outlines(map);
        let (lo, hi) = bbox(outlines.iter().flat_map(|o| o.pts.iter())).ok_or(WorldError::EmptyMap)?;
        let plan = FiringPlan::new(cfg.mounts.len(), cfg.binh_after_us)?;
        let beam = Beam::new(cfg.temperature_c, cfg.humidity_pct);
        let mounts: Vec<(f64, f64, f64)> = cfg
            .mounts
            .iter()
            .map(|m| {
                (
                    f64::from(m.x_mm) / 1000.0,
                    f64::from(m.y_mm) / 1000.0,
                    (f64::from(m.heading_mdeg) / 1000.0).to_radians(),
                )
            })
            .collect();
        let footprint_m = mounts.iter().map(|m| libm::hypot(m.0, m.1)).fold(MIN_FOOTPRINT_M, f64::max);

        // The route, on the full map.
        // A thin margin round the map: the outside of a closed building is
        // a strip too narrow for any clearance, so the route stays inside;
        // an open map is driven within its bounding box.
        let grid = Grid::covering(lo, hi, 2.0 * Grid::MARGIN);
        if grid.len() > super::grid::MAX_CELLS {
            return Err(WorldError::TooLarge { width_m: hi.0 - lo.0, height_m: hi.1 - lo.1 });
        }
        // Which obstacle occupies each cell (conservatively, as `Grid::rasterise`).
        let mut owner = vec![u32::MAX; grid.len()];
        for o in &outlines {
            for k in grid.outline_cells(&o.pts, Grid::MARGIN / 2.0) {
                owner[k] = u32::from(o.obstacle);
            }
        }
        let occ: Vec<bool> = owner.iter().map(|&o| o != u32::MAX).collect();
        let map_dist = grid.edt(&occ);
        let space = FreeSpace::new(&grid, &map_dist, cfg.clearance_m)?;
        let mut route_rng = Rng::substream(cfg.seed, STREAM_ROUTE);
        let mut route = space.route(cfg.distance_m, &mut route_rng)?;
        let turn = cfg.turn_rate_deg_s.to_radians();
        let mut traj = Trajectory::new(&route, cfg.speed_m_s, turn);
        // Each kidnap cuts the drive, carries the robot, and plans the rest
        // of the route's length from where it was set down.
        let mut legs = vec![route.clone()];
        let mut leg_start = 0.0;
        for k in &cfg.kidnaps {
            if k.t_s >= traj.duration() {
                return Err(WorldError::Kidnap(format!(
                    "at {} s: the drive is over by then ({:.1} s)",
                    k.t_s,
                    traj.duration()
                )));
            }
            // On the odometry's sample grid, so the wheels see no half step.
            let t = (k.t_s / super::motion::ODOMETRY_DT_S).round() * super::motion::ODOMETRY_DT_S;
            let driven = traj.driven(t);
            let left = cfg.distance_m - driven;
            if let Some(last) = legs.last_mut() {
                *last = driven_part(last, driven - leg_start);
            }
            leg_start = driven;
            traj.cut(t);
            let from = traj.end();
            let to = (from.0 + k.dx_m, from.1 + k.dy_m, from.2 + k.dtheta_rad);
            let cell = space.region_cell((to.0, to.1)).ok_or_else(|| {
                WorldError::Kidnap(format!(
                    "at {} s: set down at ({:.2}, {:.2}) m, which is not in the free space the route drives in",
                    k.t_s, to.0, to.1
                ))
            })?;
            traj.jump(to);
            let mut leg = space.route_from(cell, left.max(super::grid::CELL_M), &mut route_rng)?;
            leg.insert(0, (to.0, to.1));
            traj.extend(&leg, cfg.speed_m_s, turn);
            legs.push(leg);
        }
        if !cfg.kidnaps.is_empty() {
            route = legs.concat();
        }
        let odometry_errors =
            OdometryErrors::draw(&cfg.odometry, &mut Rng::substream(cfg.seed, STREAM_ODOMETRY_ERRORS));
        let odometry = Odometry::integrate(
            &traj,
            &cfg.odometry,
            &odometry_errors,
            &mut Rng::substream(cfg.seed, STREAM_ODOMETRY_NOISE),
        );

        // The floor the robot is on, and the distance to its route.
        let free0: Vec<bool> = occ.iter().map(|&o| !o).collect();
        let (labels, regions) = grid.regions(&free0);
        let start = route.first().and_then(|&p| grid.cell_of(p)).map_or(u32::MAX, |k| labels[k]);
        let floor: Vec<bool> = labels.iter().map(|&l| l == start && l != u32::MAX).collect();
        // Obstacles that touch the outside (free space reaching the grid's
        // border, other than the robot's own) are the building's shell.
        let outside = |k: usize| labels[k] != start && regions.get(labels[k] as usize).is_some_and(|r| r.border);
        let mut shell = vec![false; map.obstacle_count()];
        for (k, &ob) in owner.iter().enumerate() {
            if ob != u32::MAX {
                let (i, j) = grid.ij(k);
                if grid.neighbours(i, j).any(|(a, b)| outside(grid.idx(a, b))) {
                    if let Some(s) = shell.get_mut(ob as usize) {
                        *s = true;
                    }
                }
            }
        }
        let mut on_route = vec![false; grid.len()];
        for leg in &legs {
            grid.mark_polyline(&mut on_route, leg, Grid::MARGIN / 2.0);
        }
        let route_dist = grid.edt(&on_route);
        let areas = obstacle_areas(map, &outlines);
        let fixed: Vec<bool> =
            (0..areas.len()).map(|i| is_wall_obstacle(map, i) || shell.get(i).copied().unwrap_or(true)).collect();
        let ground = Ground { grid: &grid, map_dist: &map_dist, route_dist: &route_dist, floor: &floor, footprint_m };
        let candidates = Candidates::draw(&ground, &areas, &fixed, &mut Rng::substream(cfg.seed, STREAM_CLUTTER));

        // The firings: whole cycles until the drive is over.
        let period_us = u64::from(plan.period_us);
        let cycles = ((traj.duration() * 1e6) / period_us as f64).ceil().max(1.0) as u32;
        let firings = (0..cycles)
            .flat_map(|c| {
                let plan = &plan;
                (0..plan.order.len()).map(move |s| Firing {
                    cycle: c,
                    slot: s as u8,
                    transducer: plan.order[s],
                    t: plan.fire_us(c, s) as f64 * 1e-6,
                })
            })
            .collect();
        let map_scene = StaticScene::of_outlines(outlines.iter().enumerate());
        Ok(Self {
            cfg: cfg.clone(),
            outlines,
            map_scene,
            beam,
            plan,
            grid,
            route,
            traj,
            odometry,
            odometry_errors,
            candidates,
            footprint_m,
            firings,
            mounts,
        })
    }

    /// The route's length, m: what was driven (a carry drives nothing).
    pub fn route_length(&self) -> f64 {
        if self.cfg.kidnaps.is_empty() {
            length(&self.route)
        } else {
            self.traj.driven(self.traj.duration())
        }
    }
}

/// The first `len` metres of `route`.
fn driven_part(route: &[P], len: f64) -> Vec<P> {
    let mut out = vec![route[0]];
    let mut acc = 0.0;
    for w in route.windows(2) {
        let l = libm::hypot(w[1].0 - w[0].0, w[1].1 - w[0].1);
        if acc + l >= len {
            let t = if l > 0.0 { ((len - acc) / l).max(0.0) } else { 0.0 };
            out.push((w[0].0 + (w[1].0 - w[0].0) * t, w[0].1 + (w[1].1 - w[0].1) * t));
            return out;
        }
        acc += l;
        out.push(w[1]);
    }
    out
}
