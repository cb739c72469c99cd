//! The ring: `N` transducers on one multiplexed module, fired on a schedule.
//!
//! Slot `j` of cycle `k` fires transducer `schedule[j]` at
//! `start + k·period + j·slot + [k odd]·(j+1)·step` ([`RingTiming::fire_offset_us`]):
//! fixed slots of one listening window, the ring-down gap and the late limit,
//! shifted in odd cycles by EERUF's alternating delays. The slot times are
//! anchored to the schedule, not to when a ping happened to end, so the cycle
//! rate is steady and every crosstalk path (from a ping in this cycle or the
//! last) moves by at least one step between consecutive readings of a
//! transducer, while a true echo stays put. A reading that moves by more than
//! the tolerance is reported as [`Outcome::Crosstalk`], one that agrees with
//! the last as [`Outcome::Range`].
//!
//! Late polls. A slot fires at the first poll at or after its time. Fired up
//! to [`RingTiming::late_limit_us`] late it keeps the schedule: the slot has
//! room for that, so the whole ring-down gap still follows its window, and
//! EERUF's shifts still beat the tolerance. Fired later than that, the slot
//! re-anchors the schedule on itself, so the next ping again comes a whole
//! slot later (never a short gap, never a burst of catch-up pings); the
//! readings of the cycle that starts there have crosstalk paths from before
//! and after the jump, so EERUF neither confirms nor rejects them
//! ([`Outcome::Unconfirmed`]) nor keeps them to compare with.
//!
//! Between pings the ring points the multiplexer at the next transducer, so
//! the lines settle during the ring-down gap.

use embedded_hal::digital::{InputPin, OutputPin};

use super::clock::{elapsed, reached, Clock};
use super::config::RingTiming;
use super::error::{Error, Fault};
use super::module::{Echo, Module};
use super::schedule::Schedule;

/// What one slot of the ring found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Outcome {
    /// An echo accepted: confirmed by the previous reading of this
    /// transducer (EERUF), or any echo when EERUF is off.
    Range {
        /// One-way range, mm.
        range_mm: u32,
        /// Round-trip time of flight, µs.
        tof_us: u32,
    },
    /// An echo with nothing to confirm it yet: the previous reading of this
    /// transducer was no echo, a fault, or not from the previous cycle; or
    /// the schedule was re-anchored within the last cycle (a slot fired more
    /// than the late limit late), so that the comparison would be unsound.
    Unconfirmed {
        /// One-way range, mm.
        range_mm: u32,
        /// Round-trip time of flight, µs.
        tof_us: u32,
    },
    /// An echo that disagrees with the previous reading by more than the
    /// tolerance: suspected crosstalk (or a target that jumped).
    Crosstalk {
        /// One-way range, mm.
        range_mm: u32,
        /// Round-trip time of flight, µs.
        tof_us: u32,
        /// The previous reading it disagrees with, mm.
        previous_mm: u32,
    },
    /// Nothing within the maximum range.
    NoEcho,
    /// ECHO was high, but the ring was first polled after the listening
    /// window had passed, so the echo could not be timed
    /// ([`Echo::Untimed`]). Not "no echo".
    Untimed {
        /// Time from the ping to the poll that saw ECHO high, µs.
        seen_after_us: u32,
    },
    /// The module misbehaved on this slot.
    Fault(Fault),
}

impl Outcome {
    /// The range of an accepted echo, mm.
    pub const fn accepted_mm(&self) -> Option<u32> {
        match self {
            Self::Range { range_mm, .. } => Some(*range_mm),
            _ => None,
        }
    }

    /// The range of any echo, accepted or not, mm.
    pub const fn echo_mm(&self) -> Option<u32> {
        match self {
            Self::Range { range_mm, .. } | Self::Unconfirmed { range_mm, .. } | Self::Crosstalk { range_mm, .. } => {
                Some(*range_mm)
            }
            _ => None,
        }
    }
}

/// One reading of the ring.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RingReading {
    /// Which transducer.
    pub transducer: u8,
    /// Slot within the cycle.
    pub slot: u8,
    /// Cycle number since the ring started (wrapping).
    pub cycle: u32,
    /// Clock reading when INIT rose (or when a faulty slot was skipped), µs.
    pub fired_at_us: u32,
    /// How long after its scheduled time the slot fired, µs. More than
    /// [`RingTiming::late_limit_us`] means the schedule was re-anchored at
    /// this slot.
    pub late_us: u32,
    /// What it found.
    pub outcome: Outcome,
}

/// The previous reading of one transducer, for EERUF.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Last {
    Nothing,
    Range { mm: u32, cycle: u32 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Not started: the first poll anchors the schedule and fires slot 0.
    Unanchored,
    /// Waiting for the current slot's firing time.
    Waiting,
    /// The current slot's ping is in flight.
    Listening { fired_at: u32, late_us: u32 },
}

