//! A parameter range `[lo, hi] ⊆ [0, 1]` along a segment `a + s·(b − a)`,
//! cut by linear constraints `c0 + s·c1 ≥ 0` and kept as exact fractions:
//! the Cyrus–Beck clipping that both a piece's entry point
//! (`Convex::entry`) and a window's edge clipping (`Sector`) use.

/// An exact fraction `num / den`, `den > 0`, of two `i64` (the clipping
/// constraints' own coefficients: no wider type is ever needed to hold one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Frac {
    pub num: i64,
    pub den: i64,
}

impl Frac {
    pub const ZERO: Frac = Frac { num: 0, den: 1 };
    pub const ONE: Frac = Frac { num: 1, den: 1 };

    /// `self < o`, exactly (both denominators positive). Cross products in
    /// `i64` when every term fits 32 bits (one multiply each on a
    /// Cortex-M4, where `i128` products are library calls), else in `i128`.
    #[inline]
    pub fn lt(self, o: Frac) -> bool {
        let small = |v: i64| v as i32 as i64 == v;
        if small(self.num) && small(self.den) && small(o.num) && small(o.den) {
            return self.num * o.den < o.num * self.den;
        }
        (self.num as i128) * (o.den as i128) < (o.num as i128) * (self.den as i128)
    }

    /// The value as `f32`, correctly rounded (to nearest, ties to even):
    /// one FPU division of the two terms when both fit 24 bits (exact
    /// conversions), else an integer long division. Not through `f64`,
    /// which a Cortex-M4F has no FPU for: its soft division and conversions
    /// were 2 KiB of the firmware's flash for this one path.
    pub fn to_f32(self) -> f32 {
        let exact = |v: i64| (-(1 << 24)..=1 << 24).contains(&v);
        if exact(self.num) && exact(self.den) {
            return self.num as i32 as f32 / self.den as i32 as f32;
        }
        quotient_f32(self.num, self.den)
    }

    pub fn to_f64(self) -> f64 {
        self.num as f64 / self.den as f64
    }
}

/// `num / den` rounded to the nearest `f32` (ties to even) by long
/// division: the divisor is shifted under the dividend's top bit, 25
/// quotient bits (24 kept, one to round on) are taken, and the remainder
/// says whether anything lies beyond them. `den == 0` gives an infinity
/// with the numerator's sign, `0 / 0` NaN.
fn quotient_f32(num: i64, den: i64) -> f32 {
    let negative = (num < 0) != (den < 0);
    let (a, b) = (u128::from(num.unsigned_abs()), u128::from(den.unsigned_abs()));
    let signed = |v: f32| if negative { -v } else { v };
    if b == 0 {
        return if a == 0 { f32::NAN } else { signed(f32::INFINITY) };
    }
    if a == 0 {
        return signed(0.0);
    }
    // Both below 2^64, so the quotient's exponent lies in [-64, 64] and
    // every shifted term below 2^65: u128 holds them, and no f32 result
    // is subnormal or infinite.
    let mut e = b.leading_zeros() as i32 - a.leading_zeros() as i32;
    let (mut r, d) = if e >= 0 { (a, b << e) } else { (a << -e, b) };
    if r < d {
        r <<= 1;
        e -= 1;
    }
    // d <= r < 2d: the quotient is 1.xxx times 2^e.
    let mut q = 0u32;
    for _ in 0..25 {
        q <<= 1;
        if r >= d {
            r -= d;
            q |= 1;
        }
        r <<= 1;
    }
    let sticky = r != 0; // a remainder beyond the round bit
    let (mut mant, round) = (q >> 1, q & 1);
    if round == 1 && (sticky || mant & 1 == 1) {
        mant += 1;
        if mant == 1 << 24 {
            mant >>= 1;
            e += 1;
        }
    }
    let bits = (((e + 127) as u32) << 23) | (mant & 0x7f_ffff);
    signed(f32::from_bits(bits))
}

/// The part of `[0, 1]` that every constraint so far allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ParamRange {
    pub lo: Frac,
    pub hi: Frac,
}

