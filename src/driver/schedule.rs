//! The firing order: neighbours apart in time.
//!
//! Crosstalk is worst between neighbouring transducers (their cones overlap)
//! and between pings close in time (the earlier one's echoes are still about).
//! [`Schedule::spread`] therefore fires with a stride `s` coprime to `N`
//! (slot `j` fires transducer `j·s mod N`, so every transducer fires once a
//! cycle) chosen so that each ping is as far round the ring as possible from
//! the three pings before it (ties go to the larger distance from the ping
//! just before). For 16 transducers that is `s = 3`, for 24
//! `s = 5`: consecutive pings 3 (resp. 5) positions apart, neighbours at least
//! 5 slots apart in time.

use super::error::ConfigError;

/// How many earlier pings [`Schedule::spread`] keeps away from each ping.
const LOOK_BACK: usize = 3;

/// The order in which a ring of `N` transducers fires, one cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Schedule<const N: usize> {
    order: [u8; N],
    stride: u8,
}

impl<const N: usize> Schedule<N> {
    /// Indices are `u8`: compile-time check, no run-time panic.
    const CAPACITY_OK: () = assert!(N >= 1 && N <= 256, "a ring has 1 to 256 transducers");

    /// The stride schedule described in the module docs.
    pub const fn spread() -> Self {
        let () = Self::CAPACITY_OK;
        let mut best = 1usize;
        let mut best_score = [0usize; LOOK_BACK + 1];
        let mut s = 1usize;
        while s < N {
            if gcd(s, N) == 1 {
                // Score: first the smallest ring distance from a ping to any
                // of the LOOK_BACK pings before it, then the distances to the
                // 1st, 2nd, … ping before, compared in that order (the order
                // is periodic, so the cycle boundary needs no special case).
                let mut score = [0usize; LOOK_BACK + 1];
                score[0] = usize::MAX;
                let mut m = 1usize;
                while m <= LOOK_BACK && m < N {
                    let d = ring_distance((m * s) % N, N);
                    score[m] = d;
                    if d < score[0] {
                        score[0] = d;
                    }
                    m += 1;
                }
                if better(&score, &best_score) {
                    best_score = score;
                    best = s;
                }
            }
            s += 1;
        }
        Self::with_stride(best)
    }

    /// Slot `j` fires transducer `j·stride mod N`; `stride` must be coprime
    /// to `N` (else some transducer would never fire).
    pub const fn stride(stride: usize) -> Result<Self, ConfigError> {
        let () = Self::CAPACITY_OK;
        if stride == 0 || gcd(stride % N, N) != 1 {
            return Err(ConfigError::FiringOrder);
        }
        Ok(Self::with_stride(stride % N))
    }

    /// An explicit order; it must name every transducer `0..N` once.
    pub const fn from_order(order: [u8; N]) -> Result<Self, ConfigError> {
        let () = Self::CAPACITY_OK;
        let mut seen = [false; N];
        let mut i = 0;
        while i < N {
            let t = order[i] as usize;
            if t >= N || seen[t] {
                return Err(ConfigError::FiringOrder);
            }
            seen[t] = true;
            i += 1;
        }
        Ok(Self { order, stride: 0 })
    }

    const fn with_stride(s: usize) -> Self {
        let mut order = [0u8; N];
        let mut j = 0;
        while j < N {
            // < N ≤ 256, so the cast is exact.
            order[j] = ((j * s) % N) as u8;
            j += 1;
        }
        // s < N ≤ 256; a stride of 256 is impossible (s < N).
        Self { order, stride: s as u8 }
    }

    /// The transducers in firing order.
    pub const fn order(&self) -> &[u8; N] {
        &self.order
    }

    /// The stride, or 0 for an explicit order.
    pub const fn stride_used(&self) -> u8 {
        self.stride
    }

    /// The transducer fired in slot `slot`, if there is such a slot.
    pub const fn transducer(&self, slot: usize) -> Option<u8> {
        if slot < N {
            Some(self.order[slot])
        } else {
            None
        }
    }
}

/// Lexicographic `a > b`.
const fn better(a: &[usize; LOOK_BACK + 1], b: &[usize; LOOK_BACK + 1]) -> bool {
    let mut i = 0;
    while i < LOOK_BACK + 1 {
        if a[i] != b[i] {
            return a[i] > b[i];
        }
        i += 1;
    }
    false
}

const fn gcd(mut a: usize, mut b: usize) -> usize {
    while b != 0 {
        let t = a % b;
        a = b;
        b = t;
    }
    a
}

/// Positions between two transducers `d` apart one way round a ring of `n`.
const fn ring_distance(d: usize, n: usize) -> usize {
    if d <= n - d {
        d
    } else {
        n - d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strides_for_the_usual_rings() {
        assert_eq!(Schedule::<16>::spread().stride_used(), 3);
        assert_eq!(Schedule::<24>::spread().stride_used(), 5);
        assert_eq!(Schedule::<8>::spread().stride_used(), 3);
        assert_eq!(Schedule::<1>::spread().order(), &[0]);
        assert_eq!(Schedule::<2>::spread().order(), &[0, 1]);
    }

    #[test]
    fn explicit_orders_are_checked() {
        assert!(Schedule::<3>::from_order([2, 0, 1]).is_ok());
        assert_eq!(Schedule::<3>::from_order([2, 2, 1]), Err(ConfigError::FiringOrder));
        assert_eq!(Schedule::<3>::from_order([0, 1, 3]), Err(ConfigError::FiringOrder));
        assert_eq!(Schedule::<16>::stride(4), Err(ConfigError::FiringOrder));
        assert_eq!(Schedule::<16>::stride(7).unwrap().order()[1], 7);
    }
}
