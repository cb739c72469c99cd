//! The quantised 2-10-1 credence net: κ(R, |θ|) with integer arithmetic only
//! (paper §4, DESIGN §4.4).
//!
//! The net was trained on the host by `echoloc-lab train` (a float net, RPROP,
//! leave-one-day-out evaluation; see `docs/credence.md`); the tool quantised it
//! and wrote the weights into `weights.rs`. This module is the firmware form:
//! no float, no division, no allocator, no panic, so it runs the same on a
//! Cortex-M4F and on a Cortex-M0 (`thumbv6m-none-eabi`, no FPU).
//!
//! # The float net it stands for
//!
//! ```text
//! x₀ = (R − 3000 mm) / 2048 mm                 R clamped to 500 ..= 5500 mm
//! x₁ = (|θ| − 22.5°) / 16.384°                 |θ| clamped to 0 ..= 45°
//! hⱼ = σ(bⱼ + wⱼ₀·x₀ + wⱼ₁·x₁)                 j = 0 .. 10, σ(z) = 1 / (1 + e^−z)
//! κ  = σ(b + Σⱼ vⱼ·hⱼ)
//! ```
//!
//! The input scales are powers of two so that the inputs are exact in fixed
//! point: in millimetres and millidegrees, `x₀ = (R − 3000)·2⁻¹¹` and
//! `x₁ = (θ_mdeg − 22 500)·2⁻¹⁴`. The grid of the training data (R 500 … 5500 mm,
//! θ 0 … 45°) is the whole input domain; outside it the net answers with the
//! κ of the nearest domain edge (below `R_min` the sensor is blind anyway,
//! and the data hold κ ≈ 0 at 45°).
//!
//! # The integer algorithm, exactly
//!
//! Every quantity is a raw integer with a stated Q-format (the `fixed` types
//! name the formats of the stored tables):
//!
//! 1. inputs, [`I16F16`] bits: `x₀ = (clamp(R, 500, 5500) − 3000) << 5`,
//!    `x₁ = (min(|θ_mdeg|, 45 000) − 22 500) << 2`;
//! 2. hidden pre-activation, Q16.16 in `i64`:
//!    `zⱼ = bⱼ + ((wⱼ₀·x₀ + wⱼ₁·x₁ + 2¹⁵) >> 16)` (arithmetic shift), then
//!    clamped to `±2²⁰` (±16.0; σ is flat to within 2⁻²³ beyond);
//! 3. σ by table: `a = |z|`, `i = a >> 12`, `f = a & 0xFFF`; with
//!    `L[k] = round(2¹⁶·(1 − σ(k/16)))` ([`SIGMOID_TAIL`], 257 entries,
//!    [`U0F16`](fixed::types::U0F16)), `u = L[i] − (((L[i] − L[i+1])·f + 2¹¹) >> 12)` (`u = L[256]`
//!    when `i = 256`), and `σ(z) = 2¹⁶ − u` for `z ≥ 0`, `u` for `z < 0`:
//!    hidden activations are Q0.16 in `0 ..= 2¹⁶`;
//! 4. output pre-activation: `z = b + ((Σⱼ vⱼ·hⱼ + 2¹⁵) >> 16)`, `i64`
//!    accumulator, clamped to `±2²⁰`, then σ as in step 3;
//! 5. κ as [`Kappa`] (U1F15) bits: `(σ + 1) >> 1`, so `0 ..= 32 768`.
//!
//! Host tests pin this bit-exactly against an independent integer reference
//! and bound it within 1/256 of the float net over the dense grid
//! 0.5° × 10 mm of the domain (`host-tests/tests/credence_net.rs`).
//!
//! # Example
//!
//! ```
//! use echoloc::credence::net::CredenceNet;
//! use echoloc::credence::{Credence, EchoGeometry, Kappa};
//!
//! let net = CredenceNet::shipped();
//! // A wall 1.5 m away, square on the transducer's axis: a confident echo.
//! let on_axis = EchoGeometry { range_mm: 1500, theta_mdeg: 0, delta_mdeg: 0 };
//! // The same wall seen 12.5° off axis: the first null of the beam.
//! let null = EchoGeometry { range_mm: 1500, theta_mdeg: 12_500, delta_mdeg: 0 };
//! assert!(net.kappa(&on_axis) > Kappa::from_num(0.8));
//! assert!(net.kappa(&null) < net.kappa(&on_axis));
//! // The cone is symmetric: the sign of θ does not matter.
//! let mirrored = EchoGeometry { theta_mdeg: -12_500, ..null };
//! assert_eq!(net.kappa(&null), net.kappa(&mirrored));
//! ```

use fixed::types::I16F16;

use super::{Credence, EchoGeometry, Kappa};

