//! Shared by the `driver_*` tests (each includes it with
//! `#[path = "common/driver_support.rs"] mod support;`; it is not a test
//! target of its own): a clock the test scripts, an independent
//! floating-point reference for the physics, a builder that turns a list of
//! pings into embedded-hal-mock pin scripts and the poll times that drive
//! them, and recording pins that log every pin operation of a module, in
//! order and with the time, for a checker of the Polaroid protocol across
//! pins. Its self-tests are in `driver_support_self_tests.rs`, included by
//! `driver_module.rs` only, so they run once.
#![allow(dead_code)]

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use echoloc::driver::Clock;
use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
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

/// EERUF's late limit, µs, from the f64 speed of sound: half of what the
/// step has left over the shortest shift that reads as more than
/// `tolerance_mm` (a range rounded to the mm reads more than `r` from
/// `r + 0.5` mm on).
pub fn late_limit_ref_us(step_us: u32, tolerance_mm: u32, centi_c: i16) -> u32 {
    let shift = ((2.0 * f64::from(tolerance_mm) + 1.0) / c_ref(centi_c) * 1000.0).ceil() as u32;
    (step_us - shift) / 2
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
        let early = self.last_step.is_some_and(|l| fire.wrapping_sub(l) > 1);
        self.ring_ping_polled(fire, early, transducer, echo, next);
    }

    /// As [`Rig::ring_ping`] for a slot first polled late, at `fire`: no
    /// poll before it.
    pub fn late_ring_ping(&mut self, fire: u32, transducer: u8, echo: EchoSpec, next: Option<u8>) {
        self.ring_ping_polled(fire, false, transducer, echo, next);
    }

    fn ring_ping_polled(&mut self, fire: u32, poll_before: bool, transducer: u8, echo: EchoSpec, next: Option<u8>) {
        if poll_before {
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

/// Pin transactions from a compact string, one per letter: `H` high, `L`
/// low. `reads("LLH")`: ECHO low, low, then high.
pub fn reads(levels: &str) -> Vec<T> {
    levels.chars().map(|c| T::get(level(c))).collect()
}

/// Writes, one per letter (see [`reads`]).
pub fn writes(levels: &str) -> Vec<T> {
    levels.chars().map(|c| T::set(level(c))).collect()
}

/// INIT over `n` clean pings: up and down, `n` times.
pub fn init_pings(n: usize) -> Vec<T> {
    writes(&"HL".repeat(n))
}

fn level(c: char) -> State {
    match c {
        'H' => State::High,
        'L' => State::Low,
        _ => panic!("level {c:?}: use H or L"),
    }
}

/// One line of a module.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line {
    Init,
    Echo,
    Binh,
    Addr(u8),
}

/// What was done to a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    SetHigh,
    SetLow,
    /// A read, and what it returned (`false` if it failed).
    Read(bool),
}

/// One pin operation, in the order the driver made it across all pins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Event {
    pub line: Line,
    pub act: Act,
    /// The mock clock's true time.
    pub at: u32,
    /// Whether the mock returned `Ok`.
    pub ok: bool,
}

/// The shared, ordered record of every pin operation of one module.
#[derive(Clone)]
pub struct PinLog<'c> {
    events: Rc<RefCell<Vec<Event>>>,
    clock: &'c MockClock,
}

impl<'c> PinLog<'c> {
    pub fn new(clock: &'c MockClock) -> Self {
        Self { events: Rc::new(RefCell::new(Vec::new())), clock }
    }
    /// The events so far, leaving the log empty.
    pub fn take(&self) -> Vec<Event> {
        std::mem::take(&mut *self.events.borrow_mut())
    }
    /// A recording pin for `line` in front of `pin`.
    pub fn pin(&self, line: Line, pin: Mock) -> RecPin<'c> {
        RecPin { line, pin, log: self.clone() }
    }
    fn push(&self, line: Line, act: Act) -> usize {
        let mut ev = self.events.borrow_mut();
        ev.push(Event { line, act, at: self.clock.now(), ok: true });
        ev.len() - 1
    }
    fn outcome(&self, i: usize, ok: bool, act: Option<Act>) {
        let mut ev = self.events.borrow_mut();
        ev[i].ok = ok;
        if let Some(a) = act {
            ev[i].act = a;
        }
    }
}

