//! A sonar run on real geometry: the ring's readings derived from a lidar
//! robot's own run (`echoloc-lab simulate --from-scans RUN --map MAP`,
//! issue #35, DESIGN §4.9). The laser's returns are the reflectors
//! ([`surfaces`]); the ring fires along the robot's path between the scans
//! ([`path`]) and hears them through the simulator's sonar physics
//! ([`sonar`]); the odometry comes from the path through the simulator's
//! error model; the scans' poses (SLAM-corrected) are the reference. The
//! derivation never reads the map it is checked against (§4.7): the map
//! is read only by the filters, and by the ladder's control rungs that say
//! so.
//!
//! It is a sonar run on real geometry and real clutter, optimistic on
//! physics: glass the laser sees through, table tops below its plane and
//! the beam's vertical spread are not heard. It is also a product: *would
//! a sonar ring localize in my building? Record one lidar run and ask.*
//!
//! The ladder ([`Readings`]): where the readings come from, from the
//! map's own prediction to the whole laser.

pub mod cli;
pub mod cone;
pub mod harsh;
pub mod path;
pub mod sonar;
pub mod surfaces;

use clap::ValueEnum;
use echoloc::credence::net::CredenceNet;
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{predict_mount, Mount, Pose};
use echoloc::referencing::{judge, Reading, Verdict, VerdictConfig};
use echoloc::scenario::Header;
use serde_json::{json, Value};

use crate::credence::rng::Rng;
use crate::credence::synth::LEVEL_AT_1M_DB;
use crate::lidar::{LidarRun, Scan};
use crate::map::ros::{Cell, Grid};
use crate::simulate::filters::{self, predict_params, Start, Trace};
use crate::simulate::world::{
    wrap, Beam, EchoKind, EchoSource, FiringPlan, Odometry, OdometryErrors, OdometryModel, SimReading, WorldConfig,
};
use harsh::{Harsh, Posts};
use path::RunPath;
use surfaces::Surfaces;

/// Where the ring's readings come from: the ladder of issue #35, from the
/// map's own prediction down to everything the laser saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Readings {
    /// echoloc's own prediction at the true pose on the map, 1 % noise: the
    /// control (it reads the map, by design).
    Predicted,
    /// The sonar physics on the map's own occupied cells (a laser cast on
    /// the grid from the path): no clutter, only the map's shape (reads the
    /// map, by design).
    Map,
    /// The laser's returns within 10 cm of an occupied cell of the map:
    /// real surfaces where the map has walls, no clutter.
    MappedLaser,
    /// Every laser return: people, chairs, what the map lacks.
    Laser,
}

impl Readings {
    /// The ladder in order.
    pub const ALL: [Readings; 4] = [Readings::Predicted, Readings::Map, Readings::MappedLaser, Readings::Laser];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Readings::Predicted => "predicted",
            Readings::Map => "map",
            Readings::MappedLaser => "mapped-laser",
            Readings::Laser => "laser",
        }
    }

    fn needs_grid(self) -> bool {
        matches!(self, Readings::Map | Readings::MappedLaser)
    }
}

/// When the ring fires.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Fire {
    /// On the driver's own schedule (a cycle every 0.6 s) along the path
    /// between the scans.
    AlongPath,
    /// The whole ring at each scan's pose and time, as a logger that keeps
    /// one record per 0.5–1 m writes it (issue #35's real logs).
    AtScans,
}

/// What becomes of a transducer the laser did not cover.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Uncovered {
    /// Left out of the run (the default: nothing is known of what it would hear).
    Drop,
    /// Kept with what its seen rays heard (unseen space taken as empty).
    Keep,
}

/// How the ring's readings are derived.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeriveOptions {
    /// Seed of every draw.
    pub seed: u64,
    /// When the ring fires.
    pub fire: Fire,
    /// The widest incidence at which a smooth face is heard at 1 m, degrees
    /// (DESIGN §4.9: about ±10°, narrowing with range).
    pub face_heard_at_1m_deg: f64,
    /// Transducers the laser did not cover.
    pub uncovered: Uncovered,
    /// The wheel odometry's errors.
    pub odometry: OdometryModel,
    /// Two-bounce echoes (a face mirrors the ping onto another).
    pub multipath: bool,
    /// How much harsher than DESIGN §4.9's sonar ([`harsh`]).
    pub harsh: Harsh,
}

