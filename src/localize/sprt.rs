//! Wald's sequential probability ratio test (DESIGN §4.8, issue #48): how
//! a place is handed to the tracker, dropped, or left undecided.
//!
//! Two hypotheses, each with the log-likelihood of every reading since
//! they split; their difference `Λ` is the evidence. Wald's bounds for a
//! wrong acceptance at most `α` and a wrong rejection at most `β`:
//! accept the leader when `Λ ≥ A = ln((1 − β)/α)`, reject it when
//! `Λ ≤ B = ln(β/(1 − α))`, else keep observing. Then (Wald 1945, by the
//! likelihood ratio's martingale) the chance of accepting the wrong one is
//! at most `α/(1 − β)`, whatever the readings' distribution, *if* each
//! reading's log-ratio is the true one of independent readings.
//!
//! A sonar's readings are not independent (one wall answers several
//! transducers, one person several cycles) and the beam model is not the
//! truth, so each reading's log-ratio is clipped to `±clip` before it is
//! summed ([`Sprt::evidence`]): no single echo, however unlikely under one
//! place, moves the test by more than `clip`. How far to clip, so that the
//! error rate holds in practice, is measured on runs whose truth is known.
//!
//! ```
//! use echoloc::localize::sprt::{Decision, Sprt};
//!
//! // A wrong hand-off at most once in a thousand, a wrong drop likewise.
//! let test = Sprt::new(1e-3, 1e-3, 2.0).unwrap();
//! assert!((test.accept_bound() - (0.999f32 / 0.001).ln()).abs() < 1e-3);
//! // Each reading favours the leader by 0.1 nats ...
//! let mut lead = 0.0;
//! let mut readings = 0;
//! while test.decide(lead) == Decision::Continue {
//!     lead += test.evidence(0.1);
//!     readings += 1;
//! }
//! // ... so it is accepted after ⌈6.907 / 0.1⌉ of them.
//! assert_eq!((test.decide(lead), readings), (Decision::Accept, 70));
//! // One echo 40 nats against it counts only the clip.
//! assert_eq!(test.evidence(-40.0), -2.0);
//! ```

use crate::f32math::ln_fast;

/// What the test says of the evidence so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Decision {
    /// The leader is the place: hand it off (or, for a rival, take over).
    Accept,
    /// The leader is refuted: drop it.
    Reject,
    /// Neither yet: keep observing.
    Continue,
}

/// A settings error: the rates must lie in `(0, ½)`, the clip be positive
/// and finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SprtError {
    /// `α` or `β` outside `(0, ½)`, or NaN.
    Rate,
    /// The clip is not a positive finite number.
    Clip,
}

/// The test's bounds and each reading's clip.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sprt {
    accept: f32,
    reject: f32,
    clip: f32,
}

impl Sprt {
    /// The test for a wrong acceptance at most `alpha` and a wrong
    /// rejection at most `beta` (each in `(0, ½)`), each reading's
    /// log-ratio clipped to `±clip` nats.
    pub fn new(alpha: f32, beta: f32, clip: f32) -> Result<Self, SprtError> {
        let rate = |r: f32| r > 0.0 && r < 0.5;
        if !rate(alpha) || !rate(beta) {
            return Err(SprtError::Rate);
        }
        if !(clip > 0.0 && clip.is_finite()) {
            return Err(SprtError::Clip);
        }
        Ok(Self { accept: ln_fast((1.0 - beta) / alpha), reject: ln_fast(beta / (1.0 - alpha)), clip })
    }

    /// `A`: the lead that accepts.
    pub fn accept_bound(&self) -> f32 {
        self.accept
    }

    /// `B` (negative): the lead that rejects.
    pub fn reject_bound(&self) -> f32 {
        self.reject
    }

    /// One reading's log-ratio as the test sums it: clipped to `±clip`; a
    /// NaN (a reading neither model can score) says nothing.
    pub fn evidence(&self, log_ratio: f32) -> f32 {
        if log_ratio.is_nan() {
            0.0
        } else {
            log_ratio.clamp(-self.clip, self.clip)
        }
    }

