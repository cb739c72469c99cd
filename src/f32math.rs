//! `sin`, `cos`, `atan2` and `sqrt` in `f32` arithmetic alone. `libm`'s
//! `sinf` and `cosf` reduce and evaluate in `f64`, which the Cortex-M4F does
//! in software (≈ 1 000 instructions a call, measured by `ekf_cost`), its
//! `atan2f` takes two calls and branches on every argument class (the
//! predictor's subsurface walk calls it twice a step), and its `sqrtf` has
//! no ARM intrinsic; these cost tens of instructions with the
//! single-precision FPU and stay within a few ulp (host tests bound the
//! error against `f64`).

use core::f32::consts::FRAC_PI_2;

// π/2 split so that k·PIO2_HI is exact for |k| < 2⁸: Cody–Waite reduction.
const PIO2_HI: f32 = 1.570_312_5; // 201/128, 8 significant bits
const PIO2_LO: f32 = (core::f64::consts::FRAC_PI_2 - 1.570_312_5) as f32;

/// `(sin a, cos a)`, within 2·10⁻⁷ for |a| ≤ 200 rad (wider angles lose the
/// reduction's precision: reduce them first).
pub fn sin_cos(a: f32) -> (f32, f32) {
    let k = libm::roundf(a / FRAC_PI_2);
    let r = (a - k * PIO2_HI) - k * PIO2_LO;
    let r2 = r * r;
    // Taylor to r⁹ and r¹⁰ on |r| ≤ π/4: the next terms are below 2·10⁻⁹.
    let s = r * (1.0 + r2 * (-1.0 / 6.0 + r2 * (1.0 / 120.0 + r2 * (-1.0 / 5040.0 + r2 * (1.0 / 362_880.0)))));
    let c =
        1.0 + r2 * (-0.5 + r2 * (1.0 / 24.0 + r2 * (-1.0 / 720.0 + r2 * (1.0 / 40_320.0 + r2 * (-1.0 / 3_628_800.0)))));
    match (k as i32) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// `atan2(y, x)` in radians, `−π ..= π`, within 3·10⁻⁷ of the true angle
/// for finite arguments; `0` for `(0, 0)` (either sign), NaN if either is
/// NaN. The octant's ratio `t ∈ [0, 1]` goes through the minimax polynomial
/// of Abramowitz & Stegun 4.4.49 (error below 2·10⁻⁸ on `[0, 1]`).
/// (`micromath`'s `atan2` states 0.002 rad, a hundred times the millidegree
/// the predictor reports θ and δ in.)
pub fn atan2(y: f32, x: f32) -> f32 {
    // As printed in A&S (rounded to f32 by the compiler).
    #[allow(clippy::excessive_precision)]
    const A: [f32; 8] = [
        -0.333_331_452_8,
        0.199_935_508_5,
        -0.142_088_994_4,
        0.106_562_639_3,
        -0.075_289_640_0,
        0.042_909_613_8,
        -0.016_165_736_7,
        0.002_866_225_7,
    ];
    let (ax, ay) = (x.abs(), y.abs());
    let steep = ay > ax;
    let (lo, hi) = if steep { (ax, ay) } else { (ay, ax) };
    if hi == 0.0 {
        return 0.0;
    }
    let t = lo / hi;
    let t2 = t * t;
    let p = A[0] + t2 * (A[1] + t2 * (A[2] + t2 * (A[3] + t2 * (A[4] + t2 * (A[5] + t2 * (A[6] + t2 * A[7]))))));
    let mut r = t + t * (t2 * p);
    if steep {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = core::f32::consts::PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// `ln x` for the particle filter's likelihoods, within 5·10⁻⁵ (absolute)
/// for normal positive `x`: the exponent from the bits, then
/// `ln m = 2 atanh((m − 1)/(m + 1))` by its series to the 7th power on
/// `m ∈ [√½, √2)`. `−∞` for 0 and subnormals, NaN below 0 or for NaN.
/// (`libm::logf` costs about twice as many instructions on the M4F.)
pub fn ln_fast(x: f32) -> f32 {
    if x.is_nan() || x < 0.0 {
        return f32::NAN;
    }
    if x < f32::MIN_POSITIVE {
        return f32::NEG_INFINITY;
    }
    if x == f32::INFINITY {
        return x;
    }
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xFF) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007F_FFFF) | 0x3F80_0000);
    if m >= core::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let ln_m = 2.0 * t * (1.0 + t2 * (1.0 / 3.0 + t2 * (1.0 / 5.0 + t2 * (1.0 / 7.0))));
    e as f32 * core::f32::consts::LN_2 + ln_m
}