impl Default for DeriveOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            fire: Fire::AlongPath,
            face_heard_at_1m_deg: FACE_HEARD_AT_1M_DEG,
            uncovered: Uncovered::Drop,
            odometry: OdometryModel::calibrated(),
            multipath: true,
            harsh: Harsh::NOMINAL,
        }
    }
}

/// A Polaroid hears a smooth face at 1 m only within about this incidence,
/// degrees (DESIGN §4.9, after Kuc and Siegel): narrower than the
/// simulator's rougher faces (`world::SPECULAR_WIDTH_DEG`, heard to about
/// 30°), since a painted wall is a mirror at 7 mm.
pub const FACE_HEARD_AT_1M_DEG: f64 = 10.0;

/// A laser return this close to an occupied cell is on a mapped wall, m.
pub const MAPPED_WITHIN_M: f64 = 0.1;
/// The predicted rung's noise: a fraction of the range (standard deviation).
pub const PREDICTED_NOISE: f64 = 0.01;
/// The map rung's laser: beams over the whole turn, degrees apart.
const GRID_SCAN_STEP_DEG: f64 = 0.5;
/// ... cast from the path every so far, m, or so much turn, degrees.
const GRID_SCAN_EVERY_M: f64 = 0.25;
const GRID_SCAN_EVERY_DEG: f64 = 15.0;
/// ... as far as, m.
const GRID_SCAN_RANGE_M: f64 = 8.0;
/// Sub-streams of the derivation's draws (the simulator's firings use 1 << 40 and up).
const STREAM_ODOMETRY_ERRORS: u64 = 0x5C_0001;
const STREAM_ODOMETRY_NOISE: u64 = 0x5C_0002;
const STREAM_PREDICTED_NOISE: u64 = 0x5C_0003;

/// A run derived from scans.
pub struct Derived {
    /// Every firing along the path (covered or not), in firing order.
    pub readings: Vec<SimReading>,
    /// Per firing: whether the scans covered its main lobe.
    pub covered: Vec<bool>,
    /// What becomes of the others.
    pub uncovered: Uncovered,
    /// The path.
    pub path: RunPath,
    /// The driver's plan.
    pub plan: FiringPlan,
    /// Scans (or grid casts) the readings were heard off.
    pub surfaces: usize,
    /// The speed of sound of the run.
    pub sound: echoloc::driver::SpeedOfSound,
}

impl Derived {
    /// The readings that are kept (covered, or all with [`Uncovered::Keep`]).
    pub fn kept(&self) -> Vec<SimReading> {
        let all = self.uncovered == Uncovered::Keep;
        self.readings.iter().zip(&self.covered).filter(|(_, &c)| c || all).map(|(r, _)| r.clone()).collect()
    }
}

/// What the derivation reads beside the scans: the map for the control
/// rungs (`view` for `predicted`, `grid` for `map` and `mapped-laser`).
pub struct MapInputs<'a> {
    pub view: &'a MapView<'a>,
    pub grid: Option<&'a Grid>,
}

