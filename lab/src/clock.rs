//! The controller's clock as the host reads it: µs in a `u32` that wraps
//! every 2³² µs (71.6 minutes), unwrapped into a `u64` that does not.

/// Unwraps one stream of the controller's times, in the order they came.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Unwrap {
    epoch: u64,
    last: Option<u32>,
}

impl Unwrap {
    /// `t` unwrapped: a time before the last one is taken as the clock's
    /// wrap (the controller's times only go forward between restarts).
    pub fn next(&mut self, t: u32) -> u64 {
        if self.last.is_some_and(|l| t < l) {
            self.epoch += 1 << 32;
        }
        self.last = Some(t);
        self.epoch + u64::from(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wrap_carries_on_from_two_to_the_32() {
        let mut u = Unwrap::default();
        assert_eq!(u.next(5), 5);
        assert_eq!(u.next(u32::MAX), u64::from(u32::MAX));
        assert_eq!(u.next(3), (1 << 32) + 3);
        assert_eq!(u.next(3), (1 << 32) + 3);
        assert_eq!(u.next(2), (2 << 32) + 2);
    }
}