pub use super::weights::{FLOAT_WEIGHTS, SHIPPED_WEIGHTS, SIGMOID_TAIL};

/// Hidden units of the 2-10-1 net.
pub const HIDDEN: usize = 10;

/// Lowest range of the input domain, mm (MARGE's `R_min`, paper §4.2).
pub const R_MIN_MM: u32 = 500;
/// Highest range of the input domain, mm (MARGE's `R_max`, paper §4.2).
pub const R_MAX_MM: u32 = 5500;
/// Widest |θ| of the input domain, millidegrees (paper §4.2: ±45° "to account for all possible lobes").
pub const THETA_MAX_MDEG: u32 = 45_000;
/// Centre of the range input, mm: `x₀ = (R − R_CENTRE_MM) / 2^R_SCALE_LOG2`.
pub const R_CENTRE_MM: i32 = 3000;
/// log₂ of the range input's scale, mm (2048 mm).
pub const R_SCALE_LOG2: u32 = 11;
/// Centre of the angle input, millidegrees: `x₁ = (|θ| − THETA_CENTRE_MDEG) / 2^THETA_SCALE_LOG2`.
pub const THETA_CENTRE_MDEG: i32 = 22_500;
/// log₂ of the angle input's scale, millidegrees (16.384°).
pub const THETA_SCALE_LOG2: u32 = 14;
/// Step of the σ table in its argument: `1 / 2^SIGMOID_STEP_LOG2` (1/16).
pub const SIGMOID_STEP_LOG2: u32 = 4;
/// Entries of the σ table: arguments `0, 1/16, …, 16`.
pub const SIGMOID_ENTRIES: usize = 257;

/// Fractional bits of a Q16.16 value.
const FRAC: u32 = 16;
/// One in Q0.16 (a hidden activation or σ output).
const ONE_Q16: i32 = 1 << FRAC;
/// Largest pre-activation magnitude kept, Q16.16: 16.0, the end of the σ table.
const Z_CLAMP: i64 = ((SIGMOID_ENTRIES as i64) - 1) << (FRAC - SIGMOID_STEP_LOG2);
/// Bits of `|z|` below one table step.
const STEP_SHIFT: u32 = FRAC - SIGMOID_STEP_LOG2;

/// Raw Q0.16 bits as [`U0F16`](fixed::types::U0F16), in a `const` context
/// (for the generated σ table).
pub(crate) const fn u0f16_table<const N: usize>(bits: [u16; N]) -> [fixed::types::U0F16; N] {
    let mut out = [fixed::types::U0F16::ZERO; N];
    let mut i = 0;
    while i < N {
        out[i] = fixed::types::U0F16::from_bits(bits[i]);
        i += 1;
    }
    out
}

/// The quantised weights: every value is [`I16F16`] (Q16.16 in an `i32`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QuantWeights {
    /// Input → hidden weights `wⱼ₀` (range input), `wⱼ₁` (angle input).
    pub w_hidden: [[I16F16; 2]; HIDDEN],
    /// Hidden biases `bⱼ`.
    pub b_hidden: [I16F16; HIDDEN],
    /// Hidden → output weights `vⱼ`.
    pub w_out: [I16F16; HIDDEN],
    /// Output bias `b`.
    pub b_out: I16F16,
}

/// The float weights the quantised ones were rounded from, for host-side
/// reference (a `const`: nothing of it reaches a firmware image unless used).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatWeights {
    /// Input → hidden weights `wⱼ₀` (range input), `wⱼ₁` (angle input).
    pub w_hidden: [[f64; 2]; HIDDEN],
    /// Hidden biases `bⱼ`.
    pub b_hidden: [f64; HIDDEN],
    /// Hidden → output weights `vⱼ`.
    pub w_out: [f64; HIDDEN],
    /// Output bias `b`.
    pub b_out: f64,
}

/// The quantised 2-10-1 credence net, a [`Credence`] model over (R, |θ|).
///
/// It ignores `delta_mdeg`: the paper's net (and its training data, taken
/// square on to a long wall) has δ = 0; prediction applies its δ test apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CredenceNet<'w> {
    weights: &'w QuantWeights,
}

impl CredenceNet<'static> {
    /// The net with the checked-in weights ([`SHIPPED_WEIGHTS`]).
    pub const fn shipped() -> Self {
        Self { weights: &SHIPPED_WEIGHTS }
    }
}

impl<'w> CredenceNet<'w> {
    /// A net with other weights (for instance retrained on a real transducer).
    pub const fn new(weights: &'w QuantWeights) -> Self {
        Self { weights }
    }