/// Derives the ring's readings of `rung` along `run` with `mounts`, seeded `seed`.
pub fn derive(
    run: &LidarRun,
    rung: Readings,
    map: &MapInputs<'_>,
    mounts: &[Mount],
    opt: &DeriveOptions,
) -> Result<Derived, String> {
    let seed = opt.seed;
    if !(opt.face_heard_at_1m_deg > 0.0 && opt.face_heard_at_1m_deg <= 60.0) {
        return Err(format!("--heard-face-deg {}: expected more than 0 and at most 60", opt.face_heard_at_1m_deg));
    }
    opt.harsh.check()?;
    if run.scans.len() < 2 {
        return Err("a run needs at least two scans".into());
    }
    if rung.needs_grid() && map.grid.is_none() {
        return Err(format!(
            "--readings {}: needs the map's occupancy grid (a ROS map_server .yaml as --map)",
            rung.name()
        ));
    }
    let cfg = WorldConfig { odometry: opt.odometry, ..WorldConfig::new(seed, 1.0, 0.0, mounts.to_vec()) };
    let path = path::through(&run.scans);
    let plan = FiringPlan::new(mounts.len(), cfg.binh_after_us).map_err(|e| e.to_string())?;
    let unit = Beam::new(cfg.temperature_c, cfg.humidity_pct);
    let per_width = unit.widest_heard_deg(LEVEL_AT_1M_DB) / crate::simulate::world::SPECULAR_WIDTH_DEG;
    let beam = unit.with_specular_width(opt.face_heard_at_1m_deg / per_width);
    let errors = OdometryErrors::draw(&cfg.odometry, &mut Rng::substream(seed, STREAM_ODOMETRY_ERRORS));
    let odometry =
        Odometry::integrate(&path.traj, &cfg.odometry, &errors, &mut Rng::substream(seed, STREAM_ODOMETRY_NOISE));
    let surfaces: Vec<Surfaces> = match rung {
        Readings::Predicted => Vec::new(),
        Readings::Laser => laser_surfaces(run, &path, &|_| true),
        Readings::MappedLaser => {
            let near = near_occupied(map.grid.ok_or("no grid")?, MAPPED_WITHIN_M);
            laser_surfaces(run, &path, &|p| near(p))
        }
        Readings::Map => grid_surfaces(map.grid.ok_or("no grid")?, &path),
    };
    let mounts_m: Vec<(f64, f64, f64)> = mounts
        .iter()
        .map(|m| {
            (f64::from(m.x_mm) / 1000.0, f64::from(m.y_mm) / 1000.0, (f64::from(m.heading_mdeg) / 1000.0).to_radians())
        })
        .collect();
    let duration = path.traj.duration();
    let firings: Vec<(u32, usize, f64)> = match opt.fire {
        Fire::AlongPath => {
            let cycles = ((duration * 1e6) / f64::from(plan.period_us)).floor().max(1.0) as u32;
            (0..cycles)
                .flat_map(|c| (0..plan.order.len()).map(move |s| (c, s, 0.0)))
                .map(|(c, s, _)| (c, s, plan.fire_us(c, s) as f64 * 1e-6))
                .collect()
        }
        Fire::AtScans => path
            .scan_times
            .iter()
            .enumerate()
            .flat_map(|(c, &t)| (0..plan.order.len()).map(move |s| (c as u32, s, t)))
            .collect(),
    };
    let posts = if rung == Readings::Laser {
        let path_m: f64 =
            run.scans.windows(2).map(|w| (w[1].robot[0] - w[0].robot[0]).hypot(w[1].robot[1] - w[0].robot[1])).sum();
        Posts::place(&run.scans, path_m, opt.harsh.furniture_per_m, seed)
    } else {
        Posts::none()
    };
    let ears = sonar::Ears {
        surfaces: &surfaces,
        beam: &beam,
        plan: &plan,
        seed,
        multipath: opt.multipath,
        harsh: opt.harsh,
        posts: &posts,
    };
    let origin_of = |tr: usize, (x, y, h): (f64, f64, f64)| {
        let m = mounts_m[tr];
        ((x + h.cos() * m.0 - h.sin() * m.1, y + h.sin() * m.0 + h.cos() * m.1), h + m.2)
    };
    let net = CredenceNet::shipped();
    let params = predict_params(map.view.buffer_mm(), map.view.field());
    let sound = plan.module.sound();
    // A neighbour fired with firing `index` at `t` (harsh): the time, µs, at
    // which its echo off what its own axis met reaches the listener at `o`.
    let crosstalk = |index: u64, t: f64, tr: usize, pose: (f64, f64, f64), o: surfaces::P| -> Option<u32> {
        let n = mounts_m.len();
        if opt.harsh.crosstalk <= 0.0 || n < 2 {
            return None;
        }
        let mut rng = Rng::substream(seed, harsh::STREAM_CROSSTALK.wrapping_add(index << 8));
        if rng.next_f64() >= opt.harsh.crosstalk {
            return None;
        }
        let j = if rng.next_f64() < 0.5 { (tr + 1) % n } else { (tr + n - 1) % n };
        let (o_j, axis_j) = origin_of(j, pose);
        // The neighbour's own ping: its own draws (a sub-stream no firing uses).
        let heard = ears.ping(index | 1 << 62, t, o_j, axis_j);
        let r_j = f64::from(heard.echo_us?) * 1e-6 * beam.c / 2.0;
        let us = (2.0 * harsh::crosstalk_range_m(o, o_j, axis_j, r_j) / beam.c * 1e6).floor();
        (us >= f64::from(plan.min_echo_us()) && us <= f64::from(plan.window_us())).then_some(us as u32)
    };
    let one = |k: usize| -> Result<(SimReading, bool), String> {
        let (c, s, t) = firings[k];
        let tr = plan.order[s];
        let (x, y, h) = path.traj.pose(t);
        let (o, axis) = origin_of(usize::from(tr), (x, y, h));
        let (echo_us, source, covered) = if rung == Readings::Predicted {
            let pose = Pose { x_mm: (x * 1000.0) as f32, y_mm: (y * 1000.0) as f32, heading_rad: h as f32 };
            let (p, _) = predict_mount(map.view, &pose, &mounts[usize::from(tr)], &params, &net)
                .map_err(|e| format!("{e:?}"))?;
            let mut rng = Rng::substream(seed, STREAM_PREDICTED_NOISE.wrapping_add((k as u64) << 8));
            let us = p.map(|p| {
                let r = f64::from(p.range_mm) * (1.0 + PREDICTED_NOISE * rng.normal());
                sound.tof_us(r.round().max(1.0) as u32)
            });
            let src = if us.is_some() { EchoSource::World { kind: EchoKind::Face } } else { EchoSource::None };
            (us.filter(|&u| u >= plan.min_echo_us() && u <= plan.window_us()), src, 1.0)
        } else {
            let p = ears.ping(k as u64, t, o, axis);
            let cross = crosstalk(k as u64, t, usize::from(tr), (x, y, h), o);
            match (p.echo_us, cross) {
                (Some(e), Some(c)) if c < e => (Some(c), EchoSource::Crosstalk, p.covered),
                (None, Some(c)) => (Some(c), EchoSource::Crosstalk, p.covered),
                _ => (p.echo_us, p.source, p.covered),
            }
        };
        let odo = odometry.pose(t);
        Ok((
            SimReading {
                cycle: c,
                slot: s as u8,
                transducer: tr,
                time_s: t,
                truth: (x, y, wrap(h)),
                odometry: (odo.0, odo.1, wrap(odo.2)),
                echo_us,
                range_mm: echo_us.map(|u| plan.range_mm(u)),
                source,
                map_only_range_mm: None,
                consistent: false,
            },
            covered >= sonar::MIN_COVERED,
        ))
    };
    // Firings are independent (each draws from its own sub-stream): two threads, the same result.
    let n = firings.len();
    let half = n / 2;
    let (a, b) = std::thread::scope(|sc| {
        let h = sc.spawn(|| (half..n).map(one).collect::<Result<Vec<_>, String>>());
        let a = (0..half).map(one).collect::<Result<Vec<_>, String>>();
        (a, h.join().unwrap_or_else(|_| Err("internal error: a derivation thread panicked".into())))
    });
    let (mut readings, mut covered) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for (r, c) in a?.into_iter().chain(b?) {
        readings.push(r);
        covered.push(c);
    }
    Ok(Derived { readings, covered, uncovered: opt.uncovered, path, plan, surfaces: surfaces.len(), sound })
}

