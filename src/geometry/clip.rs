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

    /// The value as `f32`: one FPU division of the two terms when both fit
    /// 24 bits (exact conversions, so correctly rounded), else through `f64`.
    pub fn to_f32(self) -> f32 {
        let exact = |v: i64| (-(1 << 24)..=1 << 24).contains(&v);
        if exact(self.num) && exact(self.den) {
            return self.num as i32 as f32 / self.den as i32 as f32;
        }
        self.to_f64() as f32
    }

    pub fn to_f64(self) -> f64 {
        self.num as f64 / self.den as f64
    }
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
}
