//! The driver for async executors (embassy and the like), over
//! `embedded-hal-async`: ECHO is awaited with [`Wait::wait_for_high`] raced
//! against an async delay to the next deadline, instead of being polled.
//!
//! Nothing of the ranging is written twice. The async types wrap the
//! blocking [`Module`] and [`Ring`] and only *wait*: a ping starts with
//! `Module::start` (or `Ring::poll` when its slot is due); when ECHO rises,
//! the clock is read at once and the edge goes to `echo_captured`, the same
//! classification an input-capture board uses (blanking, window, range);
//! when a deadline passes (BINH's time, the end of the window) the blocking
//! `poll` runs, which raises BINH or ends the ping with "no echo". The
//! schedule, lateness, re-anchoring and EERUF are the [`Ring`]'s own.
//!
//! Every wait is bounded: by the window's end on the clock, and by a count
//! of wake-ups, after which a clock that does not move gives
//! [`Error::ClockStalled`].
//!
//! ```
//! # use core::convert::Infallible;
//! # use core::cell::Cell;
//! # use core::future::Future;
//! # use core::pin::pin;
//! # use core::task::{Context, Poll, Waker};
//! # use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
//! use echoloc::driver::{AsyncModule, Clock, Echo, Module, ModuleConfig, NoPin, SpeedOfSound};
//! # struct World { now: Cell<u32>, fired: Cell<Option<u32>> }
//! # impl Clock for World { fn now_us(&self) -> u32 { self.now.get() } }
//! # struct Init<'a>(&'a World);
//! # impl ErrorType for Init<'_> { type Error = Infallible; }
//! # impl OutputPin for Init<'_> {
//! #     fn set_low(&mut self) -> Result<(), Infallible> { self.0.fired.set(None); Ok(()) }
//! #     fn set_high(&mut self) -> Result<(), Infallible> { self.0.fired.set(Some(self.0.now.get())); Ok(()) }
//! # }
//! # /// A wall 1.5 m away: ECHO rises 8 741 µs after INIT.
//! # struct EchoPin<'a>(&'a World);
//! # impl EchoPin<'_> { fn high(&self) -> bool { self.0.fired.get().is_some_and(|f| self.0.now.get() - f >= 8_741) } }
//! # impl ErrorType for EchoPin<'_> { type Error = Infallible; }
//! # impl InputPin for EchoPin<'_> {
//! #     fn is_high(&mut self) -> Result<bool, Infallible> { Ok(self.high()) }
//! #     fn is_low(&mut self) -> Result<bool, Infallible> { Ok(!self.high()) }
//! # }
//! # impl embedded_hal_async::digital::Wait for EchoPin<'_> {
//! #     async fn wait_for_high(&mut self) -> Result<(), Infallible> {
//! #         core::future::poll_fn(|_| if self.high() { Poll::Ready(Ok(())) } else { Poll::Pending }).await
//! #     }
//! #     async fn wait_for_low(&mut self) -> Result<(), Infallible> { unimplemented!() }
//! #     async fn wait_for_rising_edge(&mut self) -> Result<(), Infallible> { unimplemented!() }
//! #     async fn wait_for_falling_edge(&mut self) -> Result<(), Infallible> { unimplemented!() }
//! #     async fn wait_for_any_edge(&mut self) -> Result<(), Infallible> { unimplemented!() }
//! # }
//! # /// A delay that lets virtual time pass, up to the echo's edge if that comes first.
//! # struct Sleep<'a>(&'a World);
//! # impl embedded_hal_async::delay::DelayNs for Sleep<'_> {
//! #     async fn delay_ns(&mut self, ns: u32) {
//! #         let w = self.0;
//! #         let end = w.now.get() + ns.div_ceil(1000);
//! #         core::future::poll_fn(|_| {
//! #             let edge = w.fired.get().map(|f| f + 8_741).filter(|&e| e > w.now.get() && e < end);
//! #             match edge { Some(e) => { w.now.set(e); Poll::Pending } None => { w.now.set(end); Poll::Ready(()) } }
//! #         }).await
//! #     }
//! # }
//! # fn block_on<F: Future>(f: F) -> F::Output {
//! #     let mut f = pin!(f);
//! #     let mut cx = Context::from_waker(Waker::noop());
//! #     loop { if let Poll::Ready(v) = f.as_mut().poll(&mut cx) { return v; } }
//! # }
//! let world = World { now: Cell::new(0), fired: Cell::new(None) };
//! let timing = ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(2000).unwrap()).timing().unwrap();
//! let no_mux: [NoPin<Infallible>; 0] = [];
//! let module = Module::new(Init(&world), EchoPin(&world), no_mux, &world, timing);
//! let mut sonar = AsyncModule::new(module, Sleep(&world));
//! // The edge is awaited, not polled: timed to the microsecond.
//! let echo = block_on(sonar.measure(0)).unwrap();
//! assert_eq!(echo, Echo::Range { range_mm: timing.sound().range_mm(8_741), tof_us: 8_741 });
//! ```

