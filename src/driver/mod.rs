//! The sonar ring driver: Polaroid 6500-class ranging modules over
//! embedded-hal 1.0 (DESIGN §5).
//!
//! | file | what it holds |
//! |---|---|
//! | [`clock`](Clock) | the driver's own clock trait: wrapping microseconds |
//! | [`sound`](SpeedOfSound) | speed of sound from temperature; time of flight ↔ mm, integers only |
//! | [`config`](ModuleConfig) | module and ring configuration, checked once into [`Timing`] / [`RingTiming`] |
//! | [`module`](Module) | one ranging module behind a transducer multiplexer: start, poll, capture, faults |
//! | [`schedule`](Schedule) | the firing order that keeps neighbours apart in time |
//! | [`ring`](Ring) | N transducers on fixed slots with EERUF's alternating delays and crosstalk check |
//! | [`error`](Error) | `Error<E>` over the HAL's pin error, [`Fault`], [`ConfigError`] |
//! | `asynch` (feature `async`) | `AsyncModule`, `AsyncRing`: the same module and ring over `embedded-hal-async`, awaiting ECHO and the next deadline |
//!
//! Nothing blocks: [`Ring::poll`] and [`Module::poll`] look once and return,
//! a ping with no echo ends when its listening window has passed, and the
//! one blocking helper ([`Module::measure`]) has a poll budget as well as the
//! clock to end it. Memory is fixed: `N` and `A` are const generics.
//!
//! # Example: a 16-transducer ring on generic pins
//!
//! `ring16` wires any HAL's pins — INIT, ECHO and four multiplexer address
//! lines sharing one pin type (use the HAL's type-erased pins) — and a
//! microsecond [`Clock`]. The hidden part of the example is a simulated
//! module in which every transducer faces a wall 1.5 m away.
//!
//! ```
//! use echoloc::driver::{
//!     Clock, ConfigError, Eeruf, Module, ModuleConfig, NoPin, Outcome, Ring, RingConfig, Schedule,
//!     SpeedOfSound,
//! };
//! use embedded_hal::digital::{Error, InputPin, OutputPin};
//!
//! type Ring16<P, I, C, E> = Ring<P, I, NoPin<E>, P, C, 4, 16>;
//!
//! fn ring16<P, I, C, E>(init: P, echo: I, addr: [P; 4], clock: C) -> Result<Ring16<P, I, C, E>, ConfigError>
//! where
//!     P: OutputPin<Error = E>,
//!     I: InputPin<Error = E>,
//!     C: Clock,
//!     E: Error,
//! {
//!     let sound = SpeedOfSound::at_centi_celsius(2000)?; // 20.00 °C
//!     let timing = ModuleConfig::polaroid_6500(sound).timing()?;
//!     let eeruf = Eeruf { alternating_us: 1_000, tolerance_mm: 50 };
//!     let ring_timing = RingConfig { ring_down_us: 5_000, eeruf: Some(eeruf) }.timing::<16>(&timing)?;
//!     let module = Module::new(init, echo, addr, clock, timing);
//!     Ok(Ring::new(module, Schedule::spread(), ring_timing))
//! }
//! # use core::cell::Cell;
//! # use core::convert::Infallible;
//! # use embedded_hal::digital::ErrorType;
//! # /// The simulated bench: time, and when INIT last rose.
//! # struct Bench { now: Cell<u32>, fired: Cell<Option<u32>> }
//! # impl Clock for Bench {
//! #     // Every look at the clock lets 10 µs pass, so polling makes progress.
//! #     fn now_us(&self) -> u32 { let t = self.now.get(); self.now.set(t + 10); t }
//! # }
//! # enum Line<'a> { Init(&'a Bench), Addr }
//! # impl ErrorType for Line<'_> { type Error = Infallible; }
//! # impl OutputPin for Line<'_> {
//! #     fn set_low(&mut self) -> Result<(), Infallible> { if let Line::Init(b) = self { b.fired.set(None) } Ok(()) }
//! #     fn set_high(&mut self) -> Result<(), Infallible> { if let Line::Init(b) = self { b.fired.set(Some(b.now.get())) } Ok(()) }
//! # }
//! # struct EchoLine<'a>(&'a Bench);
//! # impl ErrorType for EchoLine<'_> { type Error = Infallible; }
//! # impl InputPin for EchoLine<'_> {
//! #     // A wall at 1.5 m: the echo is back 8 741 µs after INIT rises.
//! #     fn is_high(&mut self) -> Result<bool, Infallible> { Ok(self.0.fired.get().is_some_and(|f| self.0.now.get() - f >= 8_741)) }
//! #     fn is_low(&mut self) -> Result<bool, Infallible> { self.is_high().map(|h| !h) }
//! # }
//! # let bench = Bench { now: Cell::new(0), fired: Cell::new(None) };
//! # let (init, echo) = (Line::Init(&bench), EchoLine(&bench));
//! # let addr = [Line::Addr, Line::Addr, Line::Addr, Line::Addr];
//!
//! let mut ring = ring16(init, echo, addr, &bench).unwrap();
//! let mut readings = 0;
//! // Two cycles: the first readings are unconfirmed, the second confirm them.
//! for _ in 0..1_000_000 {
//!     if let Some(r) = ring.poll().unwrap() {
//!         readings += 1;
//!         match r.outcome {
//!             Outcome::Unconfirmed { range_mm, .. } => assert!(r.cycle == 0 && range_mm.abs_diff(1500) <= 2),
//!             Outcome::Range { range_mm, .. } => assert!(r.cycle == 1 && range_mm.abs_diff(1500) <= 2),
//!             other => panic!("unexpected {other:?}"),
//!         }
//!         if readings == 32 {
//!             break;
//!         }
//!     }
//! }
//! assert_eq!(readings, 32);
//! ```

#[cfg(feature = "async")]
mod asynch;
mod clock;
mod config;
mod error;
mod module;
mod pin;
mod ring;
mod schedule;
mod sound;

#[cfg(feature = "async")]
pub use asynch::{AsyncModule, AsyncRing};
pub use clock::Clock;
pub use config::{
    Eeruf, ModuleConfig, RingConfig, RingTiming, Timing, MAX_RANGE_LIMIT_MM, POLAROID_BLANKING_US, TRANSMIT_BURST_US,
};
pub use error::{ConfigError, Error, Fault};
pub use module::{Echo, Module};
pub use pin::NoPin;
pub use ring::{Outcome, Ring, RingReading};
pub use schedule::Schedule;
pub use sound::SpeedOfSound;
