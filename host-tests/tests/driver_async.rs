//! The async driver (`AsyncModule`, `AsyncRing`, feature `async`) on
//! scripted async pins: the blocking driver's fault table again, and a
//! differential run in which the blocking `Ring` and the `AsyncRing` see
//! the same echoes and must give the same readings.
//!
//! The world: a virtual µs clock; INIT, BINH and address lines that record
//! what the driver did; an ECHO line that rises a scripted time of flight
//! after INIT (per transducer and cycle); an async delay that lets time pass
//! up to the next ECHO edge or its end, whichever comes first (as an
//! executor woken by the edge's interrupt would); a `block_on` with a poll
//! budget, so a hang fails the test instead of stalling it.

use core::cell::Cell;
use core::future::{poll_fn, Future};
use core::pin::pin;
use core::task::{Context, Poll, Waker};

use echoloc::driver::{
    AsyncModule, AsyncRing, Clock, Echo, Eeruf, Error, Fault, Module, ModuleConfig, NoPin, Outcome, Ring, RingConfig,
    RingReading, Schedule, SpeedOfSound, Timing,
};
use embedded_hal::digital::{ErrorKind, ErrorType, InputPin, OutputPin};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PinError;
impl embedded_hal::digital::Error for PinError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// Time of flight of transducer `t` in cycle `c`, µs (None: no echo).
type Scene = fn(u8, u32) -> Option<u32>;

struct World {
    now: Cell<u32>,
    fired: Cell<Option<(u8, u32)>>,
    addr: Cell<u8>,
    binh_rose: Cell<Option<u32>>,
    binh_high: Cell<bool>,
    pings: Cell<u32>,
    scene: Cell<Scene>,
    cycle_of_ping: fn(u32) -> u32,
    stuck_high: Cell<bool>,
    fail_init: Cell<u32>,
    fail_addr: Cell<u32>,
    fail_wait: Cell<bool>,
    frozen: Cell<bool>,
}

impl World {
    fn new(scene: Scene, cycle_of_ping: fn(u32) -> u32) -> Self {
        Self {
            now: Cell::new(1_000),
            fired: Cell::new(None),
            addr: Cell::new(0),
            binh_rose: Cell::new(None),
            binh_high: Cell::new(false),
            pings: Cell::new(0),
            scene: Cell::new(scene),
            cycle_of_ping,
            stuck_high: Cell::new(false),
            fail_init: Cell::new(0),
            fail_addr: Cell::new(0),
            fail_wait: Cell::new(false),
            frozen: Cell::new(false),
        }
    }

    /// When ECHO rises for the ping in flight.
    fn edge(&self) -> Option<u32> {
        let (t, at) = self.fired.get()?;
        let cycle = (self.cycle_of_ping)(self.pings.get().saturating_sub(1));
        (self.scene.get())(t, cycle).map(|tof| at + tof)
    }

    fn echo_high(&self) -> bool {
        self.stuck_high.get() || self.edge().is_some_and(|e| self.now.get() >= e)
    }

    /// The blocking loop's sleep: to the slot's time, or during a ping to
    /// the edge or 1 ms on (as `scenario::replay::Bench::wait`).
    fn sleep(&self, next_fire: Option<u32>) {
        let now = self.now.get();
        let to = match (self.fired.get(), self.edge()) {
            (Some(_), Some(e)) if e > now && e < now + 1_000 => e,
            (Some(_), _) => now + 1_000,
            (None, _) => next_fire.filter(|&d| d > now).unwrap_or(now + 1_000),
        };
        self.now.set(to);
    }
}

impl Clock for World {
    fn now_us(&self) -> u32 {
        self.now.get()
    }
}

struct Init<'a>(&'a World);
impl ErrorType for Init<'_> {
    type Error = PinError;
}
impl OutputPin for Init<'_> {
    fn set_low(&mut self) -> Result<(), PinError> {
        self.0.fired.set(None);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), PinError> {
        if self.0.fail_init.get() > 0 {
            self.0.fail_init.set(self.0.fail_init.get() - 1);
            return Err(PinError);
        }
        self.0.fired.set(Some((self.0.addr.get(), self.0.now.get())));
        self.0.pings.set(self.0.pings.get() + 1);
        Ok(())
    }
}