use core::future::{poll_fn, Future};
use core::pin::pin;
use core::task::Poll;

use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::digital::Wait;

use super::clock::{elapsed, reached, Clock};
use super::error::Error;
use super::module::{Echo, Module};
use super::ring::{Ring, RingReading};

/// Wake-ups one ping or one slot may take before the clock is deemed
/// stalled: a slot needs at most three (its firing time, BINH, the window's
/// end), and a few more for a delay that returned a little early.
const MAX_WAKES: u32 = 16;

enum Either<A, B> {
    Left(A),
    Right(B),
}

/// The first of two futures to finish; the other is dropped.
async fn select<A: Future, B: Future>(a: A, b: B) -> Either<A::Output, B::Output> {
    let mut a = pin!(a);
    let mut b = pin!(b);
    poll_fn(|cx| {
        if let Poll::Ready(x) = a.as_mut().poll(cx) {
            return Poll::Ready(Either::Left(x));
        }
        if let Poll::Ready(y) = b.as_mut().poll(cx) {
            return Poll::Ready(Either::Right(y));
        }
        Poll::Pending
    })
    .await
}

/// What ended a wait on a ping in flight.
enum Wake {
    /// ECHO rose; the clock read right after.
    Edge(u32),
    /// The next deadline (BINH's time or the window's end) passed.
    Deadline,
}

/// Waits for ECHO or the ping's next deadline, whichever comes first.
async fn wait_ping<INIT, ECHO, BINH, ADDR, CLK, D, E, const A: usize>(
    module: &mut Module<INIT, ECHO, BINH, ADDR, CLK, A>,
    delay: &mut D,
) -> Result<Wake, Error<E>>
where
    INIT: OutputPin<Error = E>,
    ECHO: InputPin<Error = E> + Wait<Error = E>,
    BINH: OutputPin<Error = E>,
    ADDR: OutputPin<Error = E>,
    CLK: Clock,
    D: DelayNs,
    E: embedded_hal::digital::Error,
{
    let Some((fired_at, binh_pending)) = module.listening() else {
        return Err(Error::Idle);
    };
    let timing = *module.timing();
    let el = elapsed(fired_at, module.now_us());
    // The blocking poll ends the window when `el >= window`, and raises BINH at `el >= after`.
    let deadline = match timing.binh_after_us() {
        Some(after) if binh_pending && after > el => after,
        _ => timing.window_us(),
    };
    let wait_us = deadline.saturating_sub(el).max(1);
    let woke = select(module.echo_mut().wait_for_high(), delay.delay_us(wait_us)).await;
    match woke {
        // Clock right after the edge: what an interrupt's stamp would read.
        Either::Left(Ok(())) => Ok(Wake::Edge(module.now_us())),
        Either::Left(Err(e)) => Err(module.abort_pin(e)),
        Either::Right(()) => Ok(Wake::Deadline),
    }
}

/// A ranging [`Module`] whose ECHO line can be awaited, with an async delay.
#[derive(Debug)]
pub struct AsyncModule<INIT, ECHO, BINH, ADDR, CLK, D, const A: usize> {
    module: Module<INIT, ECHO, BINH, ADDR, CLK, A>,
    delay: D,
}

