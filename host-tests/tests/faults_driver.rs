//! A pin fault at every step of a ping (issue #14 item 3): the mock HAL
//! below counts every pin operation across INIT, ECHO and the address lines
//! and fails exactly the k-th, for every k a clean ping makes, with the
//! failed write either taking effect on the line or not (a real GPIO may do
//! either). For each: the ping ends with the HAL's own error, the module is
//! idle, the physical protocol holds throughout (no burst without a rising
//! INIT, the multiplexer never switched under a raised INIT, the right
//! transducer addressed when INIT rises), and the next ping returns exactly
//! what a module that never faulted returns.
//!
//! The mock is a small model of the hardware written for this test (ECHO
//! rises a time of flight after INIT rises and falls with INIT), not the
//! scripted mocks of the other driver tests, so that a fault can land on any
//! operation without rewriting a script per case.

use std::cell::RefCell;
use std::rc::Rc;

use echoloc::driver::{Clock, Echo, Error, Module, ModuleConfig, NoPin, SpeedOfSound, Timing};
use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{ErrorKind, ErrorType, InputPin, OutputPin};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PinFault;

impl embedded_hal::digital::Error for PinFault {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

#[derive(Default)]
struct World {
    now: u32,
    ops: usize,
    fail_at: Option<usize>,
    fail_applies: bool,
    init: bool,
    addr: [bool; 2],
    fired: Vec<(u32, u8)>,
    tof_us: u32,
    violations: Vec<String>,
}

impl World {
    /// Counts one pin operation; `Err` when it is the one to fail, with
    /// whether a failing write still reaches the line.
    fn op(&mut self) -> Result<(), bool> {
        let k = self.ops;
        self.ops += 1;
        if self.fail_at == Some(k) {
            Err(self.fail_applies)
        } else {
            Ok(())
        }
    }
    fn echo_high(&self) -> bool {
        self.init && self.fired.last().is_some_and(|&(t, _)| self.now.wrapping_sub(t) >= self.tof_us)
    }
    fn set_init(&mut self, high: bool) {
        if high && self.init {
            self.violations.push(format!("INIT raised at {} while already high: no burst", self.now));
        }
        if high && !self.init {
            let t = self.addr.iter().enumerate().map(|(k, &b)| u8::from(b) << k).sum();
            self.fired.push((self.now, t));
        }
        self.init = high;
    }
    fn set_addr(&mut self, k: usize, high: bool) {
        if self.init && self.addr[k] != high {
            self.violations.push(format!("address line {k} moved under a raised INIT at {}", self.now));
        }
        self.addr[k] = high;
    }
}

type W = Rc<RefCell<World>>;

struct Init(W);
struct Echo_(W);
struct Addr(W, usize);
struct Clk(W);

impl ErrorType for Init {
    type Error = PinFault;
}
impl ErrorType for Echo_ {
    type Error = PinFault;
}
impl ErrorType for Addr {
    type Error = PinFault;
}

fn write(w: &W, f: impl FnOnce(&mut World)) -> Result<(), PinFault> {
    let mut w = w.borrow_mut();
    match w.op() {
        Ok(()) => {
            f(&mut w);
            Ok(())
        }
        Err(applies) => {
            if applies {
                f(&mut w);
            }
            Err(PinFault)
        }
    }
}

impl OutputPin for Init {
    fn set_low(&mut self) -> Result<(), PinFault> {
        write(&self.0, |w| w.set_init(false))
    }
    fn set_high(&mut self) -> Result<(), PinFault> {
        write(&self.0, |w| w.set_init(true))
    }
}
impl OutputPin for Addr {
    fn set_low(&mut self) -> Result<(), PinFault> {
        let k = self.1;
        write(&self.0, |w| w.set_addr(k, false))
    }
    fn set_high(&mut self) -> Result<(), PinFault> {
        let k = self.1;
        write(&self.0, |w| w.set_addr(k, true))
    }
}
impl InputPin for Echo_ {
    fn is_high(&mut self) -> Result<bool, PinFault> {
        let mut w = self.0.borrow_mut();
        w.op().map_err(|_| PinFault)?;
        Ok(w.echo_high())
    }
    fn is_low(&mut self) -> Result<bool, PinFault> {
        self.is_high().map(|h| !h)
    }
}
impl Clock for Clk {
    fn now_us(&self) -> u32 {
        self.0.borrow().now
    }
}

/// The blocking wait's delay: time passes in the world.
struct Delay(W);
impl DelayNs for Delay {
    fn delay_ns(&mut self, ns: u32) {
        let mut w = self.0.borrow_mut();
        w.now = w.now.wrapping_add(ns.div_ceil(1000));
    }
}

type M = Module<Init, Echo_, NoPin<PinFault>, Addr, Clk, 2>;

fn timing() -> Timing {
    ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(2000).unwrap()).timing().unwrap()
}

