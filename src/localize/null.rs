//! The null hypothesis (DESIGN §4.8, issue #48): "the robot is at none of
//! these places". A place's readings are scored by the beam model against
//! what the map says should be heard there; the null scores the same
//! readings by what the readings themselves have looked like so far,
//! knowing nothing of any place: the sequential predictive distribution of
//! a reading's *bin* (no echo, or an echo in one of [`BINS`] equal slices of
//! the window) with the Krichevsky–Trofimov estimator,
//! `P(b) = (n_b + ½) / (n + (BINS + 1)/2)`, an echo's density that mass
//! spread evenly over its slice. Every reading is scored before it is
//! counted, so the product of the scores is a proper likelihood of the
//! whole sequence (a place that only matches the ring's usual mix of short
//! and long echoes gains nothing over it); the counts are halved whenever
//! they pass [`NullModel::memory`], so it follows a corridor turning into a
//! hall.
//!
//! A place must explain the readings better than their own recent mix
//! does before the sequential test ([`super::sprt`]) may prefer it; where
//! clutter hides the walls, no place does, and the answer is *searching*.
//!
//! ```
//! use echoloc::localize::null::{NullModel, BINS};
//! use echoloc::referencing::Reading;
//!
//! let mut null = NullModel::new(408.0, 5500.0, 400.0).unwrap();
//! // Nothing seen yet: every bin is as likely as another.
//! let first = null.log_likelihood(Reading::NoEcho);
//! assert!((first - (1.0 / (BINS as f32 + 1.0)).ln()).abs() < 1e-3);
//! // After many misses a miss is nearly certain: the null explains a ring
//! // that hears nothing as well as any place could.
//! for _ in 0..200 {
//!     null.log_likelihood(Reading::NoEcho);
//! }
//! assert!(null.log_likelihood(Reading::NoEcho) > -0.05);
//! ```

use crate::f32math::ln_fast;
use crate::referencing::Reading;

/// The window's equal slices an echo is counted in.
pub const BINS: usize = 16;

/// Why a null model was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NullError {
    /// The window is empty or not finite.
    Window,
    /// The memory is not finite or is smaller than the bins.
    Memory,
}

/// The null hypothesis's counts: no echo (index 0) and the window's slices.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NullModel {
    r_min_mm: f32,
    r_max_mm: f32,
    memory: f32,
    counts: [f32; BINS + 1],
    total: f32,
}

impl NullModel {
    /// Over the window `r_min_mm..r_max_mm` (an echo beyond `r_max_mm`
    /// counts as none, as the beam model takes it; one nearer than
    /// `r_min_mm` falls in the first slice), forgetting by halves once
    /// more than `memory` readings are counted. Refused: a window that is
    /// empty or not finite ([`NullError::Window`]), a memory that is not
    /// finite or holds fewer readings than there are bins, [`BINS`] + 1
    /// ([`NullError::Memory`]).
    pub fn new(r_min_mm: f32, r_max_mm: f32, memory: f32) -> Result<Self, NullError> {
        if !(r_min_mm.is_finite() && r_max_mm.is_finite() && r_max_mm > r_min_mm) {
            return Err(NullError::Window);
        }
        if !(memory.is_finite() && memory >= (BINS + 1) as f32) {
            return Err(NullError::Memory);
        }
        Ok(Self { r_min_mm, r_max_mm, memory, counts: [0.0; BINS + 1], total: 0.0 })
    }

    /// How many readings it counts before halving.
    pub fn memory(&self) -> f32 {
        self.memory
    }

    /// Forgets everything counted.
    pub fn clear(&mut self) {
        self.counts = [0.0; BINS + 1];
        self.total = 0.0;
    }

    /// The bin of `reading` (`None`: invalid, it says nothing).
    fn bin(&self, reading: Reading) -> Option<usize> {
        match reading {
            Reading::Invalid => None,
            Reading::NoEcho => Some(0),
            Reading::Echo { range_mm } => {
                let r = range_mm as f32;
                if r > self.r_max_mm {
                    return Some(0);
                }
                let f = (r - self.r_min_mm) / (self.r_max_mm - self.r_min_mm);
                // `f` < 0 (nearer than the window) saturates to slice 0.
                let i = (f * BINS as f32) as usize;
                Some(1 + i.min(BINS - 1))
            }
        }
    }

    /// The reading's probability (no echo) or density per metre (an echo)
    /// under the counts so far, without counting it; 1 for an invalid one.
    pub fn likelihood(&self, reading: Reading) -> f32 {
        let Some(b) = self.bin(reading) else { return 1.0 };
        let p = (self.counts[b] + 0.5) / (self.total + 0.5 * (BINS + 1) as f32);
        if b == 0 {
            p
        } else {
            p * BINS as f32 / ((self.r_max_mm - self.r_min_mm) * 1e-3)
        }
    }