/// A mock pin that records every operation in a shared [`PinLog`] before
/// handing it to the embedded-hal-mock pin (which checks its own script).
pub struct RecPin<'c> {
    line: Line,
    pin: Mock,
    log: PinLog<'c>,
}

impl ErrorType for RecPin<'_> {
    type Error = MockError;
}

impl OutputPin for RecPin<'_> {
    fn set_low(&mut self) -> Result<(), MockError> {
        let i = self.log.push(self.line, Act::SetLow);
        let r = self.pin.set_low();
        self.log.outcome(i, r.is_ok(), None);
        r
    }
    fn set_high(&mut self) -> Result<(), MockError> {
        let i = self.log.push(self.line, Act::SetHigh);
        let r = self.pin.set_high();
        self.log.outcome(i, r.is_ok(), None);
        r
    }
}

impl InputPin for RecPin<'_> {
    fn is_high(&mut self) -> Result<bool, MockError> {
        let i = self.log.push(self.line, Act::Read(false));
        let r = self.pin.is_high();
        self.log.outcome(i, r.is_ok(), r.as_ref().ok().map(|&h| Act::Read(h)));
        r
    }
    fn is_low(&mut self) -> Result<bool, MockError> {
        self.is_high().map(|h| !h)
    }
}

/// A line's level as far as the writes say.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    Low,
    High,
    /// After a failed write, or never written.
    Unknown,
}

/// A ping as the pins saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fired {
    /// The transducer the address lines selected as INIT rose.
    pub transducer: u8,
    /// When INIT rose (true time).
    pub at: u32,
    /// When BINH rose, if it did.
    pub binh_at: Option<u32>,
    /// When INIT fell, if it has.
    pub ended_at: Option<u32>,
}

/// Checks the order of pin operations across all pins of one module against
/// the protocol of DESIGN §5 and `docs/driver.md` ("One ping"), and collects
/// the pings fired. Panics at the first violation:
///
/// - an address line is written only while INIT is (known) low and BINH is
///   not high: the multiplexer is settled before INIT rises and never moves
///   under a ping;
/// - INIT rises only with every address line known, BINH low, and ECHO read
///   low since INIT last moved (the stuck-line check);
/// - BINH rises only while INIT is high, after it;
/// - BINH is dropped only once INIT is no longer high (INIT falls first).
///
/// A module starts with INIT and BINH low and the address lines unknown, as
/// `Module::new` assumes.
#[derive(Debug)]
pub struct Protocol {
    init: Level,
    binh: Level,
    addr: Vec<Level>,
    echo_checked: bool,
    fired: Vec<Fired>,
    seen: usize,
}

impl Protocol {
    pub fn new(lines: usize) -> Self {
        Self {
            init: Level::Low,
            binh: Level::Low,
            addr: vec![Level::Unknown; lines],
            echo_checked: false,
            fired: Vec::new(),
            seen: 0,
        }
    }

    /// Check the next stretch of events (continuing from the last).
    pub fn feed(&mut self, events: &[Event]) {
        for e in events {
            self.seen += 1;
            let n = self.seen;
            let after = |ok: bool, to: Level| if ok { to } else { Level::Unknown };
            match (e.line, e.act) {
                (Line::Addr(b), Act::SetHigh | Act::SetLow) => {
                    assert_eq!(self.init, Level::Low, "event {n} {e:?}: address line written while INIT is not low");
                    assert_ne!(self.binh, Level::High, "event {n} {e:?}: address line written with BINH high");
                    let to = if e.act == Act::SetHigh { Level::High } else { Level::Low };
                    self.addr[b as usize] = after(e.ok, to);
                }
                (Line::Init, Act::SetHigh) => {
                    let mut t = 0u8;
                    for (b, l) in self.addr.iter().enumerate() {
                        match l {
                            Level::High => t |= 1 << b,
                            Level::Low => {}
                            Level::Unknown => panic!("event {n} {e:?}: INIT rose with address line {b} unknown"),
                        }
                    }
                    assert_eq!(self.binh, Level::Low, "event {n} {e:?}: INIT rose with BINH not low");
                    assert!(self.echo_checked, "event {n} {e:?}: INIT rose without ECHO read low first");
                    self.echo_checked = false;
                    self.init = after(e.ok, Level::High);
                    if e.ok {
                        self.fired.push(Fired { transducer: t, at: e.at, binh_at: None, ended_at: None });
                    }
                }
                (Line::Init, Act::SetLow) => {
                    self.echo_checked = false;
                    if self.init != Level::Low {
                        if let Some(f) = self.fired.last_mut().filter(|f| f.ended_at.is_none()) {
                            f.ended_at = Some(e.at);
                        }
                    }
                    self.init = after(e.ok, Level::Low);
                }
                (Line::Binh, Act::SetHigh) => {
                    assert_eq!(self.init, Level::High, "event {n} {e:?}: BINH raised while INIT is not high");
                    self.binh = after(e.ok, Level::High);
                    if let Some(f) = self.fired.last_mut() {
                        f.binh_at = f.binh_at.or(Some(e.at));
                    }
                }
                (Line::Binh, Act::SetLow) => {
                    assert_ne!(self.init, Level::High, "event {n} {e:?}: BINH dropped before INIT");
                    self.binh = after(e.ok, Level::Low);
                }
                (Line::Echo, Act::Read(high)) => {
                    if e.ok && !high && self.init == Level::Low {
                        self.echo_checked = true;
                    }
                }
                (line, act) => panic!("event {n}: {act:?} on {line:?} is not something the driver does"),
            }
        }
    }

