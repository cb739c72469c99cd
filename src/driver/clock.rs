//! The driver's clock: monotonic microseconds that wrap.
//!
//! embedded-hal 1.0 has no timer or capture trait, so the driver asks for
//! this one small trait (DESIGN §5). A board implements it over a free-running
//! hardware timer, a `SysTick` counter extended in software, or an RTIC/embassy
//! monotonic; host tests implement it with a clock they script.

/// A free-running microsecond counter.
///
/// The count wraps at 2³² µs (about 71.6 minutes). The driver only ever
/// subtracts two readings with wrapping arithmetic, so the wrap is harmless as
/// long as the driver is polled at least once every 2³¹ µs (about 35 minutes)
/// while a ping or a ring cycle is in progress.
///
/// `now_us` takes `&self` because a hardware counter is read through a shared
/// reference; an implementation that must keep state (extending a 16-bit
/// timer, say) can use a `Cell` or a critical section.
pub trait Clock {
    /// Microseconds since an arbitrary origin, wrapping at 2³².
    fn now_us(&self) -> u32;
}

/// A shared clock: several drivers (or a driver and the application) can
/// read one timer.
impl<C: Clock + ?Sized> Clock for &C {
    fn now_us(&self) -> u32 {
        (**self).now_us()
    }
}

/// Microseconds from `since` to `now`, correct across the 2³² wrap.
pub(crate) const fn elapsed(since: u32, now: u32) -> u32 {
    now.wrapping_sub(since)
}

/// Whether `now` has reached `due`, correct across the wrap for times less
/// than 2³¹ µs apart.
pub(crate) const fn reached(now: u32, due: u32) -> bool {
    // The sign of the wrapped difference tells which comes first.
    (now.wrapping_sub(due) as i32) >= 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elapsed_and_reached_cross_the_wrap() {
        assert_eq!(elapsed(u32::MAX - 9, 10), 20);
        assert!(reached(5, u32::MAX - 5));
        assert!(!reached(u32::MAX - 5, 5));
        assert!(reached(7, 7));
    }
}