struct Binh<'a>(&'a World);
impl ErrorType for Binh<'_> {
    type Error = PinError;
}
impl OutputPin for Binh<'_> {
    fn set_low(&mut self) -> Result<(), PinError> {
        self.0.binh_high.set(false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), PinError> {
        self.0.binh_high.set(true);
        self.0.binh_rose.set(Some(self.0.now.get()));
        Ok(())
    }
}

struct Addr<'a>(&'a World, u8);
impl ErrorType for Addr<'_> {
    type Error = PinError;
}
impl OutputPin for Addr<'_> {
    fn set_low(&mut self) -> Result<(), PinError> {
        if self.0.fail_addr.get() > 0 {
            self.0.fail_addr.set(self.0.fail_addr.get() - 1);
            return Err(PinError);
        }
        self.0.addr.set(self.0.addr.get() & !(1 << self.1));
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), PinError> {
        self.0.addr.set(self.0.addr.get() | (1 << self.1));
        Ok(())
    }
}

struct EchoPin<'a>(&'a World);
impl ErrorType for EchoPin<'_> {
    type Error = PinError;
}
impl InputPin for EchoPin<'_> {
    fn is_high(&mut self) -> Result<bool, PinError> {
        Ok(self.0.echo_high())
    }
    fn is_low(&mut self) -> Result<bool, PinError> {
        Ok(!self.0.echo_high())
    }
}
impl embedded_hal_async::digital::Wait for EchoPin<'_> {
    async fn wait_for_high(&mut self) -> Result<(), PinError> {
        let w = self.0;
        poll_fn(|_| {
            if w.fail_wait.get() {
                Poll::Ready(Err(PinError))
            } else if w.echo_high() {
                Poll::Ready(Ok(()))
            } else {
                Poll::Pending
            }
        })
        .await
    }
    async fn wait_for_low(&mut self) -> Result<(), PinError> {
        let w = self.0;
        poll_fn(|_| if w.echo_high() { Poll::Pending } else { Poll::Ready(Ok(())) }).await
    }
    async fn wait_for_rising_edge(&mut self) -> Result<(), PinError> {
        self.wait_for_low().await?;
        self.wait_for_high().await
    }
    async fn wait_for_falling_edge(&mut self) -> Result<(), PinError> {
        self.wait_for_high().await?;
        self.wait_for_low().await
    }
    async fn wait_for_any_edge(&mut self) -> Result<(), PinError> {
        if self.0.echo_high() {
            self.wait_for_low().await
        } else {
            self.wait_for_high().await
        }
    }
}

/// Lets time pass: to the end, or to an ECHO edge before it (then Pending,
/// so the select sees the edge first). A frozen world's delay returns at once.
struct Sleep<'a>(&'a World);
impl embedded_hal_async::delay::DelayNs for Sleep<'_> {
    async fn delay_ns(&mut self, ns: u32) {
        let w = self.0;
        let end = w.now.get() + ns.div_ceil(1_000);
        poll_fn(|_| {
            if w.frozen.get() {
                return Poll::Ready(());
            }
            match w.edge().filter(|&e| e > w.now.get() && e < end) {
                Some(e) => {
                    w.now.set(e);
                    Poll::Pending
                }
                None => {
                    w.now.set(end.max(w.now.get()));
                    Poll::Ready(())
                }
            }
        })
        .await
    }
}

fn block_on<F: Future>(f: F) -> F::Output {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    for _ in 0..100_000 {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
    panic!("the future did not finish: a hang");
}

fn timing(centi_c: i16, binh: Option<u32>) -> Timing {
    let sound = SpeedOfSound::at_centi_celsius(centi_c).unwrap();
    ModuleConfig { binh_after_us: binh, ..ModuleConfig::polaroid_6500(sound) }.timing().unwrap()
}

type Mod<'a> = Module<Init<'a>, EchoPin<'a>, Binh<'a>, Addr<'a>, &'a World, 2>;

fn module(w: &World, t: Timing) -> Mod<'_> {
    Module::new(Init(w), EchoPin(w), [Addr(w, 0), Addr(w, 1)], w, t).with_binh(Binh(w))
}