    /// The pings fired so far, leaving the list empty.
    pub fn take_fired(&mut self) -> Vec<Fired> {
        std::mem::take(&mut self.fired)
    }

    /// INIT dropped at the end, and BINH with it.
    pub fn assert_idle(&self) {
        assert_eq!((self.init, self.binh), (Level::Low, Level::Low), "the module did not end idle");
    }
}

/// The ring-down gap after each ping: from the end of its listening window
/// (`window_us` after INIT rose) to the next INIT rise, at least `gap_us`.
pub fn assert_gaps(fired: &[Fired], window_us: u32, gap_us: u32) {
    for w in fired.windows(2) {
        let gap = w[1].at.wrapping_sub(w[0].at) as i64 - i64::from(window_us);
        assert!(gap >= i64::from(gap_us), "gap of {gap} µs after the ping at {} (want {gap_us}): {w:?}", w[0].at);
    }
}

/// The mocks of one module (ECHO, INIT, BINH and address lines), the shared
/// log their recording pins write, and the protocol checker it feeds.
pub struct Pins<'c, const A: usize> {
    pub echo: Mock,
    pub init: Mock,
    pub binh: Mock,
    pub addr: [Mock; A],
    pub log: PinLog<'c>,
    pub protocol: Protocol,
}

impl<'c, const A: usize> Pins<'c, A> {
    pub fn new(s: &Scripts, clock: &'c MockClock) -> Self {
        Self {
            echo: Mock::new(&s.echo),
            init: Mock::new(&s.init),
            binh: Mock::new(&s.binh),
            addr: std::array::from_fn(|i| Mock::new(s.addr.get(i).map_or(&[][..], |v| &v[..]))),
            log: PinLog::new(clock),
            protocol: Protocol::new(A),
        }
    }

    /// Recording pins for the driver (their mocks share the expectations).
    #[allow(clippy::type_complexity)]
    pub fn clones(&self) -> (RecPin<'c>, RecPin<'c>, RecPin<'c>, [RecPin<'c>; A]) {
        (
            self.log.pin(Line::Echo, self.echo.clone()),
            self.log.pin(Line::Init, self.init.clone()),
            self.log.pin(Line::Binh, self.binh.clone()),
            std::array::from_fn(|i| self.log.pin(Line::Addr(i as u8), self.addr[i].clone())),
        )
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

    /// Check the pin operations logged since the last call against the
    /// protocol; returns the pings fired in them.
    pub fn check(&mut self) -> Vec<Fired> {
        let events = self.log.take();
        self.protocol.feed(&events);
        self.protocol.take_fired()
    }

    /// Every script used up, the protocol kept, the module idle at the end;
    /// returns the pings fired since the last check.
    pub fn done(&mut self) -> Vec<Fired> {
        let fired = self.done_in_flight();
        self.protocol.assert_idle();
        fired
    }

    /// As [`Pins::done`], for a module given up with a ping in flight.
    pub fn done_in_flight(&mut self) -> Vec<Fired> {
        self.echo.done();
        self.init.done();
        self.binh.done();
        for a in &mut self.addr {
            a.done();
        }
        self.check()
    }
}
