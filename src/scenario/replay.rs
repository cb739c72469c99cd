//! A replay bench: the HAL a board hands the real ring driver so that a
//! scenario's echoes come back through it.
//!
//! The bench is a virtual microsecond clock, an INIT line, an ECHO line and
//! multiplexer address lines, all over one shared state. When the driver
//! raises INIT, the bench takes the scenario's next record, checks that the
//! driver selected the record's transducer and fired at the record's time
//! (relative to the first firing), and raises ECHO when the clock reaches
//! the firing time plus the record's echo time. The driver reads the clock
//! and the pin as on a real board, so it is the driver's own code that
//! times every echo, classifies it (blanking, window, EERUF) and runs the
//! schedule.
//!
//! Time passes only when the board's loop waits ([`Bench::wait`]), as a
//! firmware that sleeps between polls: to the slot's firing time when no
//! ping is in flight; during a ping, to the echo's edge or one poll step
//! later, whichever comes first (a poll woken by the edge's interrupt, or by
//! the poll timer). So an echo is timed to the microsecond, and a replay
//! gives the driver exactly the ranges the lab's `scenario replay` computes.
//!
//! ```
//! use echoloc::driver::{Module, ModuleConfig, Outcome, Ring, RingConfig, Schedule, SpeedOfSound};
//! use echoloc::predict::Mount;
//! use echoloc::scenario::replay::Bench;
//! use echoloc::scenario::{write, Header, Record, Scenario};
//!
//! let sound = SpeedOfSound::at_centi_celsius(2000).unwrap();
//! let timing = ModuleConfig::polaroid_6500(sound).timing().unwrap();
//! let ring_timing = RingConfig { ring_down_us: 5_000, eeruf: None }.timing::<2>(&timing).unwrap();
//! let schedule = Schedule::<2>::spread();
//! // Two transducers, one cycle: a wall 1.5 m ahead of the first, nothing for the second.
//! let records = [0usize, 1].map(|slot| Record {
//!     time_us: ring_timing.fire_offset_us(0, slot),
//!     cycle: 0,
//!     transducer: schedule.transducer(slot).unwrap(),
//!     slot: slot as u8,
//!     echo_us: (slot == 0).then(|| sound.tof_us(1500)),
//!     odometry: [0.0; 3],
//!     truth: [0.0; 3],
//! });
//! let header = Header {
//!     map_crc: 0, speed_um_per_s: sound.um_per_s(), period_us: ring_timing.period_us(),
//!     slot_us: ring_timing.slot_us(), start: [0.0; 3], start_sigma: [0.1; 3],
//!     bound_position_m: 0.1, bound_heading_deg: 1.0,
//! };
//! let mounts = [Mount { x_mm: 0, y_mm: 0, heading_mdeg: 0 }; 2];
//! let mut bytes = Vec::new();
//! write(&header, &mounts, &records, |b| bytes.extend_from_slice(b)).unwrap();
//! let scenario = Scenario::parse(&bytes).unwrap();
//!
//! let bench = Bench::new(scenario, 1_000);
//! let module = Module::new(bench.init(), bench.echo(), [bench.addr(0)], &bench, timing);
//! let mut ring = Ring::new(module, schedule, ring_timing);
//! let mut outcomes = Vec::new();
//! while outcomes.len() < 2 {
//!     match ring.poll().unwrap() {
//!         Some(r) => outcomes.push(r.outcome),
//!         None => bench.wait(ring.next_fire_us()),
//!     }
//! }
//! assert!(matches!(outcomes[0], Outcome::Range { range_mm, .. } if range_mm.abs_diff(1500) <= 1));
//! assert_eq!(outcomes[1], Outcome::NoEcho);
//! assert_eq!(bench.fault(), None);
//! assert!(bench.done());
//! ```

use core::cell::Cell;
use core::convert::Infallible;

use embedded_hal::digital::{ErrorType, InputPin, OutputPin};

use super::{Record, Scenario};
use crate::driver::Clock;

