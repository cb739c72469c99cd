//! Shared by the `driver_*` tests (included with `#[path]`): a clock the test
//! scripts, an independent floating-point reference for the physics, and a
//! builder that turns a list of pings into embedded-hal-mock pin scripts and
//! the poll times that drive them. Built alone it runs its own self-tests.
#![allow(dead_code)]

use std::cell::Cell;

use echoloc::driver::Clock;
use embedded_hal_mock::eh1::digital::{Mock, State, Transaction as T};
use embedded_hal_mock::eh1::MockError;

/// A clock that moves only when the test says so (or by a fixed step per
/// read), optionally with a coarse resolution.
pub struct MockClock {
    now: Cell<u32>,
    step: Cell<u32>,
    tick: Cell<u32>,
    reads: Cell<u64>,
}

impl MockClock {
    pub fn at(t: u32) -> Self {
        Self { now: Cell::new(t), step: Cell::new(0), tick: Cell::new(1), reads: Cell::new(0) }
    }
    /// Set the true time.
    pub fn set(&self, t: u32) {
        self.now.set(t);
    }
    pub fn advance(&self, dt: u32) {
        self.now.set(self.now.get().wrapping_add(dt));
    }
    /// Let `step` µs pass at every read (a busy loop that takes time).
    pub fn auto_advance(&self, step: u32) {
        self.step.set(step);
    }
    /// Report time floored to multiples of `tick` µs (a slower timer).
    pub fn resolution(&self, tick: u32) {
        self.tick.set(tick.max(1));
    }
    /// The true time.
    pub fn now(&self) -> u32 {
        self.now.get()
    }
    pub fn reads(&self) -> u64 {
        self.reads.get()
    }
}

impl Clock for MockClock {
    fn now_us(&self) -> u32 {
        let t = self.now.get();
        self.reads.set(self.reads.get() + 1);
        self.now.set(t.wrapping_add(self.step.get()));
        t - t % self.tick.get()
    }
}

/// Speed of sound, m/s, straight from DESIGN §5 in f64.
pub fn c_ref(centi_c: i16) -> f64 {
    331.3 * (1.0 + f64::from(centi_c) / 100.0 / 273.15).sqrt()
}

/// Round-trip time of flight to `range_mm`, µs, rounded to the nearest µs.
pub fn tof_ref_us(range_mm: f64, centi_c: i16) -> u32 {
    (2.0 * range_mm / c_ref(centi_c) * 1000.0).round() as u32
}

/// Listening window for `max_range_mm`, µs, rounded up.
pub fn window_ref_us(max_range_mm: u32, centi_c: i16) -> u32 {
    (2.0 * f64::from(max_range_mm) / c_ref(centi_c) * 1000.0).ceil() as u32
}

pub fn pin_error() -> MockError {
    MockError::Io(std::io::ErrorKind::BrokenPipe)
}

/// What ECHO does on one ping.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EchoSpec {
    /// Rises this many µs (true time) after INIT.
    At(u32),
    /// Stays low.
    Never,
    /// Already high before the ping.
    StuckHigh,
}

/// Whether a poll at a step should give a reading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expect {
    Nothing,
    Reading,
}

#[derive(Clone, Copy, Debug)]
pub struct Step {
    pub at: u32,
    pub expect: Expect,
}

/// The pin scripts for a stretch of pings.
#[derive(Default, Debug)]
pub struct Scripts {
    pub echo: Vec<T>,
    pub init: Vec<T>,
    pub binh: Vec<T>,
    pub addr: Vec<Vec<T>>,
}

/// Builds pin scripts and poll steps for pings fired at given times, as the
/// driver's documented behaviour says the pins must move.
pub struct Rig {
    pub scripts: Scripts,
    pub steps: Vec<Step>,
    selected: Option<u8>,
    lines: usize,
    window_us: u32,
    binh_after_us: Option<u32>,
    tick: u32,
    last_step: Option<u32>,
}

impl Rig {
    pub fn new(lines: usize, window_us: u32, binh_after_us: Option<u32>) -> Self {
        Self {
            scripts: Scripts { addr: vec![Vec::new(); lines], ..Scripts::default() },
            steps: Vec::new(),
            selected: None,
            lines,
            window_us,
            binh_after_us,
            tick: 1,
            last_step: None,
        }
    }

    /// The clock under test reports multiples of `tick` µs.
    pub fn with_tick(mut self, tick: u32) -> Self {
        self.tick = tick.max(1);
        self
    }

    /// The earliest poll time ≥ `t` at which the driver's (floored) clock
    /// reads at least `t`.
    pub fn ceil_tick(&self, t: u32) -> u32 {
        let r = t % self.tick;
        if r == 0 {
            t
        } else {
            t.wrapping_add(self.tick - r)
        }
    }

    /// Address-line writes to select `t`: only the lines that change (all
    /// of them when the selection is unknown).
    pub fn select(&mut self, t: u8) {
        if self.selected == Some(t) {
            return;
        }
        for bit in 0..self.lines {
            let want = (t >> bit) & 1 == 1;
            if let Some(o) = self.selected {
                if ((o >> bit) & 1 == 1) == want {
                    continue;
                }
            }
            self.scripts.addr[bit].push(T::set(if want { State::High } else { State::Low }));
        }
        self.selected = Some(t);
    }

    /// Forget the selection (after a failed address write).
    pub fn forget_selection(&mut self) {
        self.selected = None;
    }

    fn step(&mut self, at: u32, expect: Expect) {
        self.steps.push(Step { at, expect });
        self.last_step = Some(at);
    }