    /// Counts the reading (after it is scored).
    pub fn observe(&mut self, reading: Reading) {
        let Some(b) = self.bin(reading) else { return };
        if self.total + 1.0 > self.memory {
            for c in &mut self.counts {
                *c *= 0.5;
            }
            self.total *= 0.5;
        }
        self.counts[b] += 1.0;
        self.total += 1.0;
    }

    /// The reading's log-likelihood under the counts so far, then counted:
    /// a cycle's readings scored one after another sum to their sequence's
    /// log-likelihood under the null (0 for an invalid reading).
    pub fn log_likelihood(&mut self, reading: Reading) -> f32 {
        let l = ln_fast(self.likelihood(reading));
        self.observe(reading);
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn echo(range_mm: u32) -> Reading {
        Reading::Echo { range_mm }
    }

    /// What the null predicts is a distribution over readings: the no-echo
    /// mass plus the echo density integrated over the window (summed over
    /// a fine grid of echo ranges, a brute force) is 1, before any reading
    /// and after a skewed run of them.
    #[test]
    fn the_prediction_is_a_distribution() {
        let mut null = NullModel::new(408.0, 5500.0, 50.0).unwrap();
        let check = |null: &NullModel| {
            let step_mm = 1u32;
            let mut total = f64::from(null.likelihood(Reading::NoEcho));
            let mut r = 408;
            while r < 5500 {
                total += f64::from(null.likelihood(echo(r))) * f64::from(step_mm) * 1e-3;
                r += step_mm;
            }
            assert!((total - 1.0).abs() < 2e-3, "total {total}");
        };
        check(&null);
        for i in 0..300u32 {
            null.observe(if i % 3 == 0 { Reading::NoEcho } else { echo(600 + (i * 37) % 900) });
        }
        check(&null);
    }

    /// The Krichevsky–Trofimov estimate by hand: after 3 misses and 1 echo
    /// in the first slice, a miss has (3 + ½)/(4 + 17/2) and an echo in the
    /// first slice (1 + ½)/(4 + 17/2) spread over 5.092 m / 16; an invalid
    /// reading neither scores nor counts.
    #[test]
    fn the_estimate_by_hand() {
        let mut null = NullModel::new(408.0, 5500.0, 400.0).unwrap();
        for r in [Reading::NoEcho, Reading::Invalid, Reading::NoEcho, echo(500), Reading::NoEcho, echo(9000)] {
            null.observe(r);
        }
        // The echo at 9 m is beyond the window: a miss (4 misses, 1 echo).
        let n = 5.0 + 8.5;
        assert!((null.likelihood(Reading::NoEcho) - 4.5 / n).abs() < 1e-6);
        let slice_m = 5.092 / 16.0;
        assert!((null.likelihood(echo(420)) - 1.5 / n / slice_m).abs() < 1e-5);
        // Nearer than the window: the first slice.
        assert_eq!(null.likelihood(echo(100)), null.likelihood(echo(420)));
        assert!((null.likelihood(echo(3000)) - 0.5 / n / slice_m).abs() < 1e-5);
        assert_eq!(null.likelihood(Reading::Invalid), 1.0);
        let before = null;
        assert_eq!(null.log_likelihood(Reading::Invalid), 0.0);
        assert_eq!(null, before);
    }

    /// Halving keeps the bins' proportions: after the memory is passed the
    /// estimate is what the halved counts give, by hand.
    #[test]
    fn forgetting_halves_the_counts() {
        let mut null = NullModel::new(408.0, 5500.0, 20.0).unwrap();
        for _ in 0..20 {
            null.observe(Reading::NoEcho);
        }
        // The 21st reading halves 20 misses to 10, then counts: 11 misses.
        null.observe(Reading::NoEcho);
        assert!((null.likelihood(Reading::NoEcho) - 11.5 / (11.0 + 8.5)).abs() < 1e-6);
        // A new mix takes over: 40 echoes in one slice leave the misses a
        // small share.
        for _ in 0..40 {
            null.observe(echo(2000));
        }
        assert!(null.likelihood(Reading::NoEcho) < 0.1);
    }

    /// A bad window or memory is refused with its reason; the smallest
    /// memory accepted still scores every reading finitely.
    #[test]
    fn bad_settings_are_refused() {
        for (a, b) in [(5500.0, 408.0), (408.0, 408.0), (f32::NAN, 5500.0), (408.0, f32::INFINITY)] {
            assert_eq!(NullModel::new(a, b, 400.0), Err(NullError::Window), "{a}..{b}");
        }
        for m in [f32::NAN, -1.0, 16.0, f32::INFINITY] {
            assert_eq!(NullModel::new(408.0, 5500.0, m), Err(NullError::Memory), "memory {m}");
        }
        let mut null = NullModel::new(408.0, 5500.0, 17.0).unwrap();
        for _ in 0..100 {
            for r in [Reading::NoEcho, echo(1000), echo(0), echo(u32::MAX)] {
                assert!(null.log_likelihood(r).is_finite());
            }
        }
    }
}
