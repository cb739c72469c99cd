//! One Polaroid 6500-class ranging module behind a transducer multiplexer.
//!
//! A ping: with INIT low, ECHO must read low (else [`Fault::EchoStuckHigh`]);
//! the address lines select the transducer; INIT rises and the module sends
//! its 16-cycle burst; ECHO rises on the first echo after blanking (which BINH
//! can end early); INIT falls, which also resets ECHO. The driver never
//! waits inside a call: [`Module::poll`] looks once and returns, and gives
//! "no echo" once the listening window has passed, so nothing can hang on a
//! silent module. A poll that comes too late to time an echo says so
//! ([`Echo::Untimed`]) rather than guess. A board with input capture hands the edge's time stamp to
//! [`Module::echo_captured`] instead of polling.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};

use super::clock::{elapsed, Clock};
use super::config::Timing;
use super::error::{Error, Fault};
use super::pin::NoPin;

/// What one ping found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Echo {
    /// An echo inside the window.
    Range {
        /// One-way range, mm.
        range_mm: u32,
        /// Round-trip time of flight, µs.
        tof_us: u32,
    },
    /// Nothing came back within the maximum range.
    NoEcho,
    /// ECHO was high at the first poll after the listening window had
    /// passed: something came back, but the poll was too late to say when
    /// (inside the window, or from beyond the maximum range). Not "no echo":
    /// a consumer must not read it as an empty cone.
    Untimed {
        /// Time from the ping to the poll that saw ECHO high, µs: the echo
        /// rose at or before this.
        seen_after_us: u32,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Idle,
    Listening {
        fired_at: u32,
        /// Elapsed µs at which blanking ended: internal blanking, or the
        /// moment BINH actually went high if that was sooner.
        blanking_end: u32,
    },
}

/// A ranging module: INIT, ECHO, optional BINH, `A` address lines selecting
/// one of `2^A` transducers, and a clock. Every pin shares the HAL error `E`
/// (use the HAL's type-erased pins for lines on different ports).
#[derive(Debug)]
pub struct Module<INIT, ECHO, BINH, ADDR, CLK, const A: usize> {
    init: INIT,
    echo: ECHO,
    binh: Option<BINH>,
    addr: [ADDR; A],
    clock: CLK,
    timing: Timing,
    phase: Phase,
    /// Which transducer the address lines select, `None` when a write failed
    /// (or none was made) and the lines must all be written again.
    selected: Option<u8>,
    /// INIT or BINH may be high after a failed write; drive them low before
    /// the next ping so that it starts from a clean idle.
    init_high: bool,
    binh_high: bool,
}

impl<INIT, ECHO, ADDR, CLK, E, const A: usize> Module<INIT, ECHO, NoPin<E>, ADDR, CLK, A>
where
    INIT: OutputPin<Error = E>,
    ECHO: InputPin<Error = E>,
    ADDR: OutputPin<Error = E>,
    CLK: Clock,
    E: embedded_hal::digital::Error,
{
    /// A module without a BINH line. `addr[k]` is address bit `k`.
    ///
    /// The pins are taken as they are: nothing is written until the first
    /// ping, which writes every address line.
    pub fn new(init: INIT, echo: ECHO, addr: [ADDR; A], clock: CLK, timing: Timing) -> Self {
        let () = Self::ADDR_OK;
        Self {
            init,
            echo,
            binh: None,
            addr,
            clock,
            timing,
            phase: Phase::Idle,
            selected: None,
            init_high: false,
            binh_high: false,
        }
    }

    /// The same module with a BINH line, raised `timing.binh_after_us()`
    /// after INIT (never, if that is `None`).
    pub fn with_binh<B>(self, binh: B) -> Module<INIT, ECHO, B, ADDR, CLK, A>
    where
        B: OutputPin<Error = E>,
    {
        Module {
            init: self.init,
            echo: self.echo,
            binh: Some(binh),
            addr: self.addr,
            clock: self.clock,
            timing: self.timing,
            phase: self.phase,
            selected: self.selected,
            init_high: self.init_high,
            binh_high: false,
        }
    }
}