/// The laser scans as surfaces, each at its time on the path, with the returns `keep` takes.
fn laser_surfaces(run: &LidarRun, path: &RunPath, keep: &(dyn Fn((f64, f64)) -> bool + Sync)) -> Vec<Surfaces> {
    let mut v: Vec<Surfaces> = run
        .scans
        .iter()
        .zip(&path.scan_times)
        .enumerate()
        .map(|(i, (s, &t))| Surfaces::of_scan(s, t, 0x5CA4_0000_0000 | i as u64, keep))
        .collect();
    v.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    v
}

/// Whether a point lies within `within` m of an occupied cell of `g`.
fn near_occupied(g: &Grid, within: f64) -> impl Fn((f64, f64)) -> bool + Sync + '_ {
    let res = g.yaml.resolution;
    let k = (within / res).ceil() as i64;
    let (w, h) = (g.width as i64, g.height as i64);
    let mut near = vec![false; g.width * g.height];
    for r in 0..h {
        for c in 0..w {
            if g.cells[(r * w + c) as usize] != Cell::Occupied {
                continue;
            }
            for dr in -k..=k {
                for dc in -k..=k {
                    let (rr, cc) = (r + dr, c + dc);
                    if rr >= 0
                        && cc >= 0
                        && rr < h
                        && cc < w
                        && ((dr * dr + dc * dc) as f64).sqrt() * res <= within + res
                    {
                        near[(rr * w + cc) as usize] = true;
                    }
                }
            }
        }
    }
    move |p: (f64, f64)| {
        let c = ((p.0 - g.yaml.origin[0]) / res).floor();
        // Image row 0 is the top (the largest y).
        let r = ((p.1 - g.yaml.origin[1]) / res).floor();
        c >= 0.0 && r >= 0.0 && c < w as f64 && r < h as f64 && near[((h - 1 - r as i64) * w + c as i64) as usize]
    }
}

