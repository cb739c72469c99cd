//! What a simulated run hands back.

use echoloc::driver::SpeedOfSound;

use super::geom::P;
use super::motion::OdometryErrors;

/// What really made a reading's echo.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EchoSource {
    /// A mapped obstacle present in the true world (a face, inside corner or edge of it).
    Mapped {
        /// The map obstacle's index.
        obstacle: u16,
        /// What part of it echoed.
        kind: EchoKind,
    },
    /// Something not in the map: furniture moved in, or a person.
    Unmapped,
    /// A surface of a real building, seen by a lidar run's laser
    /// (`crate::from_scans`): mapped or not is for the map to say.
    World {
        /// What part of it echoed.
        kind: EchoKind,
    },
    /// Another transducer's ping.
    Crosstalk,
    /// A false echo (electrical or acoustic noise).
    Noise,
    /// No echo within the listening window.
    None,
}

/// What part of a mapped obstacle echoed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EchoKind {
    /// A face, by (near-)specular reflection.
    Face,
    /// An inside corner, by retro-reflection.
    InsideCorner,
    /// An outside edge, by diffraction.
    OutsideEdge,
}

/// One firing of one transducer.
#[derive(Clone, Debug, PartialEq)]
pub struct SimReading {
    /// Firing cycle, from 0.
    pub cycle: u32,
    /// Slot within the cycle.
    pub slot: u8,
    /// The transducer fired (index into the ring's mounts).
    pub transducer: u8,
    /// Firing time, s from the run's start.
    pub time_s: f64,
    /// True robot pose at firing: x, y (m), heading (rad, −π..π).
    pub truth: (f64, f64, f64),
    /// Wheel odometry pose at firing as the robot logs it (equal to the truth at t = 0).
    pub odometry: (f64, f64, f64),
    /// Round-trip time of the first detected echo as the driver's µs clock
    /// counts it; `None`: no echo within the listening window.
    pub echo_us: Option<u32>,
    /// `echo_us` as the driver converts it (`SpeedOfSound::range_mm`, 20 °C).
    pub range_mm: Option<u32>,
    /// What made the echo.
    pub source: EchoSource,
    /// What the same transducer would read, with the same random draws, in
    /// the world of the map alone (nothing removed, nothing added), mm.
    pub map_only_range_mm: Option<u32>,
    /// Whether the reading agrees with `map_only_range_mm` (within
    /// [`CONSISTENT_FIXED_MM`] + [`CONSISTENT_FRACTION`] of it), or both are `None`.
    pub consistent: bool,
}

/// Readings agree within this many mm plus [`CONSISTENT_FRACTION`] of the map-only range.
pub const CONSISTENT_FIXED_MM: f64 = 30.0;
/// Proportional part of the agreement tolerance.
pub const CONSISTENT_FRACTION: f64 = 0.01;

/// Whether a reading agrees with the map-only reading.
pub fn consistent(reading: Option<u32>, map_only: Option<u32>) -> bool {
    match (reading, map_only) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            (f64::from(a) - f64::from(b)).abs() <= CONSISTENT_FIXED_MM + CONSISTENT_FRACTION * f64::from(b)
        }
        _ => false,
    }
}

/// How much clutter the run has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clutter {
    /// The calibrated density knob, 0..=1 (0: none).
    pub density: f64,
    /// Map obstacles removed from the truth.
    pub removed: usize,
    /// Pieces of furniture moved in.
    pub furniture: usize,
    /// People walking about.
    pub people: usize,
}

/// A whole simulated run.
#[derive(Clone, Debug, PartialEq)]
pub struct SimRun {
    /// The planned route, m (the robot drives it exactly, turning in place at each point).
    pub route: Vec<P>,
    /// Its length, m.
    pub route_length_m: f64,
    /// Map obstacle indices absent in the truth, ascending (all the run long
    /// but for `removed_until_s`).
    pub removed_obstacles: Vec<u16>,
    /// The one removed obstacle that is absent only from the start until this
    /// time, s (the density's fractional part).
    pub removed_until_s: Option<(u16, f64)>,
    /// Outlines of the furniture moved in, m (closed rectangles, counter-clockwise).
    pub unmapped: Vec<Vec<P>>,
    /// The one piece of furniture (index into `unmapped`) in place only from
    /// the start until this time, s.
    pub unmapped_until_s: Option<(usize, f64)>,
    /// Each person's path, m, sampled once a second while the person is there.
    pub people: Vec<Vec<P>>,
    /// Every reading, in firing order.
    pub readings: Vec<SimReading>,
    /// Achieved fraction of readings not [`consistent`](SimReading::consistent).
    pub inconsistent_fraction: f64,
    /// The clutter that achieved it.
    pub clutter: Clutter,
    /// Firing cycles run.
    pub cycles: usize,
    /// One cycle, µs (the driver's ring timing).
    pub period_us: u32,
    /// One slot of the cycle (listening window, ring-down gap, late limit), µs.
    pub slot_us: u32,
    /// The speed of sound the driver converts echo times with.
    pub sound: SpeedOfSound,
    /// Duration of the drive, s.
    pub duration_s: f64,
    /// The systematic odometry errors drawn for this run.
    pub odometry_errors: OdometryErrors,
    /// The heading corrections they call for ([`OdometryErrors::heading_bias`]).
    pub heading_bias: (f64, f64),
    /// The kidnaps: time s, carried from, set down at (x m, y m, φ rad).
    pub kidnaps: Vec<(f64, super::motion::Pose, super::motion::Pose)>,
}
