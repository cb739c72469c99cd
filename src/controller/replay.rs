//! A scenario replayed through the real ring driver and the controller: the
//! loop a board runs under QEMU, and the host tests run the same way.
//!
//! The driver fires on its own schedule over the scenario's [`Bench`]; each
//! reading it returns goes, with the odometry up to it, through
//! [`Controller::step`]; the estimate is scored against the scenario's true
//! pose at that firing. Where the odometry comes from is the caller's: the
//! scenario's own records ([`scenario_odometry`]), or a host link.

use core::convert::Infallible;

use super::{Controller, ControllerError, OdometryError, Step};
use crate::credence::Credence;
use crate::driver::{ConfigError, Eeruf, ModuleConfig, NoPin, Ring, RingConfig, SpeedOfSound};
use crate::driver::{Error as DriverError, Module, RingReading, RingTiming, Schedule, Timing};
use crate::localize::{LocalizeError, Localizer, LocalizerConfig, LocalizerCounts, Mode, Start};
use crate::map::{FieldView, MapSource};
use crate::predict::{Mount, PredictParams};
use crate::referencing::{wrap, EkfConfig, Motion, VerdictConfig};
use crate::scenario::replay::{AddrLine, Bench, BenchFault, EchoLine, InitLine};
use crate::scenario::{Record, ScenarioError};

/// Why a replay stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplayError {
    /// The scenario does not fit this map, ring or driver.
    Scenario(ScenarioError),
    /// It has another number of transducers than the ring (`expected`).
    Transducers {
        /// The ring's.
        expected: u8,
        /// The scenario's.
        found: u8,
    },
    /// Its start was refused by the localizer.
    Start(LocalizeError),
    /// The driver fired differently from the scenario's records.
    Bench(BenchFault),
    /// The driver failed (the bench's pins cannot: kept for completeness).
    Driver(DriverError<Infallible>),
    /// The driver returned nothing within a whole slot of waits.
    Stalled,
    /// The controller refused a reading.
    Controller(ControllerError),
    /// The odometry source could not answer for a reading.
    Odometry(OdometryError),
}

impl From<ControllerError> for ReplayError {
    fn from(e: ControllerError) -> Self {
        Self::Controller(e)
    }
}

impl From<OdometryError> for ReplayError {
    fn from(e: OdometryError) -> Self {
        Self::Odometry(e)
    }
}

impl core::fmt::Display for ReplayError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Scenario(e) => write!(f, "scenario: {e}"),
            Self::Transducers { expected, found } => {
                write!(f, "the scenario has {found} transducers, the ring {expected}")
            }
            Self::Start(e) => write!(f, "start refused: {e}"),
            Self::Bench(e) => write!(f, "replay: {e}"),
            Self::Driver(e) => write!(f, "driver: {e:?}"),
            Self::Stalled => f.write_str("the driver returned no reading within a slot"),
            Self::Controller(e) => write!(f, "controller: {e}"),
            Self::Odometry(e) => write!(f, "odometry: {e}"),
        }
    }
}

impl core::error::Error for ReplayError {}

/// Error figures of the estimate against the scenario's truth, over every
/// reading (the lab's `simulate --json` "ekf" figures, same definitions).
/// In `f32`, with compensated sums, so that a board without a
/// double-precision FPU carries no soft `f64` for its report: the RMSE
/// is good to a few parts in 10⁷ however long the run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Score {
    /// Readings scored.
    pub readings: u32,
    /// Position RMSE, m.
    pub position_rmse_m: f32,
    /// Heading RMSE, degrees.
    pub heading_rmse_deg: f32,
    /// Largest position error, m.
    pub max_position_m: f32,
    /// Position error at the end, m.
    pub final_position_m: f32,
    /// Heading error at the end, degrees (absolute).
    pub final_heading_deg: f32,
    sum_p2: Sum,
    sum_h2: Sum,
}

/// A running `f32` sum and the rounding error it has dropped so far
/// (Neumaier's compensated summation).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Sum {
    sum: f32,
    lost: f32,
}

