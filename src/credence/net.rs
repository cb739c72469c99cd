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
/// The output sum of [`CredenceNet::kappa_at`] stays below 2⁵¹: each of the
/// `HIDDEN` terms is an `i32` weight times σ ≤ 2¹⁶.
const _SUM_FITS: () = assert!(HIDDEN <= 1 << 15);

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
/// With [`KappaBounds`] for its weights (the shipped net has them) it tells
/// prediction where κ cannot reach τ, so that the net need not run there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CredenceNet<'w> {
    weights: &'w QuantWeights,
    bounds: Option<&'w KappaBounds>,
}

/// The bounds of [`SHIPPED_WEIGHTS`], computed by the compiler.
pub static SHIPPED_BOUNDS: KappaBounds = KappaBounds::of(&SHIPPED_WEIGHTS);

impl CredenceNet<'static> {
    /// The net with the checked-in weights ([`SHIPPED_WEIGHTS`]) and their
    /// bounds ([`SHIPPED_BOUNDS`]).
    pub const fn shipped() -> Self {
        Self { weights: &SHIPPED_WEIGHTS, bounds: Some(&SHIPPED_BOUNDS) }
    }
}

impl<'w> CredenceNet<'w> {
    /// A net with other weights (for instance retrained on a real
    /// transducer), without bounds: every candidate runs the net.
    pub const fn new(weights: &'w QuantWeights) -> Self {
        Self { weights, bounds: None }
    }

    /// The same net with bounds, which must be [`KappaBounds::of`] its
    /// weights (bounds of other weights would skip echoes wrongly).
    pub const fn with_bounds(self, bounds: &'w KappaBounds) -> Self {
        Self { weights: self.weights, bounds: Some(bounds) }
    }

    /// The weights in use.
    pub const fn weights(&self) -> &'w QuantWeights {
        self.weights
    }

    /// The bounds in use, if any.
    pub const fn bounds(&self) -> Option<&'w KappaBounds> {
        self.bounds
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
            // Each term is below 2³¹ · 2¹⁶ = 2⁴⁷ in magnitude, HIDDEN of them
            // below 2⁵¹ (`SUM_FITS`): wrapping is exact here.
            acc_out = acc_out.wrapping_add(mul(w.w_out[j].to_bits(), sigmoid_q16(z)));
        }
        // (Both terms below 2⁴⁸ in magnitude after the shift: the sum is exact.)
        let z = i64::from(w.b_out.to_bits()).wrapping_add(acc_out.wrapping_add(1 << (FRAC - 1)) >> FRAC);
        let k16 = sigmoid_q16(z) as u32;
        // 0 ..= 2¹⁶ → 0 ..= 2¹⁵: fits u16, and 2¹⁵ is exactly Kappa::ONE.
        // (`div_ceil`: the rounding half-up of `(k16 + 1) >> 1`, with no sum
        // that could overflow.)
        Kappa::from_bits(k16.div_ceil(2) as u16)
    }
}

impl Credence for CredenceNet<'_> {
    fn kappa(&self, echo: &EchoGeometry) -> Kappa {
        self.kappa_at(echo.range_mm, echo.theta_mdeg)
    }

    fn may_reach(&self, echo: &EchoGeometry, tau: Kappa) -> bool {
        self.bounds.is_none_or(|b| b.may_reach(echo.range_mm, echo.theta_mdeg, tau))
    }
}

/// The widening product of two `i32`.
fn mul(a: i32, b: i32) -> i64 {
    i64::from(a) * i64::from(b)
}

/// The two inputs as Q16.16 bits, exact (step 1 of the module docs); both
/// lie within ±2¹⁷.
fn inputs(range_mm: u32, theta_mdeg: i32) -> (i32, i32) {
    let (r, t) = clamped(range_mm, theta_mdeg);
    (input_r(r), input_t(t))
}

/// R and |θ| clamped to the domain, the nearest domain edge outside it.
fn clamped(range_mm: u32, theta_mdeg: i32) -> (u32, u32) {
    (range_mm.clamp(R_MIN_MM, R_MAX_MM), theta_mdeg.unsigned_abs().min(THETA_MAX_MDEG))
}