/// The map rung's scans: a laser over the whole turn cast on the grid's
/// occupied cells from the path, every [`GRID_SCAN_EVERY_M`].
fn grid_surfaces(g: &Grid, path: &RunPath) -> Vec<Surfaces> {
    let dur = path.traj.duration();
    let mut times = vec![0.0];
    let mut last = path.traj.pose(0.0);
    let mut t = 0.0;
    while t < dur {
        t = (t + 0.05).min(dur);
        let p = path.traj.pose(t);
        if (p.0 - last.0).hypot(p.1 - last.1) >= GRID_SCAN_EVERY_M
            || (p.2 - last.2).abs().to_degrees() >= GRID_SCAN_EVERY_DEG
        {
            times.push(t);
            last = p;
        }
    }
    let n = (360.0 / GRID_SCAN_STEP_DEG).round() as usize;
    let step = GRID_SCAN_STEP_DEG.to_radians();
    times
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let (x, y, _) = path.traj.pose(t);
            let ranges = (0..n)
                .map(|i| {
                    let a = -std::f64::consts::PI + i as f64 * step;
                    grid_cast(g, (x, y), (a.cos(), a.sin()), GRID_SCAN_RANGE_M).map_or(f32::INFINITY, |r| r as f32)
                })
                .collect();
            let scan = Scan {
                time_s: t,
                robot: [x, y, 0.0],
                laser: [x, y, 0.0],
                odometry: None,
                angle_min: -std::f64::consts::PI,
                angle_step: step,
                ranges,
                line: k as u64,
            };
            Surfaces::of_scan(&scan, t, 0x6A1D_0000_0000 | k as u64, &|_| true)
        })
        .collect()
}

/// Where the ray from `o` along unit `d` enters the first occupied cell of
/// `g` within `max` m (Amanatides and Woo's walk): the cell's face.
pub fn grid_cast(g: &Grid, o: (f64, f64), d: (f64, f64), max: f64) -> Option<f64> {
    let res = g.yaml.resolution;
    let (fx, fy) = ((o.0 - g.yaml.origin[0]) / res, (o.1 - g.yaml.origin[1]) / res);
    let (mut c, mut r) = (fx.floor() as i64, fy.floor() as i64);
    let (sx, sy) = (if d.0 >= 0.0 { 1 } else { -1 }, if d.1 >= 0.0 { 1 } else { -1 });
    let next = |f: f64, cell: i64, s: i64, dd: f64| {
        if dd == 0.0 {
            f64::INFINITY
        } else {
            ((if s > 0 { (cell + 1) as f64 } else { cell as f64 }) - f) / dd * res
        }
    };
    let (mut tx, mut ty) = (next(fx, c, sx, d.0), next(fy, r, sy, d.1));
    let (dtx, dty) = (
        if d.0 == 0.0 { f64::INFINITY } else { res / d.0.abs() },
        if d.1 == 0.0 { f64::INFINITY } else { res / d.1.abs() },
    );
    let (w, h) = (g.width as i64, g.height as i64);
    let mut t = 0.0;
    while t <= max {
        if c >= 0 && r >= 0 && c < w && r < h {
            if g.cells[((h - 1 - r) * w + c) as usize] == Cell::Occupied {
                return Some(t);
            }
        } else if t > 0.0 {
            return None;
        }
        if tx < ty {
            t = tx;
            tx += dtx;
            c += sx;
        } else {
            t = ty;
            ty += dty;
            r += sy;
        }
    }
    None
}