impl<INIT, ECHO, BINH, ADDR, CLK, E, const A: usize> Module<INIT, ECHO, BINH, ADDR, CLK, A>
where
    INIT: OutputPin<Error = E>,
    ECHO: InputPin<Error = E>,
    BINH: OutputPin<Error = E>,
    ADDR: OutputPin<Error = E>,
    CLK: Clock,
    E: embedded_hal::digital::Error,
{
    /// Indices are `u8`: at most 8 address lines (checked at compile time).
    const ADDR_OK: () = assert!(A <= 8, "at most 8 address lines");

    /// How many transducers the address lines can select.
    pub const TRANSDUCERS: usize = 1 << A;

    /// The timing the module runs on.
    pub fn timing(&self) -> &Timing {
        &self.timing
    }

    /// The clock's current reading, µs.
    pub fn now_us(&self) -> u32 {
        self.clock.now_us()
    }

    /// Whether no ping is in flight.
    pub fn is_idle(&self) -> bool {
        matches!(self.phase, Phase::Idle)
    }

    /// Point the multiplexer at `transducer` now, ahead of its ping, so an
    /// analogue multiplexer can settle. Writes only the lines that change.
    ///
    /// If an earlier write left INIT (or BINH) possibly high, they are driven
    /// low first: the multiplexer is never switched under a raised INIT.
    pub fn select(&mut self, transducer: u8) -> Result<(), Error<E>> {
        self.prepare(transducer)?;
        self.select_lines(transducer)
    }

    /// What `select` and `start` both check and do first: idle (switching the
    /// multiplexer under a listening transducer would cut its echo off), a
    /// transducer that exists, and the leftovers of a stop whose writes
    /// failed driven low.
    fn prepare(&mut self, transducer: u8) -> Result<(), Error<E>> {
        if !self.is_idle() {
            return Err(Error::Busy);
        }
        if transducer as usize >= Self::TRANSDUCERS {
            return Err(Error::NoSuchTransducer(transducer));
        }
        self.settle_idle()
    }

    /// Drive low what a failed write may have left high: a ping must start
    /// with INIT low (else no rising edge) and BINH low (else no blanking),
    /// and the address lines must not move under a raised INIT.
    fn settle_idle(&mut self) -> Result<(), Error<E>> {
        if self.init_high {
            self.init.set_low().map_err(Error::Pin)?;
            self.init_high = false;
        }
        if self.binh_high {
            if let Some(b) = self.binh.as_mut() {
                b.set_low().map_err(Error::Pin)?;
            }
            self.binh_high = false;
        }
        Ok(())
    }

    /// Both callers (`select`, `start`) checked `transducer` in `prepare`.
    fn select_lines(&mut self, transducer: u8) -> Result<(), Error<E>> {
        if self.selected == Some(transducer) {
            return Ok(());
        }
        let old = self.selected;
        // Until every write has succeeded the lines are in an unknown mix.
        self.selected = None;
        for (bit, line) in self.addr.iter_mut().enumerate() {
            let want = (transducer >> bit) & 1 == 1;
            if let Some(o) = old {
                if ((o >> bit) & 1 == 1) == want {
                    continue;
                }
            }
            let r = if want { line.set_high() } else { line.set_low() };
            r.map_err(Error::Pin)?;
        }
        self.selected = Some(transducer);
        Ok(())
    }

    /// Fire `transducer`. Returns the clock reading taken as INIT rose, µs.
    ///
    /// Refuses with [`Fault::EchoStuckHigh`] (and fires nothing) if ECHO is
    /// already high. On any error the module is idle with INIT low (or
    /// marked to be driven low first thing at the next ping).
    pub fn start(&mut self, transducer: u8) -> Result<u32, Error<E>> {
        self.prepare(transducer)?;
        // With INIT low a healthy module holds ECHO low: high now would be
        // taken for an echo at once.
        if self.echo.is_high().map_err(Error::Pin)? {
            return Err(Fault::EchoStuckHigh.into());
        }
        self.select_lines(transducer)?;
        if let Err(e) = self.init.set_high() {
            // The line may or may not have risen: try to drop it now, and if
            // that fails too, before the next ping.
            self.init_high = self.init.set_low().is_err();
            return Err(Error::Pin(e));
        }
        self.init_high = true;
        // Read after the write: the burst starts when INIT actually rises.
        let fired_at = self.clock.now_us();
        self.phase = Phase::Listening { fired_at, blanking_end: self.timing.blanking_us() };
        Ok(fired_at)
    }

    /// Look at ECHO once. `Ok(None)` while still listening; `Ok(Some(_))`
    /// when the ping is over (the module is then idle again).
    ///
    /// The range is taken at the poll that first sees ECHO high, so its
    /// resolution is the polling interval: poll often, or use input capture
    /// and [`Module::echo_captured`]. A poll that first looks after the
    /// window has passed and finds ECHO high cannot time the echo and gives
    /// [`Echo::Untimed`], never a range or "no echo".
    pub fn poll(&mut self) -> Result<Option<Echo>, Error<E>> {
        let Phase::Listening { fired_at, blanking_end } = self.phase else {
            return Err(Error::Idle);
        };
        // Pin first, clock second: a high seen at time t rose at or before t.
        let high = match self.echo.is_high() {
            Ok(h) => h,
            Err(e) => return Err(self.abort(e)),
        };
        let el = elapsed(fired_at, self.clock.now_us());
        if high {
            if el > self.timing.window_us() {
                // Too late to say when it rose: inside the window, missed by
                // a late poll, or from beyond R_max. Either way not silence.
                self.finish().map_err(Error::Pin)?;
                return Ok(Some(Echo::Untimed { seen_after_us: el }));
            }
            return self.conclude(el, blanking_end).map(Some);
        }
        if el >= self.timing.window_us() {
            self.finish().map_err(Error::Pin)?;
            return Ok(Some(Echo::NoEcho));
        }
        if let Some(after) = self.timing.binh_after_us() {
            if !self.binh_high && el >= after {
                if let Some(b) = self.binh.as_mut() {
                    // Marked high before the write: if the write fails the
                    // line may have risen and must be driven low again.
                    self.binh_high = true;
                    if let Err(e) = b.set_high() {
                        return Err(self.abort(e));
                    }
                    // Blanking ends when BINH rises, which a late poll delays.
                    let end = if el < blanking_end { el } else { blanking_end };
                    self.phase = Phase::Listening { fired_at, blanking_end: end };
                }
            }
        }
        Ok(None)
    }

    /// The rising edge of ECHO was captured at `at_us` (a hardware
    /// input-capture time stamp, or an interrupt's clock reading): finish the
    /// ping with it. An edge before the ping counts as inside blanking; an
    /// edge after the listening window came from beyond the maximum range
    /// and is "no echo" (the stamp, unlike a late poll, says exactly when).
    pub fn echo_captured(&mut self, at_us: u32) -> Result<Echo, Error<E>> {
        let Phase::Listening { fired_at, blanking_end } = self.phase else {
            return Err(Error::Idle);
        };
        let el = elapsed(fired_at, at_us);
        // A wrapped difference past 2³¹ means the stamp is before the ping.
        let el = if el > i32::MAX as u32 { 0 } else { el };
        self.conclude(el, blanking_end)
    }

    /// Stop the ping in flight, if any, and return to idle.
    pub fn cancel(&mut self) -> Result<(), Error<E>> {
        if self.is_idle() && !self.init_high && !self.binh_high {
            return Ok(());
        }
        self.finish().map_err(Error::Pin)
    }

    /// Fire `transducer` and wait for the outcome, polling every `poll_us`
    /// with `delay`. The wait is bounded twice over: by the clock (the
    /// listening window) and by a poll budget of twice the window's worth of
    /// polls, which ends a wait on a clock that has stopped with
    /// [`Error::ClockStalled`].
    pub fn measure<D: DelayNs>(&mut self, transducer: u8, delay: &mut D, poll_us: u32) -> Result<Echo, Error<E>> {
        let poll_us = if poll_us == 0 { 1 } else { poll_us };
        self.start(transducer)?;
        let budget = (self.timing.window_us() / poll_us).saturating_mul(2).saturating_add(4);
        for _ in 0..budget {
            if let Some(echo) = self.poll()? {
                return Ok(echo);
            }
            delay.delay_us(poll_us);
        }
        self.finish().map_err(Error::Pin)?;
        Err(Error::ClockStalled)
    }

    /// Give the pins and the clock back. A ping in flight is abandoned with
    /// INIT as it is: call [`Module::cancel`] first to leave it low.
    pub fn destroy(self) -> (INIT, ECHO, Option<BINH>, [ADDR; A], CLK) {
        (self.init, self.echo, self.binh, self.addr, self.clock)
    }

    /// The ping in flight: when INIT rose, and whether a BINH rise is still
    /// to come. `None` when idle.
    #[cfg_attr(not(feature = "async"), allow(dead_code))]
    pub(crate) fn listening(&self) -> Option<(u32, bool)> {
        match self.phase {
            Phase::Listening { fired_at, .. } => Some((fired_at, self.binh.is_some() && !self.binh_high)),
            Phase::Idle => None,
        }
    }

    /// The ECHO line, for a flavour of the driver that waits on it.
    #[cfg_attr(not(feature = "async"), allow(dead_code))]
    pub(crate) fn echo_mut(&mut self) -> &mut ECHO {
        &mut self.echo
    }

    /// A pin failed while waiting on ECHO: stop as cleanly as the pins allow.
    #[cfg_attr(not(feature = "async"), allow(dead_code))]
    pub(crate) fn abort_pin(&mut self, e: E) -> Error<E> {
        self.abort(e)
    }

    /// The edge came `el` µs after the ping: classify it and stop.
    fn conclude(&mut self, el: u32, blanking_end: u32) -> Result<Echo, Error<E>> {
        let outcome = if el < blanking_end {
            Err(Error::Fault(Fault::EchoInBlanking { tof_us: el }))
        } else if el > self.timing.window_us() {
            // Only a capture stamp gets here: an exact edge beyond R_max.
            Ok(Echo::NoEcho)
        } else {
            Ok(Echo::Range { range_mm: self.timing.sound().range_mm(el), tof_us: el })
        };
        self.finish().map_err(Error::Pin)?;
        outcome
    }

    /// A pin failed mid-ping: stop as cleanly as the pins allow and report
    /// the first error.
    fn abort(&mut self, e: E) -> Error<E> {
        // The first failure is the one to report; a second is remembered
        // through init_high/binh_high and retried before the next ping.
        let _ = self.finish();
        Error::Pin(e)
    }

    /// End the ping: INIT low (resets ECHO), BINH low; idle whatever happens.
    fn finish(&mut self) -> Result<(), E> {
        self.phase = Phase::Idle;
        let init = self.init.set_low();
        self.init_high = init.is_err();
        let binh = match (self.binh_high, self.binh.as_mut()) {
            (true, Some(b)) => b.set_low(),
            _ => Ok(()),
        };
        self.binh_high = binh.is_err();
        init.and(binh)
    }
}