/// σ(z) for a Q16.16 pre-activation, as Q0.16 in `0 ..= 2¹⁶` (step 3). The
/// table arithmetic is in `i32` on values the compiler sees are small: the
/// entries are `u16` and `f` is below 2¹², so no step can overflow.
/// Non-decreasing in `z` (the κ bounds rely on it). A `const fn`, so that the
/// shipped net's [`KappaBounds`] are computed by the compiler.
#[inline(always)]
const fn sigmoid_q16(z: i64) -> i32 {
    let abs = z.unsigned_abs();
    let a = if abs < Z_CLAMP as u64 { abs as u32 } else { Z_CLAMP as u32 };
    let i = (a >> STEP_SHIFT) as usize;
    let f = a & ((1 << STEP_SHIFT) - 1);
    let f = f as i32;
    let lo = SIGMOID_TAIL[i].to_bits() as i32;
    let u = if i + 1 < SIGMOID_ENTRIES {
        let next = SIGMOID_TAIL[i + 1].to_bits() as i32;
        lo - (((lo - next) * f + (1 << (STEP_SHIFT - 1))) >> STEP_SHIFT)
    } else {
        lo
    };
    if z >= 0 {
        ONE_Q16 - u
    } else {
        u
    }
}

/// Range bins of [`KappaBounds`]: `(clamp(R) − R_MIN_MM) >> 8`, 256 mm each.
pub const BOUND_R_SHIFT: u32 = 8;
/// Angle bins of [`KappaBounds`]: `min(|θ|, THETA_MAX_MDEG) >> 9`, 0.512° each.
pub const BOUND_THETA_SHIFT: u32 = 9;
const BOUND_R_BINS: usize = ((R_MAX_MM - R_MIN_MM) >> BOUND_R_SHIFT) as usize + 1;
const BOUND_THETA_BINS: usize = (THETA_MAX_MDEG >> BOUND_THETA_SHIFT) as usize + 1;

/// Upper bounds of a net's κ over small boxes of (R, |θ|), so that
/// prediction can skip the net where κ cannot reach its threshold τ
/// ([`Credence::may_reach`]). Skipping changes no prediction: a candidate
/// whose κ is below τ is passed over either way.
///
/// Each bound is proven, not sampled: the box's input intervals are carried
/// through the net's own integer steps (each hidden pre-activation's extremes
/// by the signs of its weights, then σ, which is non-decreasing, then each
/// hidden unit at whichever end its output weight favours), and rounded up
/// to 1/255. A table is 20 × 88 bytes; [`KappaBounds::of`] is a `const fn`,
/// so a board builds one for its own weights at compile time.
///
/// ```
/// use echoloc::credence::net::{CredenceNet, KappaBounds, SHIPPED_WEIGHTS};
/// use echoloc::credence::{Credence, EchoGeometry, Kappa};
///
/// static BOUNDS: KappaBounds = KappaBounds::of(&SHIPPED_WEIGHTS);
/// let net = CredenceNet::new(&SHIPPED_WEIGHTS).with_bounds(&BOUNDS);
/// let tau = Kappa::from_num(0.5);
/// // Far off axis the net cannot reach τ, and says so without running.
/// let far_off = EchoGeometry { range_mm: 2000, theta_mdeg: 40_000, delta_mdeg: 0 };
/// assert!(!net.may_reach(&far_off, tau) && net.kappa(&far_off) < tau);
/// // On axis it may (and does).
/// let on_axis = EchoGeometry { range_mm: 2000, theta_mdeg: 0, delta_mdeg: 0 };
/// assert!(net.may_reach(&on_axis, tau) && net.kappa(&on_axis) >= tau);
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KappaBounds {
    /// `ceil(255 · max κ)` over each bin, by range bin then angle bin.
    upper: [[u8; BOUND_THETA_BINS]; BOUND_R_BINS],
}