/// `eˣ` for the particle filter's weights, within 5·10⁻⁶ (relative) for
/// `x ∈ [−87, 88]`; 0 below, `+∞` above, NaN for NaN: `x / ln 2 = n + f`,
/// `2ᶠ` by its Taylor series to the 7th power on `f ∈ [−½, ½]`, `2ⁿ` into
/// the exponent bits.
pub fn exp_fast(x: f32) -> f32 {
    if x.is_nan() {
        return x;
    }
    if x < -87.0 {
        return 0.0;
    }
    if x > 88.0 {
        return f32::INFINITY;
    }
    let y = x * core::f32::consts::LOG2_E;
    let n = libm::roundf(y);
    let f = (y - n) * core::f32::consts::LN_2;
    let p = 1.0
        + f * (1.0
            + f * (1.0 / 2.0
                + f * (1.0 / 6.0 + f * (1.0 / 24.0 + f * (1.0 / 120.0 + f * (1.0 / 720.0 + f * (1.0 / 5040.0)))))));
    // n ∈ [−126, 127] here (by the range checks above): a normal power of
    // two, and the wrapping sum is exact (the compiler cannot carry float
    // compares over to the integer; a clamp costs 0.5 % of a searching cycle).
    p * f32::from_bits(((n as i32).wrapping_add(127) as u32) << 23)
}

/// `v` within `[lo, hi]` by `max` then `min`: unlike `f32::clamp`, no
/// assertion on the bounds, so no panic path (a NaN `v` gives `lo`).
#[inline(always)]
pub fn clamp(v: f32, lo: f32, hi: f32) -> f32 {
    v.max(lo).min(hi)
}

