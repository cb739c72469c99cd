//! Weighing: each reading of the cycle scored at every particle by the beam
//! model on the field, tempered so that one cycle cannot empty the set.

use super::super::expect::FieldLookup;
use super::super::measure::Measure;
use super::{McConfig, ParticleSet, Sensed};
use crate::f32math::exp_fast;

/// What weighing did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Weighed {
    /// Readings scored (all but invalid ones).
    pub readings: u16,
    /// The set's mean likelihood per reading (the geometric mean over the
    /// readings at each particle, averaged over particles): what augmented
    /// MCL's averages follow.
    pub mean_likelihood: f32,
    /// The effective sample size 1/Σw² after weighing.
    pub ess: f32,
    /// The largest log-likelihood of the cycle's readings at a particle.
    pub best_ll: f32,
    /// The exponent the likelihoods were taken to (adaptive tempering).
    pub alpha: f32,
}

impl<const N: usize> ParticleSet<N> {
    /// Weighs every particle by the readings `sensed` (transducer poses in
    /// the particles' frame) and normalises the weights.
    pub fn weigh(&mut self, sensed: &[Sensed], lookup: &FieldLookup<'_, '_>, cfg: &McConfig) -> Weighed {
        let m = Measure::new(lookup, &cfg.beam, self.extra_var(cfg));
        let k = Sensed::usable(sensed);
        if self.n == 0 {
            return Weighed::default();
        }
        let mut best = f32::NEG_INFINITY;
        for (p, w) in self.pose.iter().zip(self.weight.iter_mut()).take(self.n) {
            let ll = m.log_likelihood(p, sensed);
            *w = ll;
            if ll > best {
                best = ll;
            }
        }
        let per = 1.0 / k.max(1) as f32;
        let mut mean = 0.0f32;
        for &ll in self.weight.iter().take(self.n) {
            mean += exp_fast(ll * per);
        }
        mean /= self.n as f32;
        let alpha = self.tempering(best, cfg);
        self.alpha = alpha;
        let mut sum = 0.0f32;
        for (i, w) in self.weight.iter_mut().enumerate().take(self.n) {
            let prior = if i >= self.injected_from { self.injected_prior } else { 1.0 };
            let v = prior * exp_fast(alpha * (*w - best));
            *w = v;
            sum += v;
        }
        let mut sq = 0.0;
        if sum > 0.0 && sum.is_finite() {
            let inv = 1.0 / sum;
            for w in self.weight.iter_mut().take(self.n) {
                *w *= inv;
                sq += *w * *w;
            }
        } else {
            self.set_uniform(self.n);
            sq = 1.0 / self.n as f32;
        }
        if k > 0 {
            if self.w_slow == 0.0 {
                self.w_slow = mean;
                self.w_fast = mean;
            } else {
                self.w_slow += cfg.alpha_slow * (mean - self.w_slow);
                self.w_fast += cfg.alpha_fast * (mean - self.w_fast);
            }
        }
        Weighed {
            readings: k as u16,
            mean_likelihood: mean,
            ess: if sq > 0.0 { 1.0 / sq } else { 0.0 },
            best_ll: best,
            alpha,
        }
    }

    /// The exponent the log-likelihoods (now in the weights, the largest
    /// `best`) are taken to: `temper`, or less, the largest that leaves an
    /// effective sample size of `ess_target` of the set (bisection on the
    /// ESS, which falls as the exponent grows). A set far from the pose
    /// then takes a cycle's readings in part rather than collapsing on the
    /// first place that fits them (adaptive tempering, as in sequential
    /// Monte Carlo samplers).
    fn tempering(&self, best: f32, cfg: &McConfig) -> f32 {
        let ess = |a: f32| {
            let (mut s1, mut s2) = (0.0f32, 0.0f32);
            for (i, &ll) in self.weight.iter().enumerate().take(self.n) {
                let prior = if i >= self.injected_from { self.injected_prior } else { 1.0 };
                let v = prior * exp_fast(a * (ll - best));
                s1 += v;
                s2 += v * v;
            }
            if s2 > 0.0 {
                s1 * s1 / s2
            } else {
                0.0
            }
        };
        let target = cfg.ess_target * self.n as f32;
        if cfg.ess_target <= 0.0 || ess(cfg.temper) >= target {
            return cfg.temper;
        }
        let (mut lo, mut hi) = (0.0f32, cfg.temper);
        for _ in 0..12 {
            let mid = 0.5 * (lo + hi);
            if ess(mid) >= target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo.max(cfg.min_temper)
    }

    /// The set's position spread (set by the localizer from its heaviest
    /// cluster), m, capped at `spread_max_m`.
    pub fn set_spread(&mut self, spread_m: f32) {
        self.spread_m = if spread_m.is_finite() { spread_m.max(0.0) } else { f32::INFINITY };
    }

    /// The hit variance the set's spread adds, mm²: half the spread (so
    /// that a converging set keeps tightening), at most `spread_max_m`.
    pub(super) fn extra_var(&self, cfg: &McConfig) -> f32 {
        let s = (0.5 * self.spread_m).min(cfg.spread_max_m) * 1e3;
        s * s
    }

    /// The exponent the last weighing took the likelihoods to.
    pub fn alpha(&self) -> f32 {
        self.alpha
    }
}