impl ParamRange {
    /// The whole segment.
    pub const UNIT: ParamRange = ParamRange { lo: Frac::ZERO, hi: Frac::ONE };

    /// Cuts the range by `c0 + s·c1 ≥ 0`; `false` once it is empty.
    /// Exact while `|c0|, |c1| < 2⁶³` (every product below 2¹²⁶).
    pub fn cut(&mut self, c0: i64, c1: i64) -> bool {
        if c1 == 0 {
            if c0 < 0 {
                self.hi = Frac { num: -1, den: 1 }; // empty for good
            }
        } else if c1 > 0 {
            // s ≥ −c0/c1
            let f = Frac { num: c0.saturating_neg(), den: c1 };
            if self.lo.lt(f) {
                self.lo = f;
            }
        } else {
            // s ≤ c0/(−c1)
            let f = Frac { num: c0, den: c1.saturating_neg() };
            if f.lt(self.hi) {
                self.hi = f;
            }
        }
        !self.hi.lt(self.lo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cuts_narrow_exactly_and_empty_stays_empty() {
        let mut r = ParamRange::UNIT;
        assert!(r.cut(-1, 4)); // s ≥ 1/4
        assert!(r.cut(3, -4)); // s ≤ 3/4
        assert_eq!((r.lo, r.hi), (Frac { num: 1, den: 4 }, Frac { num: 3, den: 4 }));
        assert!(r.cut(-1, 2)); // s ≥ 1/2
        assert!(r.cut(5, 0), "a constraint that always holds");
        assert!(!r.cut(-1, 0), "a constraint that never holds");
        assert!(!r.cut(0, 1), "empty stays empty");
        let mut r = ParamRange::UNIT;
        assert!(!r.cut(-3, 2), "s ≥ 3/2 leaves nothing of [0, 1]");
    }

    /// Against the host's `f64` division rounded to `f32` (exact
    /// conversions below 2^53, and a double rounding that differs from one
    /// correct rounding with odds near 2^-29 a pair): every magnitude pair
    /// from 2^0 to 2^62, both signs, and the rounding's edges.
    #[test]
    fn quotients_round_as_the_host_divides() {
        let oracle = |n: i64, d: i64| (n as f64 / d as f64) as f32;
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut checked = 0;
        for bits_n in 1..63 {
            for bits_d in 1..63 {
                for _ in 0..8 {
                    let n = (next() >> (64 - bits_n)) as i64 | 1 << (bits_n - 1);
                    let d = (next() >> (64 - bits_d)) as i64 | 1 << (bits_d - 1);
                    if n.max(d) < 1 << 53 {
                        for (n, d) in [(n, d), (-n, d), (n, -d)] {
                            let (got, want) = (quotient_f32(n, d), oracle(n, d));
                            assert_eq!(got.to_bits(), want.to_bits(), "{n} / {d}: {got:e} against {want:e}");
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 50_000, "{checked}");
        // Ties: (2^24 + 1) / 2 and (2^24 + 3) / 2 round to even, up and down
        // of the odd last bit; one past a tie rounds away from it.
        let t = 1i64 << 25;
        for n in [t + 2, t + 6, t + 3, t + 5, (1 << 50) + (1 << 26), (1 << 50) + (3 << 26)] {
            assert_eq!(quotient_f32(n, 2).to_bits(), oracle(n, 2).to_bits(), "{n} / 2");
        }
        assert_eq!(quotient_f32((1 << 62) - 1, 1), 4.611_686e18);
        assert_eq!(quotient_f32(i64::MIN, 1), -9.223_372e18);
        assert_eq!(quotient_f32(1, i64::MAX), 1.084_202_2e-19);
        assert_eq!(quotient_f32(0, 5), 0.0);
        assert!(quotient_f32(0, 0).is_nan());
        assert_eq!(quotient_f32(-3, 0), f32::NEG_INFINITY);
        // The public path: both terms past 24 bits take the long division.
        let f = Frac { num: 123_456_789_012, den: 987_654_321_098 };
        assert_eq!(f.to_f32(), (123_456_789_012f64 / 987_654_321_098f64) as f32);
    }
}