/// Why the bench stopped answering the driver: the driver did something the
/// scenario did not record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BenchFault {
    /// The driver fired after the last record.
    Exhausted,
    /// The driver returned a reading for which the bench saw no ping
    /// (expected record `record`).
    Unpaired {
        /// The record the reading should have been.
        record: u32,
    },
    /// It fired another transducer than the record's.
    Transducer {
        /// Record index.
        record: u32,
        /// The record's transducer.
        expected: u8,
        /// What the address lines selected.
        selected: u8,
    },
    /// It fired at another time than the record's (µs after the first firing).
    Schedule {
        /// Record index.
        record: u32,
        /// The record's firing time.
        expected_us: u32,
        /// The driver's.
        fired_us: u32,
    },
}

impl core::fmt::Display for BenchFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Exhausted => f.write_str("the driver fired after the scenario's last record"),
            Self::Unpaired { record } => write!(f, "a reading without a ping where record {record} was due"),
            Self::Transducer { record, expected, selected } => {
                write!(f, "record {record}: transducer {selected} fired, the scenario has {expected}")
            }
            Self::Schedule { record, expected_us, fired_us } => {
                write!(f, "record {record}: fired at {fired_us} µs, the scenario at {expected_us} µs")
            }
        }
    }
}

impl core::error::Error for BenchFault {}

/// The ping in flight.
#[derive(Clone, Copy, Debug)]
struct Ping {
    record: usize,
    /// Clock reading at which ECHO rises, if an echo comes.
    edge: Option<u32>,
}

/// The bench: a scenario behind a virtual clock and the module's lines.
#[derive(Debug)]
pub struct Bench<'s> {
    scenario: Scenario<'s>,
    poll_step_us: u32,
    now: Cell<u32>,
    addr: Cell<u8>,
    ping: Cell<Option<Ping>>,
    next: Cell<usize>,
    /// (clock, scenario time) of the first firing.
    origin: Cell<Option<(u32, u32)>>,
    last: Cell<Option<usize>>,
    fault: Cell<Option<BenchFault>>,
}

impl<'s> Bench<'s> {
    /// A bench at time 0 before the scenario's first record. `poll_step_us`
    /// (at least 1) is how far the clock moves at a wait during a ping with
    /// no edge due sooner: the poll timer's period.
    pub fn new(scenario: Scenario<'s>, poll_step_us: u32) -> Self {
        Self {
            scenario,
            poll_step_us: poll_step_us.max(1),
            now: Cell::new(0),
            addr: Cell::new(0),
            ping: Cell::new(None),
            next: Cell::new(0),
            origin: Cell::new(None),
            last: Cell::new(None),
            fault: Cell::new(None),
        }
    }