    /// The weights in use.
    pub const fn weights(&self) -> &'w QuantWeights {
        self.weights
    }

    /// κ for a range (mm) and an off-axis angle (millidegrees, either sign).
    pub fn kappa_at(&self, range_mm: u32, theta_mdeg: i32) -> Kappa {
        let (x0, x1) = inputs(range_mm, theta_mdeg);
        let w = self.weights;
        let mut acc_out: i64 = 0;
        for j in 0..HIDDEN {
            // i32 × i32 → i64: one multiply(-accumulate) instruction each on a Cortex-M4.
            let acc = mul(w.w_hidden[j][0].to_bits(), x0) + mul(w.w_hidden[j][1].to_bits(), x1);
            let z = i64::from(w.b_hidden[j].to_bits()) + ((acc + (1 << (FRAC - 1))) >> FRAC);
            acc_out += mul(w.w_out[j].to_bits(), sigmoid_q16(z));
        }
        let z = i64::from(w.b_out.to_bits()) + ((acc_out + (1 << (FRAC - 1))) >> FRAC);
        let k16 = sigmoid_q16(z) as u32;
        // 0 ..= 2¹⁶ → 0 ..= 2¹⁵: fits u16, and 2¹⁵ is exactly Kappa::ONE.
        Kappa::from_bits(((k16 + 1) >> 1) as u16)
    }
}

impl Credence for CredenceNet<'_> {
    fn kappa(&self, echo: &EchoGeometry) -> Kappa {
        self.kappa_at(echo.range_mm, echo.theta_mdeg)
    }
}

/// The widening product of two `i32`.
fn mul(a: i32, b: i32) -> i64 {
    i64::from(a) * i64::from(b)
}

/// The two inputs as Q16.16 bits, exact (step 1 of the module docs); both
/// lie within ±2¹⁷.
fn inputs(range_mm: u32, theta_mdeg: i32) -> (i32, i32) {
    let r = range_mm.clamp(R_MIN_MM, R_MAX_MM) as i32;
    let t = theta_mdeg.unsigned_abs().min(THETA_MAX_MDEG) as i32;
    let x0 = (r - R_CENTRE_MM) << (FRAC - R_SCALE_LOG2);
    let x1 = (t - THETA_CENTRE_MDEG) << (FRAC - THETA_SCALE_LOG2);
    (x0, x1)
}

/// σ(z) for a Q16.16 pre-activation, as Q0.16 in `0 ..= 2¹⁶` (step 3). The
/// table arithmetic fits `u32`: a step's difference is below 2¹¹ and `f` below 2¹².
#[inline(always)]
fn sigmoid_q16(z: i64) -> i32 {
    let a = z.unsigned_abs().min(Z_CLAMP as u64) as u32;
    let i = (a >> STEP_SHIFT) as usize;
    let f = a & ((1 << STEP_SHIFT) - 1);
    let lo = u32::from(SIGMOID_TAIL[i].to_bits());
    let u = match SIGMOID_TAIL.get(i + 1) {
        Some(next) => lo - (((lo - u32::from(next.to_bits())) * f + (1 << (STEP_SHIFT - 1))) >> STEP_SHIFT),
        None => lo,
    } as i32;
    if z >= 0 {
        ONE_Q16 - u
    } else {
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigmoid_table_ends() {
        assert_eq!(sigmoid_q16(0), 1 << 15);
        assert_eq!(sigmoid_q16(Z_CLAMP), ONE_Q16 - i32::from(SIGMOID_TAIL[256].to_bits()));
        assert_eq!(sigmoid_q16(i64::MIN + 1), i32::from(SIGMOID_TAIL[256].to_bits()));
        // Symmetric: σ(−z) = 1 − σ(z), exactly.
        for z in [1, 4095, 4096, 100_000, 1 << 20] {
            assert_eq!(sigmoid_q16(-z), ONE_Q16 - sigmoid_q16(z), "z = {z}");
        }
    }

    #[test]
    fn inputs_are_exact_and_clamped() {
        assert_eq!(inputs(3000, 22_500), (0, 0));
        assert_eq!(inputs(5048, 0), (1 << 16, -22_500 * 4));
        assert_eq!(inputs(0, i32::MIN), inputs(500, 45_000));
        assert_eq!(inputs(u32::MAX, -10_000), inputs(5500, 10_000));
    }

    #[test]
    fn kappa_is_within_bounds_for_extreme_weights() {
        let big = I16F16::MAX;
        let w = QuantWeights {
            w_hidden: [[big, I16F16::MIN]; HIDDEN],
            b_hidden: [big; HIDDEN],
            w_out: [big; HIDDEN],
            b_out: I16F16::MIN,
        };
        let net = CredenceNet::new(&w);
        for (r, t) in [(0, 0), (5500, 45_000), (u32::MAX, i32::MIN), (3000, 22_500)] {
            assert!(net.kappa_at(r, t) <= Kappa::ONE);
        }
    }
}