/// √x, correctly rounded (IEEE 754), NaN below zero: the same bits on
/// every target. On a hard-float ARM target (the Cortex-M4F) it is the FPU's
/// `VSQRT.F32`, one instruction; elsewhere `libm`'s `sqrtf`.
#[inline]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        vsqrt(x)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// The crate's one `unsafe`, for a measured reason: the predictor takes
/// square roots per candidate and per subsurface step, and on the M4F the
/// software routines cost about 7 % of a ring's instructions (185 k of 2.4 M
/// in `scripts/m4-profile.sh` with Newton's iteration, more with `libm`'s
/// bit-by-bit `sqrtf`), where the FPU has the instruction.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[allow(unsafe_code)]
#[inline(always)]
fn vsqrt(x: f32) -> f32 {
    let bits: u32;
    // SAFETY: FPU instructions on s0, which is saved and restored around them
    // (rustc's `sreg` operands need the double-precision `vfp2` feature, which
    // the single-precision M4F target does not enable); the push and pop use
    // only the stack below the stack pointer; besides its result the root
    // touches only the FPSCR's sticky exception flags.
    unsafe {
        core::arch::asm!(
            "vpush {{s0}}",
            "vmov s0, {x}",
            "vsqrt.f32 s0, s0",
            "vmov {r}, s0",
            "vpop {{s0}}",
            x = in(reg) x.to_bits(),
            r = lateout(reg) bits,
            options(pure, nomem),
        );
    }
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_within_bound_against_f64() {
        let mut worst = 0.0f64;
        let mut a = -200.0f64;
        while a <= 200.0 {
            let (s, c) = sin_cos(a as f32);
            // Compare at the f32 the function was given.
            let x = f64::from(a as f32);
            worst = worst.max((f64::from(s) - libm::sin(x)).abs()).max((f64::from(c) - libm::cos(x)).abs());
            a += 0.000_7;
        }
        assert!(worst <= 2e-7, "worst error {worst}");
    }

    #[test]
    fn atan2_within_bound_against_f64() {
        let mut worst = 0.0f64;
        // Every direction at 0.0001 rad, at scales from 10⁻³ to 10⁶, and
        // the axes and diagonals exactly.
        for k in 0..=62_832 {
            let a = -core::f64::consts::PI + k as f64 * 1e-4;
            for scale in [1e-3, 0.7, 1.0, 123.4, 5_000.0, 1e6] {
                let (y, x) = ((a.sin() * scale) as f32, (a.cos() * scale) as f32);
                let want = libm::atan2(f64::from(y), f64::from(x));
                worst = worst.max((f64::from(atan2(y, x)) - want).abs());
            }
        }
        assert!(worst <= 3e-7, "worst error {worst}");
        for (y, x, want) in [
            (0.0, 1.0, 0.0),
            (1.0, 0.0, FRAC_PI_2),
            (0.0, -1.0, core::f32::consts::PI),
            (-1.0, 0.0, -FRAC_PI_2),
            (1.0, 1.0, core::f32::consts::FRAC_PI_4),
            (-2.0, -2.0, -3.0 * core::f32::consts::FRAC_PI_4),
            (0.0, 0.0, 0.0),
        ] {
            assert!((atan2(y, x) - want).abs() <= 3e-7, "atan2({y}, {x}) = {}", atan2(y, x));
        }
        assert!(atan2(f32::NAN, 1.0).is_nan() && atan2(1.0, f32::NAN).is_nan());
    }

    #[test]
    fn ln_and_exp_within_bounds_against_f64() {
        let mut x = f32::MIN_POSITIVE;
        let mut worst = 0.0f64;
        while x < 3e38 {
            worst = worst.max((f64::from(ln_fast(x)) - libm::log(f64::from(x))).abs());
            x *= 1.000_9;
        }
        assert!(worst <= 5e-5, "ln: worst {worst}");
        let mut worst = 0.0f64;
        let mut x = -87.0f32;
        while x <= 88.0 {
            let want = libm::exp(f64::from(x));
            worst = worst.max(((f64::from(exp_fast(x)) - want) / want).abs());
            x += 0.000_37;
        }
        assert!(worst <= 5e-6, "exp: worst {worst}");
        assert_eq!(ln_fast(0.0), f32::NEG_INFINITY);
        assert!(ln_fast(-1.0).is_nan() && ln_fast(f32::NAN).is_nan() && exp_fast(f32::NAN).is_nan());
        assert_eq!(ln_fast(f32::INFINITY), f32::INFINITY);
        assert_eq!(exp_fast(-100.0), 0.0);
        assert_eq!(exp_fast(100.0), f32::INFINITY);
        assert_eq!(exp_fast(0.0), 1.0);
    }

    #[test]
    fn sqrt_is_correctly_rounded() {
        let mut x = 1e-40f32;
        while x < 1e30 {
            // f64's root rounded to f32 is the correctly rounded f32 root
            // (f64 carries more than twice f32's precision).
            let e = libm::sqrt(f64::from(x)) as f32;
            assert_eq!(sqrt(x).to_bits(), e.to_bits(), "sqrt({x})");
            x *= 1.000_37;
        }
        assert_eq!(sqrt(0.0), 0.0);
        assert!(sqrt(-1.0).is_nan() && sqrt(f32::NAN).is_nan());
        assert_eq!(sqrt(f32::INFINITY), f32::INFINITY);
        assert_eq!(sqrt(4.0), 2.0);
    }
}