fn scene_fixed(tof: Option<u32>) -> Scene {
    // One scene per case, as plain fns.
    match tof {
        Some(3_000) => |_, _| Some(3_000),
        Some(8_741) => |_, _| Some(8_741),
        Some(20_000) => |_, _| Some(20_000),
        Some(1_000) => |_, _| Some(1_000),
        Some(1_200) => |_, _| Some(1_200),
        _ => |_, _| None,
    }
}

#[test]
fn normal_pings_at_several_ranges_and_temperatures() {
    for centi_c in [-1_000, 2_000, 4_000] {
        for tof in [3_000, 8_741, 20_000] {
            let w = World::new(scene_fixed(Some(tof)), |_| 0);
            let t = timing(centi_c, None);
            let mut m = AsyncModule::new(module(&w, t), Sleep(&w));
            let echo = block_on(m.measure(2)).unwrap();
            assert_eq!(echo, Echo::Range { range_mm: t.sound().range_mm(tof), tof_us: tof }, "{centi_c} {tof}");
            assert_eq!(w.fired.get(), None, "INIT low after the ping");
            assert!(m.module().is_idle());
        }
    }
}

#[test]
fn no_echo_ends_with_the_window() {
    let w = World::new(scene_fixed(None), |_| 0);
    let t = timing(2_000, None);
    let mut m = AsyncModule::new(module(&w, t), Sleep(&w));
    let start = w.now.get();
    assert_eq!(block_on(m.measure(1)), Ok(Echo::NoEcho));
    let took = w.now.get() - start;
    assert!(took >= t.window_us() && took <= t.window_us() + 1, "ended {took} µs after firing");
    assert!(m.module().is_idle());
}

#[test]
fn stuck_high_echo_refuses_the_ping_then_recovers() {
    let w = World::new(scene_fixed(Some(3_000)), |_| 0);
    let mut m = AsyncModule::new(module(&w, timing(2_000, None)), Sleep(&w));
    w.stuck_high.set(true);
    assert_eq!(block_on(m.measure(0)), Err(Error::Fault(Fault::EchoStuckHigh)));
    assert_eq!(w.pings.get(), 0, "nothing fired");
    w.stuck_high.set(false);
    assert!(matches!(block_on(m.measure(0)), Ok(Echo::Range { tof_us: 3_000, .. })));
}

#[test]
fn echo_inside_blanking_is_a_fault_and_the_module_stops() {
    let w = World::new(scene_fixed(Some(1_000)), |_| 0);
    let mut m = AsyncModule::new(module(&w, timing(2_000, None)), Sleep(&w));
    assert_eq!(block_on(m.measure(3)), Err(Error::Fault(Fault::EchoInBlanking { tof_us: 1_000 })));
    assert_eq!(w.fired.get(), None);
    assert!(m.module().is_idle());
}

#[test]
fn binh_shortens_blanking_and_is_dropped_after() {
    let w = World::new(scene_fixed(Some(1_200)), |_| 0);
    let t = timing(2_000, Some(1_000));
    let mut m = AsyncModule::new(module(&w, t), Sleep(&w));
    let fired = w.now.get();
    assert_eq!(block_on(m.measure(0)), Ok(Echo::Range { range_mm: t.sound().range_mm(1_200), tof_us: 1_200 }));
    assert_eq!(w.binh_rose.get(), Some(fired + 1_000), "BINH rose at its time, woken by the deadline");
    assert!(!w.binh_high.get(), "and fell with the ping");
}

#[test]
fn pin_errors_leave_a_clean_idle() {
    let w = World::new(scene_fixed(Some(3_000)), |_| 0);
    let mut m = AsyncModule::new(module(&w, timing(2_000, None)), Sleep(&w));
    // INIT fails to rise.
    w.fail_init.set(1);
    assert_eq!(block_on(m.measure(1)), Err(Error::Pin(PinError)));
    assert!(m.module().is_idle());
    assert!(matches!(block_on(m.measure(1)), Ok(Echo::Range { .. })));
    // The wait on ECHO fails mid-ping.
    w.fail_wait.set(true);
    assert_eq!(block_on(m.measure(2)), Err(Error::Pin(PinError)));
    assert_eq!(w.fired.get(), None, "INIT dropped");
    assert!(m.module().is_idle());
    w.fail_wait.set(false);
    // An address line fails.
    w.fail_addr.set(1);
    assert_eq!(block_on(m.measure(0)), Err(Error::Pin(PinError)));
    assert!(matches!(block_on(m.measure(0)), Ok(Echo::Range { .. })));
}