impl Sum {
    fn add(&mut self, v: f32) {
        let t = self.sum + v;
        self.lost += if self.sum.abs() >= v.abs() { (self.sum - t) + v } else { (v - t) + self.sum };
        self.sum = t;
    }

    fn value(&self) -> f32 {
        self.sum + self.lost
    }
}

impl Score {
    /// Adds the estimate `x` against the true pose `truth` (m, rad).
    pub fn add(&mut self, x: [f32; 3], truth: [f32; 3]) {
        let (dx, dy) = (x[0] - truth[0], x[1] - truth[1]);
        let p2 = dx * dx + dy * dy;
        let p = crate::f32math::sqrt(p2);
        let h = wrap(x[2] - truth[2]).to_degrees();
        // A count that stops at its largest value rather than restarting.
        self.readings = self.readings.saturating_add(1);
        self.sum_p2.add(p2);
        self.sum_h2.add(h * h);
        let n = self.readings as f32;
        self.position_rmse_m = crate::f32math::sqrt(self.sum_p2.value() / n);
        self.heading_rmse_deg = crate::f32math::sqrt(self.sum_h2.value() / n);
        self.max_position_m = self.max_position_m.max(p);
        self.final_position_m = p;
        self.final_heading_deg = h.abs();
    }

    /// Within the bounds: position RMSE (m) and heading RMSE (°).
    pub fn within(&self, bound_position_m: f32, bound_heading_deg: f32) -> bool {
        self.readings > 0 && self.position_rmse_m <= bound_position_m && self.heading_rmse_deg <= bound_heading_deg
    }
}

/// What a replay produced.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplaySummary {
    /// The estimate against the truth.
    pub score: Score,
    /// The scenario's bounds passed.
    pub passed: bool,
    /// The loop's counts.
    pub counts: super::LoopCounts,
    /// Readings the filter accepted and gated.
    pub accepted: u32,
    /// Readings its gate rejected.
    pub gated: u32,
    /// Times the EKF became lost, and cycles it ended lost.
    pub lost: (u32, u32),
    /// The localizer's cycles by mode, its hand-offs and wake-ups.
    pub localizer: LocalizerCounts,
    /// Its mode at the end.
    pub mode: Mode,
    /// The final estimate.
    pub state: [f32; 3],
}

/// The settings of the ring and the filter a replay runs with.
#[derive(Clone, Copy, Debug)]
pub struct ReplaySetup<const N: usize> {
    /// The module's timing (the scenario must have been made for it).
    pub timing: Timing,
    /// The ring's.
    pub ring: RingTiming<N>,
    /// Its firing order.
    pub schedule: Schedule<N>,
    /// Prediction.
    pub params: PredictParams,
    /// The filter.
    pub ekf: EkfConfig,
    /// How readings are judged.
    pub verdicts: VerdictConfig,
    /// The localizer around the filter.
    pub localizer: LocalizerConfig,
}

impl<const N: usize> ReplaySetup<N> {
    /// What `echoloc-lab simulate` writes scenarios for: a Polaroid 6500
    /// module without BINH at 20.00 °C, a 5 ms ring-down gap, EERUF with
    /// 1 ms steps and a 50 mm tolerance, the spread schedule; the default
    /// EKF and the Polaroid verdicts.
    pub const fn standard(params: PredictParams) -> Result<Self, ConfigError> {
        let sound = match SpeedOfSound::at_centi_celsius(2000) {
            Ok(s) => s,
            Err(e) => return Err(e),
        };
        let timing = match ModuleConfig::polaroid_6500(sound).timing() {
            Ok(t) => t,
            Err(e) => return Err(e),
        };
        let eeruf = Eeruf { alternating_us: 1_000, tolerance_mm: 50 };
        let ring = match (RingConfig { ring_down_us: 5_000, eeruf: Some(eeruf) }).timing::<N>(&timing) {
            Ok(r) => r,
            Err(e) => return Err(e),
        };
        Ok(Self {
            timing,
            ring,
            schedule: Schedule::spread(),
            params,
            ekf: EkfConfig::DEFAULT,
            verdicts: VerdictConfig::POLAROID,
            localizer: LocalizerConfig::DEFAULT,
        })
    }
}

