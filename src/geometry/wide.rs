//! Exact comparisons of products too wide for `i128`.
//!
//! The window tests compare squared distances of rational points, whose
//! numerators reach about 2¹⁵⁶. A 256-bit unsigned value (two `u128` limbs)
//! with multiply, add and compare is all they need.

/// An unsigned 256-bit integer: `hi · 2¹²⁸ + lo`.
/// Ordered by `hi`, then `lo`: the numeric order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct U256 {
    hi: u128,
    lo: u128,
}

impl U256 {
    /// Zero.
    pub const ZERO: U256 = U256 { hi: 0, lo: 0 };

    /// The full product of two `u128`.
    pub const fn mul(a: u128, b: u128) -> U256 {
        const M: u128 = u64::MAX as u128;
        let (a1, a0) = (a >> 64, a & M);
        let (b1, b0) = (b >> 64, b & M);
        let p00 = a0 * b0;
        let p01 = a0 * b1;
        let p10 = a1 * b0;
        let p11 = a1 * b1;
        // Middle column: carries collected in 64-bit halves (cannot overflow).
        let mid = (p00 >> 64) + (p01 & M) + (p10 & M);
        let lo = (p00 & M) | (mid << 64);
        let hi = p11 + (p01 >> 64) + (p10 >> 64) + (mid >> 64);
        U256 { hi, lo }
    }

    /// The square of `|a|`.
    pub const fn square(a: i128) -> U256 {
        Self::mul(a.unsigned_abs(), a.unsigned_abs())
    }

    /// `self + o`, saturating at the maximum (never reached by the window
    /// tests, whose values stay below 2¹⁶⁰).
    pub const fn add(self, o: U256) -> U256 {
        let (lo, c) = self.lo.overflowing_add(o.lo);
        let hi = self.hi.saturating_add(o.hi).saturating_add(c as u128);
        U256 { hi, lo }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_match_u128_where_they_fit_and_carry_beyond() {
        assert_eq!(U256::mul(3, 5), U256 { hi: 0, lo: 15 });
        let m = u64::MAX as u128;
        assert_eq!(U256::mul(m, m), U256 { hi: 0, lo: m * m });
        // (2^128 - 1)^2 = 2^256 - 2^129 + 1
        assert_eq!(U256::mul(u128::MAX, u128::MAX), U256 { hi: u128::MAX - 1, lo: 1 });
        assert_eq!(U256::mul(1 << 100, 1 << 100), U256 { hi: 1 << 72, lo: 0 });
        let a = U256::mul(1 << 127, 2);
        assert_eq!(a, U256 { hi: 1, lo: 0 });
        assert_eq!(U256 { hi: 0, lo: u128::MAX }.add(U256 { hi: 0, lo: 1 }), U256 { hi: 1, lo: 0 });
        assert_eq!(U256::square(-7), U256 { hi: 0, lo: 49 });
        assert!(U256 { hi: 1, lo: 0 }.cmp(&U256 { hi: 0, lo: u128::MAX }).is_gt());
    }
}