#[test]
fn a_stalled_clock_ends_the_wait() {
    let w = World::new(scene_fixed(None), |_| 0);
    let mut m = AsyncModule::new(module(&w, timing(2_000, None)), Sleep(&w));
    w.frozen.set(true);
    assert_eq!(block_on(m.measure(0)), Err(Error::ClockStalled));
    assert!(m.module().is_idle());
    assert_eq!(w.fired.get(), None);
}

/// 16 transducers, 4 address lines: echoes that move a little from cycle to
/// cycle (EERUF confirms), silences, a jump (crosstalk) and echoes near the
/// window's edges.
fn ring_scene(t: u8, c: u32) -> Option<u32> {
    if t.is_multiple_of(5) && c % 2 == 1 {
        return None;
    }
    let base = 2_500 + 1_700 * u32::from(t);
    let jump = if t == 7 && c == 2 { 3_000 } else { 0 };
    Some(base + 20 * (c % 3) + jump)
}

type Ring16<'a> = Ring<Init<'a>, EchoPin<'a>, NoPin<PinError>, Addr<'a>, &'a World, 4, 16>;

fn ring16(w: &World) -> Ring16<'_> {
    let t = timing(2_000, None);
    let rt = RingConfig { ring_down_us: 5_000, eeruf: Some(Eeruf { alternating_us: 1_000, tolerance_mm: 50 }) }
        .timing::<16>(&t)
        .unwrap();
    let module = Module::new(Init(w), EchoPin(w), [Addr(w, 0), Addr(w, 1), Addr(w, 2), Addr(w, 3)], w, t);
    Ring::new(module, Schedule::spread(), rt)
}

#[test]
fn async_ring_gives_the_blocking_rings_readings() {
    const READINGS: usize = 16 * 5;
    let w = World::new(ring_scene, |ping| ping / 16);
    let mut ring = ring16(&w);
    let mut blocking: Vec<RingReading> = Vec::new();
    while blocking.len() < READINGS {
        match ring.poll().unwrap() {
            Some(r) => blocking.push(r),
            None => w.sleep(ring.next_fire_us()),
        }
    }
    let w2 = World::new(ring_scene, |ping| ping / 16);
    let mut aring = AsyncRing::new(ring16(&w2), Sleep(&w2));
    let asynced: Vec<RingReading> = (0..READINGS).map(|_| block_on(aring.next()).unwrap()).collect();
    assert_eq!(asynced, blocking);
    // The scene exercised what it should: confirmations, silences, crosstalk.
    let count = |f: fn(&Outcome) -> bool| blocking.iter().filter(|r| f(&r.outcome)).count();
    assert!(count(|o| matches!(o, Outcome::Range { .. })) >= 30);
    assert!(count(|o| matches!(o, Outcome::NoEcho)) >= 4);
    // The jump disagrees with the reading before it, and the next reading with the jump.
    assert_eq!(count(|o| matches!(o, Outcome::Crosstalk { .. })), 2);
    assert!(blocking.iter().all(|r| r.late_us == 0));
}

#[test]
fn async_ring_pin_error_while_firing_retries_the_slot() {
    let w = World::new(ring_scene, |ping| ping / 16);
    let mut aring = AsyncRing::new(ring16(&w), Sleep(&w));
    let first = block_on(aring.next()).unwrap();
    w.fail_init.set(1);
    assert_eq!(block_on(aring.next()), Err(Error::Pin(PinError)));
    let again = block_on(aring.next()).unwrap();
    assert_eq!((first.slot, again.slot), (0, 1), "the failed slot fired on the next call");
    w.frozen.set(true);
    assert_eq!(block_on(aring.next()), Err(Error::ClockStalled));
}
