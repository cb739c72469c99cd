//! `sin`, `cos` and `sqrt` in `f32` arithmetic alone. `libm`'s `sinf` and
//! `cosf` reduce and evaluate in `f64`, which the Cortex-M4F does in
//! software (≈ 1 000 instructions a call, measured by `ekf_cost`), and its
//! `sqrtf` has no ARM intrinsic; these cost tens of instructions with the
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
