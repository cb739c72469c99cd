//! What the caller asks of the simulated world, and how it can fail.

use std::fmt;

use echoloc::predict::Mount;

/// Default driving speed, m/s: a Pioneer-class robot indoors.
pub const DEFAULT_SPEED_M_S: f64 = 0.4;
/// Default clearance of the route from every true obstacle, m: the Pioneer
/// ring's radius (0.26 m) and about 0.2 m to spare.
pub const DEFAULT_CLEARANCE_M: f64 = 0.45;
/// Default turn rate in place, °/s: a Pioneer turns at up to about 100 °/s.
pub const DEFAULT_TURN_RATE_DEG_S: f64 = 90.0;
/// Default air temperature of the true world, °C: the driver's own
/// assumption (`SpeedOfSound::at_centi_celsius(2000)`), so ranges carry no
/// speed-of-sound bias unless asked to.
pub const DEFAULT_TEMPERATURE_C: f64 = 20.0;
/// Default relative humidity, %: mid-range of an indoor climate.
pub const DEFAULT_HUMIDITY_PCT: f64 = 45.0;
/// Longest route accepted, m: a whole day of driving at 0.4 m/s.
pub const MAX_DISTANCE_M: f64 = 20_000.0;
/// Most transducers on a ring (the firing plan is built for 1 to this many).
pub const MAX_TRANSDUCERS: usize = 64;

/// How far from the robot's centre a transducer may sit, each way, mm.
pub const MAX_MOUNT_MM: i32 = 2_000;

/// Whether a transducer sits within `MAX_MOUNT_MM` of the robot's centre.
pub fn within_reach(m: &Mount) -> bool {
    m.x_mm.unsigned_abs() <= MAX_MOUNT_MM as u32 && m.y_mm.unsigned_abs() <= MAX_MOUNT_MM as u32
}

/// A kidnap: at `t_s` the robot is picked up and set down `dx_m`, `dy_m`
/// away (map frame) and turned by `dtheta_rad`; the wheels do not see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kidnap {
    /// When, s from the start.
    pub t_s: f64,
    /// Carried this far along the map's x, m ...
    pub dx_m: f64,
    /// ... and y, m ...
    pub dy_m: f64,
    /// ... and turned by this, rad.
    pub dtheta_rad: f64,
}

/// The simulated world's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldConfig {
    /// Seed of every random draw: the same seed gives the same run, bit for bit.
    pub seed: u64,
    /// Length of the route to drive, m.
    pub distance_m: f64,
    /// Target fraction of readings inconsistent with the map (0..=1): the
    /// clutter is calibrated to reach it; 0 means no clutter at all.
    pub inconsistent: f64,
    /// The ring's transducers, in the robot frame.
    pub mounts: Vec<Mount>,
    /// Driving speed, m/s.
    pub speed_m_s: f64,
    /// Turn rate in place at the route's corners, °/s.
    pub turn_rate_deg_s: f64,
    /// Least distance of the route from every true obstacle, m.
    pub clearance_m: f64,
    /// True air temperature, °C (the driver converts with 20 °C whatever this is).
    pub temperature_c: f64,
    /// True relative humidity, % (air absorption).
    pub humidity_pct: f64,
    /// When BINH is raised, µs after INIT (`None`: the 6500's own 2.38 ms
    /// blanking, DESIGN §5; the STM32 board raises it at 1 000 µs).
    pub binh_after_us: Option<u32>,
    /// The wheel odometry's error model.
    pub odometry: OdometryModel,
    /// Kidnaps, in time order: after each the route goes on from where the
    /// robot was set down, for what remains of its length.
    pub kidnaps: Vec<Kidnap>,
}