    /// One ring slot: a poll just before `fire` (nothing may happen), the
    /// poll at `fire` that fires, the polls of the listening window, the stop,
    /// and the multiplexer pointed at `next`.
    pub fn ring_ping(&mut self, fire: u32, transducer: u8, echo: EchoSpec, next: Option<u8>) {
        // The ring's very first poll anchors the schedule and fires at once,
        // so only later slots get a poll just before their time.
        if self.last_step.is_some_and(|l| fire.wrapping_sub(l) > 1) {
            self.step(fire.wrapping_sub(1), Expect::Nothing);
        }
        self.ping_at(fire, transducer, echo);
        if let Some(n) = next {
            self.select(n);
        }
    }

    /// One ping driven through `start` (or the ring's firing poll) at `fire`
    /// and polls after it. The first step is the firing itself.
    pub fn ping_at(&mut self, fire: u32, transducer: u8, echo: EchoSpec) {
        if echo == EchoSpec::StuckHigh {
            self.scripts.echo.push(T::get(State::High));
            self.step(fire, Expect::Reading);
            return;
        }
        self.scripts.echo.push(T::get(State::Low));
        self.select(transducer);
        self.scripts.init.push(T::set(State::High));
        self.step(fire, Expect::Nothing);
        // Polls, as offsets from the firing, in order.
        let mut polls: Vec<u32> = Vec::new();
        if let Some(b) = self.binh_after_us {
            polls.push(self.ceil_tick(b));
        }
        match echo {
            EchoSpec::At(x) => {
                polls.push(x.saturating_sub(1).max(1));
                polls.push(x);
            }
            _ => {
                polls.push(self.window_us / 2);
                polls.push(self.window_us - 1);
                polls.push(self.ceil_tick(self.window_us));
            }
        }
        polls.sort_unstable();
        polls.dedup();
        let mut binh_raised = false;
        for e in polls {
            let high = matches!(echo, EchoSpec::At(x) if e >= x);
            self.scripts.echo.push(T::get(if high { State::High } else { State::Low }));
            let ended = high || (echo == EchoSpec::Never && e - e % self.tick >= self.window_us);
            if ended {
                self.scripts.init.push(T::set(State::Low));
                if binh_raised {
                    self.scripts.binh.push(T::set(State::Low));
                }
                self.step(fire.wrapping_add(e), Expect::Reading);
                return;
            }
            if let Some(b) = self.binh_after_us {
                if !binh_raised && e - e % self.tick >= b {
                    self.scripts.binh.push(T::set(State::High));
                    binh_raised = true;
                }
            }
            self.step(fire.wrapping_add(e), Expect::Nothing);
        }
    }

    /// Take the scripts built so far (to load into mocks) and the steps.
    pub fn take(&mut self) -> (Scripts, Vec<Step>) {
        let lines = self.lines;
        let s = std::mem::replace(&mut self.scripts, Scripts { addr: vec![Vec::new(); lines], ..Scripts::default() });
        (s, std::mem::take(&mut self.steps))
    }
}

/// The mocks of one module: ECHO, INIT, BINH and address lines, plus clones
/// the test keeps to reload and check them.
pub struct Pins<const A: usize> {
    pub echo: Mock,
    pub init: Mock,
    pub binh: Mock,
    pub addr: [Mock; A],
}

impl<const A: usize> Pins<A> {
    pub fn new(s: &Scripts) -> Self {
        Self {
            echo: Mock::new(&s.echo),
            init: Mock::new(&s.init),
            binh: Mock::new(&s.binh),
            addr: std::array::from_fn(|i| Mock::new(s.addr.get(i).map_or(&[][..], |v| &v[..]))),
        }
    }

    /// Clones for the driver (they share the expectations).
    pub fn clones(&self) -> (Mock, Mock, Mock, [Mock; A]) {
        (self.echo.clone(), self.init.clone(), self.binh.clone(), std::array::from_fn(|i| self.addr[i].clone()))
    }

    /// Load the next stretch; panics if the last one was not used up.
    pub fn reload(&mut self, s: &Scripts) {
        self.echo.update_expectations(&s.echo);
        self.init.update_expectations(&s.init);
        self.binh.update_expectations(&s.binh);
        for (i, a) in self.addr.iter_mut().enumerate() {
            a.update_expectations(s.addr.get(i).map_or(&[][..], |v| &v[..]));
        }
    }

    pub fn done(&mut self) {
        self.echo.done();
        self.init.done();
        self.binh.done();
        for a in &mut self.addr {
            a.done();
        }
    }
}

#[cfg(test)]
mod self_tests {
    use super::*;

    #[test]
    fn mock_clock_scripts_steps_ticks_and_wraps() {
        let c = MockClock::at(u32::MAX - 4);
        assert_eq!(c.now_us(), u32::MAX - 4);
        c.advance(10);
        assert_eq!(c.now_us(), 5);
        c.auto_advance(3);
        assert_eq!((c.now_us(), c.now_us(), c.now()), (5, 8, 11));
        c.resolution(4);
        c.auto_advance(0);
        assert_eq!(c.now_us(), 8);
        assert_eq!(c.reads(), 5);
    }

    #[test]
    fn reference_speed_of_sound() {
        assert!((c_ref(2000) - 343.21).abs() < 0.01);
        // 1 m at 20 °C is 5 827 µs there and back.
        assert_eq!(tof_ref_us(1000.0, 2000), 5827);
    }

    #[test]
    fn rig_writes_only_changed_address_lines() {
        let mut rig = Rig::new(3, 10_000, None);
        rig.select(5);
        rig.select(4);
        rig.select(4);
        assert_eq!(rig.scripts.addr[0], vec![T::set(State::High), T::set(State::Low)]);
        assert_eq!(rig.scripts.addr[1], vec![T::set(State::Low)]);
        assert_eq!(rig.scripts.addr[2], vec![T::set(State::High)]);
    }
}