/// A sonar ring of `N` transducers on a [`Module`] with `A` address lines.
#[derive(Debug)]
pub struct Ring<INIT, ECHO, BINH, ADDR, CLK, const A: usize, const N: usize> {
    module: Module<INIT, ECHO, BINH, ADDR, CLK, A>,
    schedule: Schedule<N>,
    timing: RingTiming<N>,
    state: State,
    /// Clock reading at which cycle 0 started (moved on when polls run late).
    origin: u32,
    cycle: u32,
    slot: usize,
    last: [Last; N],
    /// Readings still to finish since the last re-anchor whose crosstalk
    /// paths may straddle it: EERUF neither judges them nor keeps them.
    settle: usize,
}

impl<INIT, ECHO, BINH, ADDR, CLK, E, const A: usize, const N: usize> Ring<INIT, ECHO, BINH, ADDR, CLK, A, N>
where
    INIT: OutputPin<Error = E>,
    ECHO: InputPin<Error = E>,
    BINH: OutputPin<Error = E>,
    ADDR: OutputPin<Error = E>,
    CLK: Clock,
    E: embedded_hal::digital::Error,
{
    /// The multiplexer must reach every transducer: checked at compile time.
    const FITS: () = assert!(N >= 1 && A <= 8 && N <= (1usize << A), "N transducers need 2^A >= N");

    /// A ring over `module`. Derive `timing` from `module.timing()` so the
    /// slots hold the module's whole listening window.
    pub fn new(module: Module<INIT, ECHO, BINH, ADDR, CLK, A>, schedule: Schedule<N>, timing: RingTiming<N>) -> Self {
        let () = Self::FITS;
        Self {
            module,
            schedule,
            timing,
            state: State::Unanchored,
            origin: 0,
            cycle: 0,
            slot: 0,
            last: [Last::Nothing; N],
            settle: 0,
        }
    }

    /// The firing schedule.
    pub fn schedule(&self) -> &Schedule<N> {
        &self.schedule
    }

    /// The ring's timing.
    pub fn timing(&self) -> &RingTiming<N> {
        &self.timing
    }

    /// The module's timing.
    pub fn module_timing(&self) -> &super::config::Timing {
        self.module.timing()
    }

    /// Clock reading at which the next (or current) slot fires, µs; `None`
    /// before the first poll.
    pub fn next_fire_us(&self) -> Option<u32> {
        match self.state {
            State::Unanchored => None,
            _ => Some(self.due()),
        }
    }

    /// Drive the ring: fire a due slot, look at a ping in flight. Returns a
    /// reading when a slot finishes. Never waits; call it at least as often
    /// as the range resolution you want (one call per µs of clock ≈ 0.17 mm).
    ///
    /// A slot fires at the first call at or after its time; see the module
    /// docs for what a late call does to the schedule.
    ///
    /// A pin error is returned as `Err` with the module left idle: if it
    /// came while firing, the same slot is tried again at the next call; if
    /// it came while listening, that slot's reading is lost and the ring
    /// moves on.
    pub fn poll(&mut self) -> Result<Option<RingReading>, Error<E>> {
        match self.state {
            State::Unanchored => {
                self.origin = self.module.now_us();
                self.cycle = 0;
                self.slot = 0;
                self.settle = 0;
                self.fire(true)
            }
            State::Waiting => {
                if !reached(self.module.now_us(), self.due()) {
                    return Ok(None);
                }
                self.fire(false)
            }
            State::Listening { fired_at, late_us } => match self.module.poll() {
                Ok(None) => Ok(None),
                Ok(Some(echo)) => self.end_slot(fired_at, late_us, Ok(echo)).map(Some),
                Err(e) => self.end_slot(fired_at, late_us, Err(e)).map(Some),
            },
        }
    }

    /// The ECHO edge of the ping in flight was captured at `at_us`: finish
    /// the slot with it (see [`Module::echo_captured`]).
    pub fn echo_captured(&mut self, at_us: u32) -> Result<RingReading, Error<E>> {
        let State::Listening { fired_at, late_us } = self.state else {
            return Err(Error::Idle);
        };
        let r = self.module.echo_captured(at_us);
        self.end_slot(fired_at, late_us, r)
    }

    /// Ends the slot on the module's answer: an echo or a fault is a
    /// reading; any other error (a pin) moves on to the next slot and is
    /// returned.
    fn end_slot(&mut self, fired_at: u32, late_us: u32, r: Result<Echo, Error<E>>) -> Result<RingReading, Error<E>> {
        match r {
            Ok(echo) => Ok(self.finish_slot(fired_at, late_us, Ok(echo))),
            Err(Error::Fault(f)) => Ok(self.finish_slot(fired_at, late_us, Err(f))),
            Err(e) => {
                self.advance();
                Err(e)
            }
        }
    }

    /// Forget the schedule anchor and EERUF's history; stop a ping in flight.
    /// The next poll starts cycle 0 at once.
    pub fn reset(&mut self) -> Result<(), Error<E>> {
        self.state = State::Unanchored;
        self.last = [Last::Nothing; N];
        self.settle = 0;
        self.module.cancel()
    }

    /// Whether the current slot's ping is in flight.
    #[cfg_attr(not(feature = "async"), allow(dead_code))]
    pub(crate) fn in_flight(&self) -> bool {
        matches!(self.state, State::Listening { .. })
    }

    /// The module, for a flavour of the driver that waits on its ECHO line.
    #[cfg_attr(not(feature = "async"), allow(dead_code))]
    pub(crate) fn module_mut(&mut self) -> &mut Module<INIT, ECHO, BINH, ADDR, CLK, A> {
        &mut self.module
    }

    /// Give the module back.
    pub fn release(self) -> Module<INIT, ECHO, BINH, ADDR, CLK, A> {
        self.module
    }

    fn due(&self) -> u32 {
        self.origin.wrapping_add(self.timing.fire_offset_us(self.cycle, self.slot))
    }

    fn current(&self) -> u8 {
        // slot < N always (advance wraps it); 0 is unreachable.
        self.schedule.transducer(self.slot).unwrap_or(0)
    }

    /// How late `at` is for the current slot, µs (0 if not yet due).
    fn late(&self, at: u32) -> u32 {
        let due = self.due();
        if reached(at, due) {
            elapsed(due, at)
        } else {
            0
        }
    }

    /// Fire the current slot (it is due). `anchoring`: the first slot of a
    /// fresh schedule, which the ping itself anchors.
    fn fire(&mut self, anchoring: bool) -> Result<Option<RingReading>, Error<E>> {
        let t = self.current();
        match self.module.start(t) {
            Ok(fired_at) => {
                // Lateness by the clock reading taken as INIT rose.
                let late_us = if anchoring { 0 } else { self.late(fired_at) };
                if anchoring || late_us > self.timing.late_limit_us() {
                    // Re-anchor on this ping: the next one is due a whole
                    // slot after it, so its window is followed by the whole
                    // ring-down gap, and nothing fires in a catch-up burst.
                    self.origin = fired_at.wrapping_sub(self.timing.fire_offset_us(self.cycle, self.slot));
                    if !anchoring {
                        // Every reading of the cycle from here may hear
                        // crosstalk from pings on both sides of the jump.
                        self.settle = N;
                    }
                }
                self.state = State::Listening { fired_at, late_us };
                Ok(None)
            }
            Err(Error::Fault(f)) => {
                // Nothing was fired, so there is no gap to keep.
                let at = self.module.now_us();
                let late_us = self.late(at);
                Ok(Some(self.finish_slot(at, late_us, Err(f))))
            }
            Err(e) => {
                // Same slot again at the next poll; it is already due. A
                // fresh schedule stays unanchored until its first ping.
                self.state = if anchoring { State::Unanchored } else { State::Waiting };
                Err(e)
            }
        }
    }

    fn finish_slot(&mut self, fired_at: u32, late_us: u32, found: Result<Echo, Fault>) -> RingReading {
        let t = self.current();
        let i = t as usize;
        let previous = self.last.get(i).copied().unwrap_or(Last::Nothing);
        // Only readings whose crosstalk paths all lie on one anchoring of
        // the schedule may confirm, reject or be kept.
        let settled = self.settle == 0;
        self.settle = self.settle.saturating_sub(1);
        let (outcome, last) = match found {
            Err(f) => (Outcome::Fault(f), Last::Nothing),
            Ok(Echo::NoEcho) => (Outcome::NoEcho, Last::Nothing),
            Ok(Echo::Untimed { seen_after_us }) => (Outcome::Untimed { seen_after_us }, Last::Nothing),
            Ok(Echo::Range { range_mm, tof_us }) => {
                let last = if settled { Last::Range { mm: range_mm, cycle: self.cycle } } else { Last::Nothing };
                let outcome = match (self.timing.tolerance_mm(), previous) {
                    (None, _) => Outcome::Range { range_mm, tof_us },
                    (Some(tol), Last::Range { mm, cycle }) if settled && cycle.wrapping_add(1) == self.cycle => {
                        if range_mm.abs_diff(mm) <= tol {
                            Outcome::Range { range_mm, tof_us }
                        } else {
                            Outcome::Crosstalk { range_mm, tof_us, previous_mm: mm }
                        }
                    }
                    (Some(_), _) => Outcome::Unconfirmed { range_mm, tof_us },
                };
                (outcome, last)
            }
        };
        if let Some(l) = self.last.get_mut(i) {
            *l = last;
        }
        // slot < N ≤ 256 (compile-time check), so it fits a u8.
        let reading = RingReading {
            transducer: t,
            slot: self.slot as u8,
            cycle: self.cycle,
            fired_at_us: fired_at,
            late_us,
            outcome,
        };
        self.advance();
        reading
    }

    /// On to the next slot; point the multiplexer at it during the gap.
    fn advance(&mut self) {
        // Compared before adding (`slot < N`): no sum that could overflow.
        if self.slot >= N.saturating_sub(1) {
            self.slot = 0;
            self.cycle = self.cycle.wrapping_add(1);
        } else {
            self.slot += 1;
        }
        self.state = State::Waiting;
        let next = self.current();
        // A failed write leaves the lines marked unknown; the ping rewrites
        // them all and reports the error then, so nothing is lost here.
        let _ = self.module.select(next);
    }
}