impl KappaBounds {
    /// The bounds of the net with these weights.
    pub const fn of(w: &QuantWeights) -> Self {
        let mut upper = [[0u8; BOUND_THETA_BINS]; BOUND_R_BINS];
        let mut k = 0;
        while k < BOUND_R_BINS {
            let r_lo = R_MIN_MM + ((k as u32) << BOUND_R_SHIFT);
            let r_hi = min_u32(r_lo + (1 << BOUND_R_SHIFT) - 1, R_MAX_MM);
            let mut m = 0;
            while m < BOUND_THETA_BINS {
                let t_lo = (m as u32) << BOUND_THETA_SHIFT;
                let t_hi = min_u32(t_lo + (1 << BOUND_THETA_SHIFT) - 1, THETA_MAX_MDEG);
                let bits = kappa_max_bits(w, (r_lo, r_hi), (t_lo, t_hi)) as u32;
                // ceil(255 · bits / 2¹⁵): at most 255.
                upper[k][m] = ((bits * 255 + (1 << 15) - 1) >> 15) as u8;
                m += 1;
            }
            k += 1;
        }
        Self { upper }
    }

    /// The bound for an echo, in 1/255 of κ.
    #[inline]
    pub fn upper_255(&self, range_mm: u32, theta_mdeg: i32) -> u8 {
        let (r, t) = clamped(range_mm, theta_mdeg);
        self.upper
            .get(((r - R_MIN_MM) >> BOUND_R_SHIFT) as usize)
            .and_then(|row| row.get((t >> BOUND_THETA_SHIFT) as usize))
            .copied()
            .unwrap_or(u8::MAX)
    }

    /// Whether κ at this echo can be at least `tau`.
    #[inline]
    pub fn may_reach(&self, range_mm: u32, theta_mdeg: i32, tau: Kappa) -> bool {
        // ub / 255 < τ  ⇔  ub · 2¹⁵ < τ_bits · 255.
        u32::from(self.upper_255(range_mm, theta_mdeg)) << 15 >= u32::from(tau.to_bits()) * 255
    }
}

const fn min_u32(a: u32, b: u32) -> u32 {
    if a < b {
        a
    } else {
        b
    }
}

const fn max_i64(a: i64, b: i64) -> i64 {
    if a > b {
        a
    } else {
        b
    }
}

const fn min_i64(a: i64, b: i64) -> i64 {
    if a < b {
        a
    } else {
        b
    }
}

/// The largest κ (U1F15 bits) the net's integer algorithm gives for any
/// clamped input in the box `r ∈ [r.0, r.1]`, `|θ| ∈ [t.0, t.1]` (both within
/// the domain).
const fn kappa_max_bits(w: &QuantWeights, r: (u32, u32), t: (u32, u32)) -> u16 {
    // Step 1 is increasing in each input.
    let x0 = (input_r(r.0) as i64, input_r(r.1) as i64);
    let x1 = (input_t(t.0) as i64, input_t(t.1) as i64);
    let mut acc_out: i64 = 0;
    let mut j = 0;
    while j < HIDDEN {
        let (w0, w1) = (w.w_hidden[j][0].to_bits() as i64, w.w_hidden[j][1].to_bits() as i64);
        let lo = min_i64(w0 * x0.0, w0 * x0.1) + min_i64(w1 * x1.0, w1 * x1.1);
        let hi = max_i64(w0 * x0.0, w0 * x0.1) + max_i64(w1 * x1.0, w1 * x1.1);
        let b = w.b_hidden[j].to_bits() as i64;
        // The rounding shift is non-decreasing, and so is σ.
        let h_lo = sigmoid_q16(b + ((lo + (1 << (FRAC - 1))) >> FRAC)) as i64;
        let h_hi = sigmoid_q16(b + ((hi + (1 << (FRAC - 1))) >> FRAC)) as i64;
        let v = w.w_out[j].to_bits() as i64;
        acc_out += max_i64(v * h_lo, v * h_hi);
        j += 1;
    }
    let z = w.b_out.to_bits() as i64 + ((acc_out + (1 << (FRAC - 1))) >> FRAC);
    ((sigmoid_q16(z) as u32 + 1) >> 1) as u16
}

/// Step 1 for a range already clamped to the domain.
const fn input_r(r: u32) -> i32 {
    (r as i32 - R_CENTRE_MM) << (FRAC - R_SCALE_LOG2)
}

/// Step 1 for an angle already clamped to the domain.
const fn input_t(t: u32) -> i32 {
    (t as i32 - THETA_CENTRE_MDEG) << (FRAC - THETA_SCALE_LOG2)
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