    /// The scenario replayed.
    pub fn scenario(&self) -> &Scenario<'s> {
        &self.scenario
    }

    /// The INIT line.
    pub fn init(&self) -> InitLine<'_, 's> {
        InitLine(self)
    }

    /// The ECHO line.
    pub fn echo(&self) -> EchoLine<'_, 's> {
        EchoLine(self)
    }

    /// Multiplexer address line `bit` (0..8).
    pub fn addr(&self, bit: u8) -> AddrLine<'_, 's> {
        AddrLine { bench: self, bit: bit & 7 }
    }

    /// Lets time pass, as a firmware sleeping until its next wake-up:
    /// during a ping, to the echo's edge or one poll step, whichever is
    /// sooner; otherwise to `next_fire_us` (the ring's
    /// [`next_fire_us`](crate::driver::Ring::next_fire_us)) if it is ahead,
    /// else one poll step.
    pub fn wait(&self, next_fire_us: Option<u32>) {
        let now = self.now.get();
        let step = now.wrapping_add(self.poll_step_us);
        let to = match self.ping.get() {
            Some(Ping { edge: Some(e), .. }) if ahead(now, e) && ahead(e, step) => e,
            Some(_) => step,
            None => match next_fire_us {
                Some(d) if ahead(now, d) => d,
                _ => step,
            },
        };
        self.now.set(to);
    }

    /// The first mismatch between the driver and the scenario, if any. After
    /// one the bench fires nothing more (ECHO stays low).
    pub fn fault(&self) -> Option<BenchFault> {
        self.fault.get()
    }

    /// The record of the last ping that ended (INIT fell), and its index.
    pub fn last_record(&self) -> Option<(usize, Record)> {
        let i = self.last.get()?;
        self.scenario.record(i).map(|r| (i, r))
    }

    /// Records fired so far.
    pub fn fired(&self) -> usize {
        self.next.get()
    }

    /// Every record has been fired and its ping has ended.
    pub fn done(&self) -> bool {
        self.next.get() >= self.scenario.len() && self.ping.get().is_none()
    }

    fn fire(&self) {
        if self.fault.get().is_some() {
            return;
        }
        let i = self.next.get();
        let Some(r) = self.scenario.record(i) else {
            self.fault.set(Some(BenchFault::Exhausted));
            return;
        };
        let now = self.now.get();
        let (clock0, time0) = *self.origin.get().get_or_insert((now, r.time_us));
        self.origin.set(Some((clock0, time0)));
        let record = i as u32;
        let selected = self.addr.get();
        if selected != r.transducer {
            self.fault.set(Some(BenchFault::Transducer { record, expected: r.transducer, selected }));
            return;
        }
        let (expected_us, fired_us) = (r.time_us.wrapping_sub(time0), now.wrapping_sub(clock0));
        if expected_us != fired_us {
            self.fault.set(Some(BenchFault::Schedule { record, expected_us, fired_us }));
            return;
        }
        self.ping.set(Some(Ping { record: i, edge: r.echo_us.map(|e| now.wrapping_add(e)) }));
        self.next.set(i.saturating_add(1));
    }

    fn stop(&self) {
        if let Some(p) = self.ping.take() {
            self.last.set(Some(p.record));
        }
    }

    fn echo_high(&self) -> bool {
        matches!(self.ping.get(), Some(Ping { edge: Some(e), .. }) if !ahead(self.now.get(), e))
    }
}

/// `b` is later than `a` (wrapping, less than 2³¹ µs apart).
fn ahead(a: u32, b: u32) -> bool {
    (b.wrapping_sub(a) as i32) > 0
}

impl Clock for Bench<'_> {
    fn now_us(&self) -> u32 {
        self.now.get()
    }
}

/// The bench's INIT line: rising fires the next record, falling ends it.
#[derive(Debug)]
pub struct InitLine<'b, 's>(&'b Bench<'s>);

/// The bench's ECHO line.
#[derive(Debug)]
pub struct EchoLine<'b, 's>(&'b Bench<'s>);

/// One of the bench's multiplexer address lines.
#[derive(Debug)]
pub struct AddrLine<'b, 's> {
    bench: &'b Bench<'s>,
    bit: u8,
}

impl AddrLine<'_, '_> {
    /// This line's bit of the address (none for a line past the eighth).
    fn mask(&self) -> u8 {
        1u8.checked_shl(u32::from(self.bit)).unwrap_or(0)
    }
}

impl ErrorType for InitLine<'_, '_> {
    type Error = Infallible;
}

impl OutputPin for InitLine<'_, '_> {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.0.stop();
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.0.fire();
        Ok(())
    }
}

impl ErrorType for EchoLine<'_, '_> {
    type Error = Infallible;
}

impl InputPin for EchoLine<'_, '_> {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.0.echo_high())
    }

    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0.echo_high())
    }
}

impl ErrorType for AddrLine<'_, '_> {
    type Error = Infallible;
}

impl OutputPin for AddrLine<'_, '_> {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.bench.addr.set(self.bench.addr.get() & !self.mask());
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.bench.addr.set(self.bench.addr.get() | self.mask());
        Ok(())
    }
}