    /// The decision on a summed lead (NaN: continue).
    pub fn decide(&self, lead: f32) -> Decision {
        if lead >= self.accept {
            Decision::Accept
        } else if lead <= self.reject {
            Decision::Reject
        } else {
            Decision::Continue
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bounds by hand: α = β = 0.01 gives ±ln 99 = ±4.595.
    #[test]
    fn the_bounds_by_hand() {
        let t = Sprt::new(0.01, 0.01, 1.0).unwrap();
        assert!((t.accept_bound() - 4.595_12).abs() < 1e-3);
        assert!((t.reject_bound() + 4.595_12).abs() < 1e-3);
        // Unequal rates: α = 10⁻³, β = 0.1: ln(0.9/0.001) = 6.8024 and
        // ln(0.1/0.999) = −2.3016.
        let t = Sprt::new(1e-3, 0.1, 1.0).unwrap();
        assert!((t.accept_bound() - 6.802_4).abs() < 1e-3);
        assert!((t.reject_bound() + 2.301_6).abs() < 1e-3);
        assert_eq!(t.decide(f32::NAN), Decision::Continue);
        assert_eq!(t.evidence(f32::NAN), 0.0);
        assert_eq!(t.evidence(f32::INFINITY), 1.0);
    }

    #[test]
    fn bad_settings_are_refused() {
        for (a, b) in [(0.0, 0.1), (0.5, 0.1), (0.1, -0.1), (f32::NAN, 0.1), (0.1, 1.0)] {
            assert_eq!(Sprt::new(a, b, 1.0), Err(SprtError::Rate));
        }
        for c in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert_eq!(Sprt::new(0.01, 0.01, c), Err(SprtError::Clip));
        }
    }

    /// splitmix64 and Box–Muller, in the test: the crate's own generator is
    /// not what is tested here.
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^= z >> 31;
            ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn next(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (core::f64::consts::TAU * v).cos()
        }
    }

    /// Wald's guarantee, checked by simulation: readings `x ~ N(0, 1)`
    /// tested against `N(δ, 1)` have log-ratio `δx − δ²/2`; the test
    /// accepts the wrong one at most `α/(1 − β)` of the time (20 000 runs,
    /// allowing three binomial standard deviations), and the true one is
    /// accepted when the truth is the other, as often as `1 − α`.
    #[test]
    fn the_error_rate_holds_on_independent_readings() {
        let (alpha, beta) = (0.01f32, 0.01f32);
        let t = Sprt::new(alpha, beta, 100.0).unwrap();
        let mut g = Normal(7);
        let runs = 20_000;
        for delta in [0.3f64, 1.0] {
            let mut wrong = 0;
            let mut right = 0;
            for run in 0..2 * runs {
                // Even runs: the truth is N(0, 1) and the leader tested is
                // N(δ, 1); odd: the truth is the leader.
                let mean = if run % 2 == 0 { 0.0 } else { delta };
                let mut lead = 0.0f32;
                let decision = loop {
                    let x = mean + g.next();
                    lead += t.evidence((delta * x - 0.5 * delta * delta) as f32);
                    match t.decide(lead) {
                        Decision::Continue => {}
                        d => break d,
                    }
                };
                match (run % 2, decision) {
                    (0, Decision::Accept) => wrong += 1,
                    (1, Decision::Accept) => right += 1,
                    _ => {}
                }
            }
            let bound = f64::from(alpha / (1.0 - beta));
            let sd = (bound * (1.0 - bound) / f64::from(runs)).sqrt();
            let rate = f64::from(wrong) / f64::from(runs);
            assert!(rate <= bound + 3.0 * sd, "δ {delta}: wrong acceptances {rate} against {bound}");
            // And it is not a test that never accepts.
            assert!(f64::from(right) / f64::from(runs) >= 0.98, "δ {delta}: right {right}");
        }
    }

    /// Why the clip: readings that share one cause (the same wall answering
    /// four transducers) each carry the same log-ratio; unclipped, one cycle
    /// of a wrong place's lucky echoes accepts it, clipped it does not.
    #[test]
    fn the_clip_bounds_a_cycle() {
        let loose = Sprt::new(1e-3, 1e-3, 100.0).unwrap();
        let tight = Sprt::new(1e-3, 1e-3, 0.5).unwrap();
        let cycle = [3.0f32; 4];
        let sum = |t: &Sprt| cycle.iter().map(|&r| t.evidence(r)).sum::<f32>();
        assert_eq!(loose.decide(sum(&loose)), Decision::Accept);
        assert_eq!(tight.decide(sum(&tight)), Decision::Continue);
        assert_eq!(sum(&tight), 2.0);
    }
}