impl<INIT, ECHO, BINH, ADDR, CLK, D, E, const A: usize> AsyncModule<INIT, ECHO, BINH, ADDR, CLK, D, A>
where
    INIT: OutputPin<Error = E>,
    ECHO: InputPin<Error = E> + Wait<Error = E>,
    BINH: OutputPin<Error = E>,
    ADDR: OutputPin<Error = E>,
    CLK: Clock,
    D: DelayNs,
    E: embedded_hal::digital::Error,
{
    /// Over a blocking module (its pins, clock and timing) and a delay.
    pub fn new(module: Module<INIT, ECHO, BINH, ADDR, CLK, A>, delay: D) -> Self {
        Self { module, delay }
    }

    /// Fires `transducer` and awaits the outcome: the echo's edge, or the
    /// end of the window. Faults and pin errors as [`Module::start`] and
    /// [`Module::poll`] give them; the module is idle afterwards.
    pub async fn measure(&mut self, transducer: u8) -> Result<Echo, Error<E>> {
        self.module.start(transducer)?;
        for _ in 0..MAX_WAKES {
            match wait_ping(&mut self.module, &mut self.delay).await? {
                Wake::Edge(at) => return self.module.echo_captured(at),
                Wake::Deadline => {
                    if let Some(echo) = self.module.poll()? {
                        return Ok(echo);
                    }
                }
            }
        }
        self.module.cancel()?;
        Err(Error::ClockStalled)
    }

    /// The blocking module, for what the async flavour does not wrap
    /// (`select`, `cancel`, its timing).
    pub fn module(&mut self) -> &mut Module<INIT, ECHO, BINH, ADDR, CLK, A> {
        &mut self.module
    }

    /// The module and the delay back.
    pub fn release(self) -> (Module<INIT, ECHO, BINH, ADDR, CLK, A>, D) {
        (self.module, self.delay)
    }
}

/// A [`Ring`] driven by awaiting: the delay until each slot is due, then
/// ECHO or the window's end.
#[derive(Debug)]
pub struct AsyncRing<INIT, ECHO, BINH, ADDR, CLK, D, const A: usize, const N: usize> {
    ring: Ring<INIT, ECHO, BINH, ADDR, CLK, A, N>,
    delay: D,
}

impl<INIT, ECHO, BINH, ADDR, CLK, D, E, const A: usize, const N: usize> AsyncRing<INIT, ECHO, BINH, ADDR, CLK, D, A, N>
where
    INIT: OutputPin<Error = E>,
    ECHO: InputPin<Error = E> + Wait<Error = E>,
    BINH: OutputPin<Error = E>,
    ADDR: OutputPin<Error = E>,
    CLK: Clock,
    D: DelayNs,
    E: embedded_hal::digital::Error,
{
    /// Over a blocking ring (module, schedule, timing) and a delay.
    pub fn new(ring: Ring<INIT, ECHO, BINH, ADDR, CLK, A, N>, delay: D) -> Self {
        Self { ring, delay }
    }

    /// The next reading: waits until the slot is due, fires it, awaits its
    /// echo or the window's end. A pin error is returned as the blocking
    /// [`Ring::poll`] returns it (the ring moves on as it does there).
    pub async fn next(&mut self) -> Result<RingReading, Error<E>> {
        for _ in 0..MAX_WAKES {
            if self.ring.in_flight() {
                match wait_ping(self.ring.module_mut(), &mut self.delay).await? {
                    Wake::Edge(at) => return self.ring.echo_captured(at),
                    Wake::Deadline => {}
                }
            } else if let Some(due) = self.ring.next_fire_us() {
                let now = self.ring.module_mut().now_us();
                if !reached(now, due) {
                    self.delay.delay_us(elapsed(now, due)).await;
                }
            }
            // Fires a due slot, or ends a window that has passed.
            if let Some(r) = self.ring.poll()? {
                return Ok(r);
            }
        }
        Err(Error::ClockStalled)
    }

    /// The blocking ring: its schedule, timing, `reset`.
    pub fn ring(&mut self) -> &mut Ring<INIT, ECHO, BINH, ADDR, CLK, A, N> {
        &mut self.ring
    }

    /// The ring and the delay back.
    pub fn release(self) -> (Ring<INIT, ECHO, BINH, ADDR, CLK, A, N>, D) {
        (self.ring, self.delay)
    }
}