impl WorldConfig {
    /// The defaults for everything but the seed, the route length, the
    /// inconsistency target and the ring.
    pub fn new(seed: u64, distance_m: f64, inconsistent: f64, mounts: Vec<Mount>) -> Self {
        Self {
            seed,
            distance_m,
            inconsistent,
            mounts,
            speed_m_s: DEFAULT_SPEED_M_S,
            turn_rate_deg_s: DEFAULT_TURN_RATE_DEG_S,
            clearance_m: DEFAULT_CLEARANCE_M,
            temperature_c: DEFAULT_TEMPERATURE_C,
            humidity_pct: DEFAULT_HUMIDITY_PCT,
            binh_after_us: None,
            odometry: OdometryModel::default(),
            kidnaps: Vec::new(),
        }
    }

    /// Checks every field; the message names the field.
    pub(super) fn check(&self) -> Result<(), WorldError> {
        let bad = |m: String| Err(WorldError::Config(m));
        if !(self.distance_m.is_finite() && self.distance_m > 0.0 && self.distance_m <= MAX_DISTANCE_M) {
            return bad(format!("distance {} m: expected more than 0 and at most {MAX_DISTANCE_M} m", self.distance_m));
        }
        if !(0.0..=1.0).contains(&self.inconsistent) {
            return bad(format!("inconsistent fraction {}: expected 0 to 1", self.inconsistent));
        }
        if self.mounts.is_empty() || self.mounts.len() > MAX_TRANSDUCERS {
            return bad(format!("{} transducers: expected 1 to {MAX_TRANSDUCERS}", self.mounts.len()));
        }
        if !self.mounts.iter().all(within_reach) {
            return bad("a transducer more than 2 m from the robot's centre".into());
        }
        if !(self.speed_m_s.is_finite() && self.speed_m_s > 0.01 && self.speed_m_s <= 3.0) {
            return bad(format!("speed {} m/s: expected 0.01 to 3 m/s", self.speed_m_s));
        }
        if !(self.turn_rate_deg_s.is_finite() && self.turn_rate_deg_s >= 5.0 && self.turn_rate_deg_s <= 720.0) {
            return bad(format!("turn rate {} °/s: expected 5 to 720 °/s", self.turn_rate_deg_s));
        }
        if !(self.clearance_m.is_finite() && self.clearance_m > 0.0 && self.clearance_m <= 5.0) {
            return bad(format!("clearance {} m: expected more than 0 and at most 5 m", self.clearance_m));
        }
        if !(-20.0..=50.0).contains(&self.temperature_c) {
            return bad(format!("temperature {} °C: expected −20 to 50 °C", self.temperature_c));
        }
        if !(0.0..=100.0).contains(&self.humidity_pct) {
            return bad(format!("humidity {} %: expected 0 to 100 %", self.humidity_pct));
        }
        let mut last = 0.0;
        for k in &self.kidnaps {
            if !(k.t_s.is_finite() && k.t_s > last) {
                return bad(format!("kidnap at {} s: times must be finite, after 0 and increasing", k.t_s));
            }
            if !(k.dx_m.is_finite() && k.dy_m.is_finite() && k.dtheta_rad.is_finite()) {
                return bad(format!("kidnap at {} s: a non-finite displacement", k.t_s));
            }
            last = k.t_s;
        }
        self.odometry.check()
    }
}

/// Wheel odometry's errors (Borenstein & Feng's UMBmark terms): each
/// systematic scale is drawn per seed, `±` a magnitude uniform in the range
/// given; the random error is per wheel, with variance proportional to the
/// distance that wheel rolled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryModel {
    /// Nominal wheelbase (track width), m. Pioneer 3-DX: about 0.33 m.
    pub wheelbase_m: f64,
    /// Range of the magnitude of the difference between the right and the
    /// left wheel radius scale (UMBmark's `E_d − 1`): Borenstein & Feng
    /// measured about 0.1–0.4 % on robots before calibration (heading drifts
    /// by `E_d − 1` over the wheelbase per metre: 0.2 % on 0.33 m is 0.35°/m).
    pub wheel_diff: (f64, f64),
    /// Largest magnitude of the common wheel radius scale error (both wheels
    /// read long or short): tyre pressure, load.
    pub wheel_common: f64,
    /// Range of the magnitude of the wheelbase scale error (UMBmark's
    /// `E_b − 1`): the contact patch is wide; a few per mille to 1 %.
    pub wheelbase_scale: (f64, f64),
    /// Random wheel distance error, m per √m rolled (standard deviation):
    /// slip and encoder quantisation.
    pub noise_m_per_sqrt_m: f64,
}