/// The ring driver over a bench, `A` address lines for `N` transducers.
pub type BenchRing<'b, 's, const A: usize, const N: usize> =
    Ring<InitLine<'b, 's>, EchoLine<'b, 's>, NoPin<Infallible>, AddrLine<'b, 's>, &'b Bench<'s>, A, N>;

/// The odometry the scenario recorded for `record`.
pub fn scenario_odometry(_: &RingReading, record: &Record) -> Result<Motion, ReplayError> {
    Ok(Motion { dx: record.odometry[0], dy: record.odometry[1], dphi: record.odometry[2] })
}

/// Checks the scenario against the map's CRC, the ring and the driver.
pub fn check<const N: usize>(bench: &Bench<'_>, map_crc: u32, setup: &ReplaySetup<N>) -> Result<(), ReplayError> {
    let s = bench.scenario();
    s.check_map(map_crc).map_err(ReplayError::Scenario)?;
    if s.transducers() != N {
        return Err(ReplayError::Transducers { expected: N as u8, found: s.transducers() as u8 });
    }
    s.header()
        .check_driver(setup.ring.period_us(), setup.ring.slot_us(), setup.timing.sound().um_per_s())
        .map_err(ReplayError::Scenario)
}

/// A localizer for a replay: the setup's settings, `seed` fixing the
/// particles' draws. Start it with [`start`].
pub fn localizer<const P: usize, const N: usize>(setup: &ReplaySetup<N>, seed: u64) -> Localizer<P> {
    Localizer::new(setup.localizer, setup.ekf, setup.verdicts, seed)
}

/// Starts `localizer` for a replay of the bench's scenario on the map's
/// `field`: tracking from the scenario's start pose (`how: None`), or as
/// `how` says.
pub fn start<const P: usize>(
    localizer: &mut Localizer<P>,
    bench: &Bench<'_>,
    field: &FieldView<'_>,
    how: Option<Start>,
) -> Result<(), ReplayError> {
    let h = bench.scenario().header();
    let how = how.unwrap_or(Start::Known { pose: h.start, sigma: h.start_sigma });
    localizer.start(how, field).map_err(ReplayError::Start)
}