/// The filters on a derivation: the kept readings as the scenario's
/// records, from the first true pose, with what `how` sets on that start
/// (the seed, the start the user gave, the filters' switches).
pub fn run_filters<M: MapSource>(
    d: &Derived,
    map: &M,
    field: &echoloc::map::FieldView<'_>,
    mounts: &[Mount],
    map_crc: u32,
    how: impl FnOnce(&mut Start),
) -> Result<(Trace, Vec<filters::Step>, Vec<SimReading>), String> {
    let kept = d.kept();
    let records = crate::simulate::report::to_records(&kept).map_err(|e| e.0)?;
    let first = records.first().map_or([0.0; 3], |r| r.truth);
    let header = Header {
        map_crc,
        speed_um_per_s: d.sound.um_per_s(),
        period_us: d.plan.period_us,
        slot_us: d.plan.slot_us,
        start: first,
        start_sigma: crate::simulate::report::START_SIGMA,
        bound_position_m: 0.15,
        bound_heading_deg: 2.0,
    };
    let steps = filters::steps_of_records(&header, &records)?;
    let mut start = crate::simulate::report::start_of(&header);
    how(&mut start);
    let trace = filters::run(map, field, mounts, &start, &steps, &mut |_| {})?;
    Ok((trace, steps, kept))
}

/// What the readings say against the map at the true pose: the fraction
/// confirmed, and the median (reading − prediction) where they nearly
/// agree (within 0.3 m) — the map's offset from the surfaces. With `csv`,
/// one row per reading for a user's own tools (`--at-truth-csv`).
pub fn at_truth(map: &MapView<'_>, mounts: &[Mount], kept: &[SimReading], mut csv: Option<&mut String>) -> Value {
    let net = CredenceNet::shipped();
    let params = predict_params(map.buffer_mm(), map.field());
    let (mut n, mut confirmed, mut echoes) = (0usize, 0usize, 0usize);
    let mut near: Vec<f64> = Vec::new();
    if let Some(c) = csv.as_deref_mut() {
        c.push_str("time_s,transducer,range_mm,predicted_mm,kappa,theta_deg,delta_deg,tolerance_mm,case,source\n");
    }
    for r in kept {
        let Some(m) = mounts.get(usize::from(r.transducer)) else { continue };
        let pose = echoloc::referencing::pose_mm([r.truth.0 as f32, r.truth.1 as f32, r.truth.2 as f32]);
        let Ok((p, _)) = predict_mount(map, &pose, m, &params, &net) else { continue };
        let reading = r.range_mm.map_or(Reading::NoEcho, |range_mm| Reading::Echo { range_mm });
        n += 1;
        if let Some(c) = csv.as_deref_mut() {
            let opt = |v: Option<String>| v.unwrap_or_default();
            let source = match r.source {
                EchoSource::World { kind: EchoKind::Face } => "face",
                EchoSource::World { kind: EchoKind::InsideCorner } => "inside_corner",
                EchoSource::World { kind: EchoKind::OutsideEdge } => "outside_edge",
                EchoSource::Crosstalk => "crosstalk",
                EchoSource::Noise => "noise",
                EchoSource::None => "none",
                _ => "other",
            };
            c.push_str(&format!(
                "{:.6},{},{},{},{},{},{},{},{},{source}\n",
                r.time_s,
                r.transducer,
                opt(r.range_mm.map(|v| v.to_string())),
                opt(p.map(|p| p.range_mm.to_string())),
                opt(p.map(|p| format!("{:.4}", p.kappa.to_num::<f64>()))),
                opt(p.map(|p| format!("{:.3}", f64::from(p.theta_mdeg) / 1000.0))),
                opt(p.map(|p| format!("{:.3}", f64::from(p.delta_mdeg) / 1000.0))),
                opt(p.map(|p| p.tolerance_mm.to_string())),
                opt(p.map(|p| format!("{:?}", p.case))),
            ));
        }
        if judge(reading, p.as_ref(), &VerdictConfig::POLAROID) == Verdict::Confirmed {
            confirmed += 1;
        }
        if let (Some(obs), Some(p)) = (r.range_mm, p) {
            echoes += 1;
            let res = f64::from(obs) - f64::from(p.range_mm);
            if res.abs() < 300.0 {
                near.push(res);
            }
        }
    }
    near.sort_by(f64::total_cmp);
    json!({
        "readings": n,
        "confirmed_fraction": if n == 0 { Value::Null } else { json!(round4(confirmed as f64 / n as f64)) },
        "echoes_with_prediction": echoes,
        "near_agreement": near.len(),
        "median_offset_mm": near.get(near.len() / 2).copied(),
    })
}