fn module(w: &W) -> M {
    Module::new(Init(w.clone()), Echo_(w.clone()), [Addr(w.clone(), 0), Addr(w.clone(), 1)], Clk(w.clone()), timing())
}

const POLL_US: u32 = 100;

/// One ping of `transducer` by `start` and polls every 100 µs, bounded.
fn ping(m: &mut M, w: &W, transducer: u8) -> Result<Echo, Error<PinFault>> {
    m.start(transducer)?;
    for _ in 0..1_000 {
        w.borrow_mut().now += POLL_US;
        if let Some(e) = m.poll()? {
            return Ok(e);
        }
    }
    panic!("a ping did not end within 1000 polls");
}

fn world(tof_us: u32) -> W {
    Rc::new(RefCell::new(World { now: 10_000, tof_us, ..World::default() }))
}

/// What a module that never faulted reads on the second ping.
fn reference(tof_us: u32, first: u8, second: u8, blocking: bool) -> (Echo, usize) {
    let w = world(tof_us);
    let mut m = module(&w);
    let a = if blocking { m.measure(first, &mut Delay(w.clone()), POLL_US) } else { ping(&mut m, &w, first) };
    let ops = w.borrow().ops;
    assert!(matches!(a, Ok(Echo::Range { .. })), "{a:?}");
    w.borrow_mut().now += 50_000;
    let b = if blocking { m.measure(second, &mut Delay(w.clone()), POLL_US) } else { ping(&mut m, &w, second) };
    assert!(w.borrow().violations.is_empty());
    (b.unwrap(), ops)
}

fn fault_at_every_step(blocking: bool) {
    let tof_us = 6_000; // about 1 m
    for (first, second) in [(2u8, 1u8), (3, 3), (0, 2)] {
        let (want, ops) = reference(tof_us, first, second, blocking);
        assert!(ops > 50, "a clean ping made only {ops} pin operations");
        for k in 0..ops {
            for applies in [false, true] {
                let w = world(tof_us);
                w.borrow_mut().fail_at = Some(k);
                w.borrow_mut().fail_applies = applies;
                let mut m = module(&w);
                let case =
                    format!("ping {first} then {second}, operation {k} of {ops} fails (write applied: {applies})");
                let r =
                    if blocking { m.measure(first, &mut Delay(w.clone()), POLL_US) } else { ping(&mut m, &w, first) };
                assert_eq!(r, Err(Error::Pin(PinFault)), "{case}");
                assert!(m.is_idle(), "{case}: not idle after the fault");
                // The next ping, with the HAL healthy again, reads what a
                // module that never faulted reads.
                w.borrow_mut().fail_at = None;
                w.borrow_mut().now += 50_000;
                let r =
                    if blocking { m.measure(second, &mut Delay(w.clone()), POLL_US) } else { ping(&mut m, &w, second) };
                assert_eq!(r, Ok(want), "{case}: the next ping");
                let w = w.borrow();
                assert!(w.violations.is_empty(), "{case}: {:?}", w.violations);
                assert_eq!(w.fired.last().map(|f| f.1), Some(second), "{case}: the wrong transducer fired");
                assert!(!w.init, "{case}: INIT left high after the next ping");
            }
        }
    }
}

#[test]
fn a_pin_fault_at_every_step_of_a_polled_ping_is_reported_and_the_next_ping_is_clean() {
    fault_at_every_step(false);
}

#[test]
fn a_pin_fault_at_every_step_of_a_blocking_measure_is_reported_and_the_next_is_clean() {
    fault_at_every_step(true);
}
