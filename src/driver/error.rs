//! Typed errors and faults.
//!
//! Pin errors keep the HAL's own error type (`Error::Pin(E)`); everything the
//! sonar itself can do wrong is a [`Fault`], a plain value with no generic, so
//! the ring can hand it on as a reading outcome and keep going.

use core::fmt;

/// Something the ranging module did that a healthy module does not.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// ECHO was already high before the ping: a stuck line, a missing pull-up
    /// or a wiring fault. The ping was not sent.
    EchoStuckHigh,
    /// ECHO went high while the module should still have been blanking (or
    /// before the ping, as far as a time stamp says): transmit ring-down
    /// leaking through, noise, or a BINH line that is wired wrong.
    EchoInBlanking {
        /// Time from the ping to the edge, µs (0 if the edge came before it).
        tof_us: u32,
    },
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EchoStuckHigh => f.write_str("ECHO high before the ping"),
            Self::EchoInBlanking { tof_us } => write!(f, "echo inside blanking after {tof_us} us"),
        }
    }
}

impl core::error::Error for Fault {}

/// An error from the driver, generic over the HAL's pin error `E`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// A pin operation failed; the HAL's own error.
    Pin(E),
    /// The module misbehaved.
    Fault(Fault),
    /// A ping is already in flight.
    Busy,
    /// No ping is in flight.
    Idle,
    /// The transducer index is beyond what the address lines can select.
    NoSuchTransducer(u8),
    /// A blocking wait used up its poll budget without the clock reaching the
    /// end of the listening window: the clock is not running.
    ClockStalled,
}

impl<E> From<Fault> for Error<E> {
    fn from(f: Fault) -> Self {
        Self::Fault(f)
    }
}

impl<E: fmt::Debug> fmt::Display for Error<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Pin(e) => write!(f, "pin error: {e:?}"),
            Self::Fault(x) => write!(f, "sonar fault: {x}"),
            Self::Busy => f.write_str("a ping is already in flight"),
            Self::Idle => f.write_str("no ping is in flight"),
            Self::NoSuchTransducer(t) => write!(f, "no transducer {t} on this multiplexer"),
            Self::ClockStalled => f.write_str("the clock did not advance"),
        }
    }
}

/// `E` needs only `Debug` (every embedded-hal pin error has it). A fault is
/// the `source`; the pin error is not, because `E` need not implement
/// `core::error::Error` itself.
impl<E: fmt::Debug> core::error::Error for Error<E> {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Fault(f) => Some(f),
            _ => None,
        }
    }
}

/// A configuration the driver refuses, found before any pin is touched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// Temperature outside −40.00 … +85.00 °C.
    Temperature,
    /// A speed of sound outside 300 … 400 m/s.
    SpeedOfSound,
    /// Maximum range zero or beyond 11 m (the 6500 is specified to 10.7 m).
    MaxRange,
    /// Blanking not shorter than the listening window.
    Blanking,
    /// BINH set before the transmit burst ends, or not before internal
    /// blanking ends (where it would do nothing).
    Binh,
    /// Ring-down gap longer than one second.
    RingDown,
    /// The alternating delay is zero or moves a crosstalk echo by no more
    /// than the tolerance, so EERUF could not tell it from a true echo.
    AlternatingDelay,
    /// One ring cycle would last 2³¹ µs or more.
    CycleTooLong,
    /// A firing order that is not a permutation of `0..N`.
    FiringOrder,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            Self::Temperature => "temperature outside -40..=85 C",
            Self::SpeedOfSound => "speed of sound outside 300..=400 m/s",
            Self::MaxRange => "maximum range outside 1..=11000 mm",
            Self::Blanking => "blanking not shorter than the listening window",
            Self::Binh => "BINH time outside the transmit burst .. blanking end",
            Self::RingDown => "ring-down gap over one second",
            Self::AlternatingDelay => "alternating delay too short for the tolerance",
            Self::CycleTooLong => "ring cycle of 2^31 us or more",
            Self::FiringOrder => "firing order is not a permutation",
        };
        f.write_str(s)
    }
}

impl core::error::Error for ConfigError {}