/// The fraction of the path's firings whose robot stands on the map's
/// known-free cells: how much of the run the map covers.
pub fn map_covers(g: &Grid, readings: &[SimReading]) -> f64 {
    let res = g.yaml.resolution;
    let (w, h) = (g.width as f64, g.height as f64);
    let on = readings
        .iter()
        .filter(|r| {
            let c = ((r.truth.0 - g.yaml.origin[0]) / res).floor();
            let row = ((r.truth.1 - g.yaml.origin[1]) / res).floor();
            c >= 0.0 && row >= 0.0 && c < w && row < h && g.at(c as usize, (h - 1.0 - row) as usize) == Cell::Free
        })
        .count();
    on as f64 / readings.len().max(1) as f64
}

/// The derivation's own figures for the report.
pub fn summary(d: &Derived, run: &LidarRun, rung: Readings) -> Value {
    let n = d.readings.len();
    let covered = d.covered.iter().filter(|&&c| c).count();
    let all = d.uncovered == Uncovered::Keep;
    let kept = if all { n } else { covered };
    let mut kinds = [0usize; 5];
    for (r, _) in d.readings.iter().zip(&d.covered).filter(|(_, &c)| c || all) {
        let k = match r.source {
            EchoSource::World { kind: EchoKind::Face } => 0,
            EchoSource::World { kind: EchoKind::InsideCorner } => 1,
            EchoSource::World { kind: EchoKind::OutsideEdge } => 2,
            EchoSource::None => 4,
            _ => 3,
        };
        kinds[k] += 1;
    }
    json!({
        "readings_from": rung.name(),
        "format": run.format,
        "pass": format!("{}:{}", run.first_index, run.first_index + run.scans.len()),
        "scans": run.scans.len(),
        "path_m": round4(run.path_length_m()),
        "duration_s": round4(d.path.traj.duration()),
        "retimed_steps": d.path.retimed,
        "turn_drive_turn_steps": d.path.turn_drive_turn,
        "surfaces": d.surfaces,
        "firings": n,
        "covered": covered,
        "covered_fraction": round4(covered as f64 / n.max(1) as f64),
        "kept": kept,
        "echoes": {"face": kinds[0], "inside_corner": kinds[1], "outside_edge": kinds[2], "crosstalk_or_noise": kinds[3], "none": kinds[4]},
    })
}

fn round4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::ros::{MapYaml, Mode};

    #[test]
    fn grid_cast_meets_the_first_occupied_cell_as_a_brute_force_does() {
        // 5 cm cells, origin (−1, −1), a scatter of occupied cells.
        let (w, h) = (60usize, 50usize);
        let mut cells = vec![Cell::Free; w * h];
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..120 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            cells[(x % (w * h) as u64) as usize] = Cell::Occupied;
        }
        let yaml = MapYaml {
            image: "x.pgm".into(),
            resolution: 0.05,
            origin: [-1.0, -1.0, 0.0],
            negate: false,
            occupied_thresh: 0.65,
            free_thresh: 0.196,
            mode: Mode::Trinary,
        };
        let g = Grid { width: w, height: h, cells, yaml };
        let occupied = |p: (f64, f64)| {
            let c = ((p.0 + 1.0) / 0.05).floor();
            let r = ((p.1 + 1.0) / 0.05).floor();
            c >= 0.0
                && r >= 0.0
                && c < w as f64
                && r < h as f64
                && g.at(c as usize, h - 1 - r as usize) == Cell::Occupied
        };
        let o = (0.512, 0.237);
        if occupied(o) {
            return;
        }
        for k in 0..360 {
            let a = f64::from(k).to_radians() + 0.001;
            let d = (a.cos(), a.sin());
            // The brute force: 0.1 mm steps.
            let mut brute = None;
            let mut t = 0.0;
            while t <= 3.0 {
                if occupied((o.0 + d.0 * t, o.1 + d.1 * t)) {
                    brute = Some(t);
                    break;
                }
                t += 1e-4;
            }
            let got = grid_cast(&g, o, d, 3.0);
            match (got, brute) {
                (Some(a), Some(b)) => assert!((a - b).abs() < 2e-4, "{k}°: {a} against {b}"),
                (None, None) => {}
                _ => panic!("{k}°: {got:?} against {brute:?}"),
            }
        }
    }
}