impl Default for OdometryModel {
    fn default() -> Self {
        Self {
            wheelbase_m: 0.33,
            wheel_diff: (0.0005, 0.002),
            wheel_common: 0.005,
            wheelbase_scale: (0.002, 0.01),
            noise_m_per_sqrt_m: 0.001,
        }
    }
}

impl OdometryModel {
    /// A robot after UMBmark's calibration: Borenstein and Feng's
    /// correction cut the systematic errors by about an order of magnitude,
    /// so a tenth of [`OdometryModel::default`]'s (the wheels' difference
    /// 0.005–0.02 %, the wheelbase 0.02–0.1 %, the common scale ±0.1 %);
    /// the random slip is the same. The lidar runs' derived sonar uses it
    /// (issue #35: "odometry with a calibrated robot's errors").
    pub fn calibrated() -> Self {
        Self { wheel_diff: (0.00005, 0.0002), wheel_common: 0.001, wheelbase_scale: (0.0002, 0.001), ..Self::default() }
    }

    fn check(&self) -> Result<(), WorldError> {
        let ok_range = |(a, b): (f64, f64)| a.is_finite() && b.is_finite() && 0.0 <= a && a <= b && b < 0.2;
        let ok = self.wheelbase_m.is_finite()
            && self.wheelbase_m > 0.05
            && self.wheelbase_m < 5.0
            && ok_range(self.wheel_diff)
            && ok_range(self.wheelbase_scale)
            && (0.0..0.2).contains(&self.wheel_common)
            && (0.0..0.2).contains(&self.noise_m_per_sqrt_m);
        if ok {
            Ok(())
        } else {
            Err(WorldError::Config(format!("odometry model {self:?}: a wheelbase of 0.05–5 m and errors below 20 %")))
        }
    }
}

/// Why the world could not be simulated.
#[derive(Clone, Debug, PartialEq)]
pub enum WorldError {
    /// A setting is out of range; the message names it.
    Config(String),
    /// The map has no piece at all.
    EmptyMap,
    /// No free region can hold the route's clearance.
    NoFreeSpace {
        /// The clearance asked for, m.
        clearance_m: f64,
    },
    /// The free region that holds the clearance is too small to drive in.
    TooSmall {
        /// The clearance asked for, m.
        clearance_m: f64,
        /// The region's extent (its bounding box's diagonal), m.
        extent_m: f64,
    },
    /// The map is too large for the simulator's 5 cm grid.
    TooLarge {
        /// The map's width, m.
        width_m: f64,
        /// The map's height, m.
        height_m: f64,
    },
    /// The firing schedule could not be derived from the driver's settings.
    Timing(String),
    /// A kidnap that cannot happen: after the run, or setting the robot
    /// down where the route cannot go on.
    Kidnap(String),
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WorldError::Config(m) => write!(f, "simulation settings: {m}"),
            WorldError::EmptyMap => write!(f, "the map has no obstacles: nothing to drive through"),
            WorldError::NoFreeSpace { clearance_m } => {
                write!(f, "no free space with {clearance_m} m clearance in the map")
            }
            WorldError::TooSmall { clearance_m, extent_m } => write!(
                f,
                "the free space with {clearance_m} m clearance in the map spans only {extent_m:.2} m: too small to drive a route"
            ),
            WorldError::TooLarge { width_m, height_m } => write!(
                f,
                "the map spans {width_m:.0} m x {height_m:.0} m: more than the simulator's grid holds ({} cells of 5 cm)",
                super::grid::MAX_CELLS
            ),
            WorldError::Timing(m) => write!(f, "sonar timing: {m}"),
            WorldError::Kidnap(m) => write!(f, "kidnap: {m}"),
        }
    }
}

impl std::error::Error for WorldError {}