/// Replays every record of the bench's scenario: the driver fires and times
/// each ping, `odometry` gives the motion up to it, the controller judges it
/// and updates the filter, and `each` sees every step (for a link, a log or
/// a cost counter) and may restart the controller (a link's `SetPose`). Call [`check`] first, and [`start`] the localizer.
#[allow(clippy::too_many_arguments)]
pub fn run<M, K, const A: usize, const N: usize, const P: usize>(
    bench: &Bench<'_>,
    map: &M,
    field: &FieldView<'_>,
    mounts: &[Mount],
    credence: &K,
    setup: &ReplaySetup<N>,
    localizer: &mut Localizer<P>,
    mut odometry: impl FnMut(&RingReading, &Record) -> Result<Motion, ReplayError>,
    mut each: impl FnMut(&mut Controller<'_, M, K, P>, &RingReading, &Record, &Step),
) -> Result<ReplaySummary, ReplayError>
where
    M: MapSource + ?Sized,
    K: Credence + ?Sized,
{
    let header = *bench.scenario().header();
    let mut controller = Controller::new(map, field, mounts, setup.params, credence, localizer);
    let addr: [AddrLine<'_, '_>; A] = core::array::from_fn(|bit| bench.addr(bit as u8));
    let module = Module::new(bench.init(), bench.echo(), addr, bench, setup.timing);
    let mut ring: BenchRing<'_, '_, A, N> = Ring::new(module, setup.schedule, setup.ring);
    let mut score = Score::default();
    let (mut accepted, mut gated) = (0u32, 0u32);
    // A slot is one window and a gap: far fewer waits than its length in µs.
    let max_waits = setup.ring.slot_us().saturating_add(setup.ring.period_us());
    let total = bench.scenario().len();
    for k in 0..total {
        let mut waits = 0u32;
        let reading = loop {
            if let Some(f) = bench.fault() {
                return Err(ReplayError::Bench(f));
            }
            match ring.poll() {
                Ok(Some(r)) => break r,
                Ok(None) => {
                    waits = waits.saturating_add(1);
                    if waits > max_waits {
                        return Err(ReplayError::Stalled);
                    }
                    bench.wait(ring.next_fire_us());
                }
                Err(e) => return Err(ReplayError::Driver(e)),
            }
        };
        // The reading must be the ping of record k (a reading without a
        // ping, such as a refused start, would pair with the wrong truth).
        let record = match bench.last_record() {
            Some((i, r)) if i == k => r,
            _ => return Err(ReplayError::Bench(bench.fault().unwrap_or(BenchFault::Unpaired { record: k as u32 }))),
        };
        let u = odometry(&reading, &record)?;
        let step = controller.step(&u, &reading)?;
        match step.report.update {
            Some(crate::referencing::Update::Accepted { .. }) => accepted = accepted.saturating_add(1),
            Some(crate::referencing::Update::Gated { .. }) => gated = gated.saturating_add(1),
            _ => {}
        }
        score.add(controller.state(), record.truth);
        each(&mut controller, &reading, &record, &step);
    }
    controller.finish()?;
    let ekf = &controller.referencer().ekf;
    Ok(ReplaySummary {
        score,
        passed: score.within(header.bound_position_m, header.bound_heading_deg),
        counts: controller.counts(),
        accepted,
        gated,
        lost: (ekf.lost_count(), ekf.cycles_lost()),
        localizer: controller.localizer().counts(),
        mode: controller.mode(),
        state: controller.state(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `f32` score against the same figures summed in `f64` over a
    /// long run (200 000 readings, errors from 0 to 2 m and 0 to 30°):
    /// the compensated sums keep the RMSE to parts in 10⁶, where a plain
    /// `f32` sum drifts by parts in 10⁴ or more.
    #[test]
    fn a_long_run_scores_as_in_f64() {
        let mut s = Score::default();
        let (mut p2, mut h2, mut max) = (0f64, 0f64, 0f64);
        let mut state = 0x9e37_79b9u32;
        let mut unit = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / (1 << 24) as f32
        };
        let n = 200_000;
        for _ in 0..n {
            let truth = [10.0 * unit(), -5.0 * unit(), 3.0 * unit() - 1.5];
            let x = [truth[0] + 1.4 * unit(), truth[1] - 1.4 * unit(), truth[2] + 0.5 * (unit() - 0.5)];
            s.add(x, truth);
            let (dx, dy) = (f64::from(x[0]) - f64::from(truth[0]), f64::from(x[1]) - f64::from(truth[1]));
            let h = f64::from(wrap(x[2] - truth[2])).to_degrees();
            p2 += dx * dx + dy * dy;
            h2 += h * h;
            max = max.max((dx * dx + dy * dy).sqrt());
        }
        let rel = |got: f32, want: f64| (f64::from(got) - want).abs() / want;
        assert_eq!(s.readings, n);
        assert!(rel(s.position_rmse_m, (p2 / f64::from(n)).sqrt()) < 2e-6, "{s:?}");
        assert!(rel(s.heading_rmse_deg, (h2 / f64::from(n)).sqrt()) < 2e-6, "{s:?}");
        assert!(rel(s.max_position_m, max) < 1e-6, "{s:?}");
        assert!(s.within(s.position_rmse_m, s.heading_rmse_deg) && !s.within(s.position_rmse_m * 0.999, 90.0));
        assert!(!Score::default().within(1.0, 1.0), "no readings, no pass");
    }
}
