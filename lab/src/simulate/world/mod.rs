//! The simulated world: route, odometry and the physical sonar. It shares no
//! geometry code with the predictor.
//!
//! [`simulate_world`] plans a route through the map's free space, drives it
//! (true poses and the wheel odometry a robot logs), builds the true scene
//! (mapped pieces minus some removed obstacles, plus furniture moved in and
//! people walking; the density calibrated to the asked-for inconsistency),
//! and fires the ring on the driver's own schedule, ray-casting each ping
//! with `parry2d` on the true outlines. The map is read once for its piece
//! outlines; none of the predictor's code (prediction, windows, t-vectors,
//! buffers, the map's queries) is used (DESIGN §4.7).
//!
//! A seed gives the same run bit for bit: every draw comes from the lab's
//! SplitMix64 streams (one per purpose, one per firing), every
//! transcendental function is `libm`'s, and parry is built with its
//! `enhanced-determinism` feature.
//!
//! Files: `config` (settings, errors), `geom` and `grid` (plain geometry, the
//! occupancy grid), `route`, `motion` (truth and odometry), `timing` (the
//! driver's firing plan), `scene` (parry shapes), `clutter`, `sonar` (the
//! echo model), `setup` (what every density shares), `truth` (one world,
//! one firing), `calibrate`, `run` (results).

mod calibrate;
mod clutter;
mod config;
mod geom;
mod grid;
mod motion;
mod route;
mod run;
mod scene;
mod setup;
mod sonar;
#[cfg(test)]
mod tests;
mod timing;
mod truth;

pub use config::{within_reach, Kidnap, WorldConfig, WorldError};
pub use geom::wrap;
pub use run::{EchoKind, EchoSource, SimReading, SimRun};
// The rest of the API: the types of `WorldConfig`'s and `SimRun`'s fields,
// and the agreement tolerance (the simulate command need not name them).
#[allow(unused_imports)]
pub use config::OdometryModel;
pub use motion::{Odometry, OdometryErrors, Trajectory, ODOMETRY_DT_S};
#[allow(unused_imports)]
pub use run::{Clutter, CONSISTENT_FIXED_MM, CONSISTENT_FRACTION};
pub use sonar::{point_key, Beam, Draws, Listener, FAN_HALF_DEG, RAY_STEP_DEG, SPECULAR_WIDTH_DEG};
pub use timing::FiringPlan;
pub use truth::World;

use echoloc::map::MapSource;

/// How often progress is reported, in firings.
const PROGRESS_EVERY: usize = 256;

/// Simulates a run of `cfg` through `map`. `progress` is called now and then
/// with the fraction done (0 to 1). Errors name what is wrong (a map path is
/// the caller's to add).
pub fn simulate_world<M: MapSource>(
    map: &M,
    cfg: &WorldConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<SimRun, WorldError> {
    progress(0.0);
    let setup = setup::Setup::new(map, cfg)?;
    let n = setup.firings.len();
    let total = (calibrate::work(&setup) + n).max(1) as f64;
    let mut done = 0usize;
    let mut tick = || {
        done += 1;
        if done.is_multiple_of(PROGRESS_EVERY) {
            progress((done as f64 / total).min(1.0));
        }
    };
    let k = calibrate::calibrate(&setup, cfg.inconsistent, &mut tick);
    let world = World::new(&setup, k);
    let readings: Vec<SimReading> = (0..n)
        .map(|i| {
            tick();
            world.fire(&setup, i)
        })
        .collect();
    progress(1.0);
    Ok(SimRun {
        route_length_m: setup.route_length(),
        route: setup.route.clone(),
        removed_obstacles: world.removed.clone(),
        removed_until_s: world.removed_until_s,
        unmapped: world.furniture.clone(),
        unmapped_until_s: world.furniture_until_s,
        people: world.people.iter().map(|p| p.path(1.0)).collect(),
        inconsistent_fraction: truth::inconsistent_fraction(&readings),
        readings,
        clutter: world.clutter,
        cycles: setup.firings.len() / setup.plan.order.len().max(1),
        period_us: setup.plan.period_us,
        slot_us: setup.plan.slot_us,
        sound: setup.plan.module.sound(),
        duration_s: setup.traj.duration(),
        odometry_errors: setup.odometry_errors,
        heading_bias: setup.odometry_errors.heading_bias(setup.cfg.odometry.wheelbase_m),
        kidnaps: setup.traj.jumps().to_vec(),
    })
}
