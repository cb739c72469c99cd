//! Monte Carlo localization's particle set, in fixed memory: `N` poses and
//! their weights (16 bytes a particle), held by the caller. Resampling
//! works in place: the weights' words hold the copy counts, then the KLD
//! bins' hash table.
//!
//! One ring cycle: the particles stand where the robot was at the cycle's
//! start; each reading is scored at every particle through the transducer's
//! pose in that frame ([`Sensed`]) by the beam model on the field
//! ([`ParticleSet::weigh`]); then the set is resampled
//! ([`ParticleSet::resample`]: low-variance, KLD-sized, with random particles
//! injected over free space when the short-term likelihood falls below the
//! long-term one: augmented MCL) and moved by the cycle's odometry with
//! noise ([`ParticleSet::motion`]).

use super::beam::BeamModel;
use super::expect::FieldLookup;
use super::rng::Rng;
use super::scan::Candidate;
use crate::f32math::{exp_fast, ln_fast, sin_cos, sqrt};
use crate::referencing::{wrap, Motion, Reading};

/// A reading as the particles take it: the transducer's pose in the frame
/// of the cycle's start (x m, y m, heading rad) and what it read.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sensed {
    /// The transducer's pose at its firing, in the robot's frame at the
    /// cycle's start.
    pub pose: [f32; 3],
    /// The reading.
    pub reading: Reading,
}

impl Sensed {
    /// How many of `sensed` are usable readings (not `Invalid`). A fold
    /// that saturates, where `count` would carry an overflow check.
    pub(crate) fn usable(sensed: &[Sensed]) -> usize {
        sensed.iter().filter(|r| r.reading != Reading::Invalid).fold(0usize, |n, _| n.saturating_add(1))
    }
}

/// The odometry's noise, for moving particles: variances per metre driven
/// and per radian turned, and a floor per cycle so that particles spread
/// even while the robot stands.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionNoise {
    /// Variance along the motion, m² per metre.
    pub along_per_m: f32,
    /// Variance across it, m² per metre.
    pub side_per_m: f32,
    /// Heading variance, rad² per radian turned.
    pub turn_per_rad: f32,
    /// Heading variance, rad² per metre driven.
    pub turn_per_m: f32,
    /// Position σ added each cycle, m.
    pub floor_m: f32,
    /// Heading σ added each cycle, rad.
    pub floor_rad: f32,
}

/// The settings of the particle set.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct McConfig {
    /// The measurement model.
    pub beam: BeamModel,
    /// Log-likelihoods are multiplied by this before they become weights
    /// (below 1: the readings of one cycle are not independent, and a
    /// field is an approximation; a set that believes them fully collapses
    /// on the first place that fits).
    pub temper: f32,
    /// Adaptive tempering: the exponent is lowered (not below `min_temper`)
    /// until the weights keep an effective sample size of this fraction of
    /// the set (0: always `temper`).
    pub ess_target: f32,
    /// The least exponent adaptive tempering goes to.
    pub min_temper: f32,
    /// The hit's σ grows with the set's spread (its heaviest cluster's
    /// position σ, from the localizer), up to this, m: a spread set sees
    /// wide basins, a converged one the sonar's own σ.
    pub spread_max_m: f32,
    /// The motion noise.
    pub motion: MotionNoise,
    /// KLD sampling: the fewest particles kept ...
    pub min_particles: u16,
    /// ... the bound ε on the K–L divergence ...
    pub kld_epsilon: f32,
    /// ... its confidence as the normal quantile z₁₋δ (2.326: δ = 0.01) ...
    pub kld_z: f32,
    /// ... over bins of this size, m ...
    pub bin_m: f32,
    /// ... and this many radians.
    pub bin_rad: f32,
    /// Augmented MCL: weight of a cycle in the long-term average likelihood ...
    pub alpha_slow: f32,
    /// ... and in the short-term one.
    pub alpha_fast: f32,
    /// The most of the set injected in one cycle.
    pub max_inject: f32,
    /// The least share of the set injected each cycle, whatever the
    /// averages say: the search keeps testing other places, so that a
    /// cluster must keep the weight against them to be handed off.
    pub explore: f32,
    /// Each injected particle is the one of this many random poses that
    /// the cycle's readings favour, drawn in proportion to its likelihood
    /// (1: plainly random).
    pub inject_tries: u8,
    /// Each injected pose takes the heading the readings favour most among
    /// this many (0: a random heading).
    pub scan_headings: u8,
}

impl McConfig {
    /// Settings for a Pioneer-class robot and ring (`docs/localization.md`).
    pub const DEFAULT: Self = Self {
        beam: BeamModel::DEFAULT,
        temper: 1.0,
        ess_target: 0.1,
        min_temper: 0.02,
        spread_max_m: 0.2,
        motion: MotionNoise {
            along_per_m: 4e-3,
            side_per_m: 1e-3,
            turn_per_rad: 1e-3,
            turn_per_m: 1e-3,
            floor_m: 0.01,
            floor_rad: 0.005,
        },
        min_particles: 100,
        kld_epsilon: 0.05,
        kld_z: 2.326,
        bin_m: 0.5,
        bin_rad: 10.0 * core::f32::consts::PI / 180.0,
        alpha_slow: 0.01,
        alpha_fast: 0.2,
        max_inject: 0.25,
        explore: 0.1,
        inject_tries: 1,
        scan_headings: 0,
    };
}

/// KLD sampling's bound (Fox 2003, eq. 11): particles needed so that, with
/// probability 1 − δ, the K–L divergence between the sample-based and the
/// true posterior stays below ε, when the samples fall into `k` bins:
/// `(k − 1)/(2ε) · (1 − 2/(9(k − 1)) + √(2/(9(k − 1))) · z₁₋δ)³`; 0 for `k ≤ 1`.
pub fn kld_bound(k: u32, epsilon: f32, z: f32) -> f32 {
    if k <= 1 {
        return 0.0;
    }
    let km1 = (k - 1) as f32;
    let a = 2.0 / (9.0 * km1);
    let b = 1.0 - a + sqrt(a) * z;
    km1 / (2.0 * epsilon) * b * b * b
}

/// The heaviest cluster of the weighted set.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Cluster {
    /// Its weighted mean (x m, y m, φ rad).
    pub mean: [f32; 3],
    /// Its weighted covariance.
    pub covariance: [[f32; 3]; 3],
    /// The weight within the cluster's radius and angle of its mean (0–1).
    pub weight: f32,
    /// The whole set's covariance about the mean (heading differences
    /// wrapped): how sure the set is.
    pub spread: [[f32; 3]; 3],
}

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

/// Why the set could not do what was asked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParticleError {
    /// The set has no room (`N = 0`).
    NoCapacity,
    /// The map's field has no free node to draw from.
    NoFreeSpace,
    /// A non-finite pose, σ or odometry.
    NotFinite,
}

/// `N` particles.
#[derive(Clone, Debug)]
pub struct ParticleSet<const N: usize> {
    pose: [[f32; 3]; N],
    weight: [f32; N],
    n: usize,
    /// The particles from this index on were injected at the last
    /// resampling, with this prior factor (Mixture MCL); the others have 1.
    injected_from: usize,
    injected_prior: f32,
    rng: Rng,
    /// Augmented MCL's long- and short-term average likelihoods (0: unset).
    w_slow: f32,
    w_fast: f32,
    /// The fraction injected at the last resampling.
    injected: f32,
    /// The last weighing's exponent.
    alpha: f32,
    /// The pose spread the measurement model widens by, m.
    spread_m: f32,
}

impl<const N: usize> ParticleSet<N> {
    /// An empty set drawing from `seed`.
    pub fn new(seed: u64) -> Self {
        // The generator first: with its branch before the arrays, they are
        // zeroed where the set is kept (after them, the 16 KiB of a
        // 1 024-particle set were zeroed in a temporary and copied: 16 KiB
        // more of the caller's stack).
        let rng = Rng::new(seed);
        Self {
            pose: [[0.0; 3]; N],
            weight: [0.0; N],
            n: 0,
            injected_from: N,
            injected_prior: 1.0,
            rng,
            w_slow: 0.0,
            w_fast: 0.0,
            injected: 0.0,
            alpha: 0.0,
            spread_m: f32::INFINITY,
        }
    }

    /// Particles held.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The particles (x m, y m, φ rad).
    pub fn poses(&self) -> &[[f32; 3]] {
        self.pose.get(..self.n).unwrap_or(&[])
    }

    /// Their weights (summing to 1 after weighing or resampling).
    pub fn weights(&self) -> &[f32] {
        self.weight.get(..self.n).unwrap_or(&[])
    }

    /// The fraction of the set injected at the last resampling.
    pub fn injected(&self) -> f32 {
        self.injected
    }

    /// Augmented MCL's long- and short-term average likelihoods.
    pub fn averages(&self) -> (f32, f32) {
        (self.w_slow, self.w_fast)
    }

    /// The generator (the localizer draws from it too, so one seed fixes a run).
    pub fn rng(&mut self) -> &mut Rng {
        &mut self.rng
    }

    /// A pose drawn evenly over the field's free space: a free node, a
    /// point evenly within its cell, any heading.
    pub fn free_pose(rng: &mut Rng, lookup: &FieldLookup<'_, '_>) -> Option<[f32; 3]> {
        let f = lookup.field();
        let nodes = f.nodes();
        if f.free_nodes() == 0 {
            return None;
        }
        let mut n = rng.below(nodes);
        // Rejection until a free node, bounded; then the next free one.
        let mut tries = 0u32;
        while !f.is_free(n) {
            tries = tries.saturating_add(1);
            n = if tries < 64 { rng.below(nodes) } else { (n + 1).checked_rem(nodes).unwrap_or(0) };
            if tries > nodes.saturating_add(64) {
                return None;
            }
        }
        let (x, y) = f.position_mm(n)?;
        let h = lookup.node_mm();
        let jx = (rng.uniform() - 0.5) * h;
        let jy = (rng.uniform() - 0.5) * h;
        let th = (rng.uniform() * 2.0 - 1.0) * core::f32::consts::PI;
        Some([(x as f32 + jx) * 1e-3, (y as f32 + jy) * 1e-3, th])
    }

    /// Replaces the set by `count` particles (at most `N`) spread evenly
    /// over free space.
    pub fn seed_global(&mut self, lookup: &FieldLookup<'_, '_>, count: usize) -> Result<(), ParticleError> {
        let count = count.min(N);
        if count == 0 {
            return Err(ParticleError::NoCapacity);
        }
        if lookup.field().free_nodes() == 0 {
            return Err(ParticleError::NoFreeSpace);
        }
        for i in 0..count {
            let p = Self::free_pose(&mut self.rng, lookup).ok_or(ParticleError::NoFreeSpace)?;
            if let Some(slot) = self.pose.get_mut(i) {
                *slot = p;
            }
        }
        self.set_uniform(count);
        self.reset_averages();
        Ok(())
    }

    /// Replaces the set by `count` particles (at most `N`): a share
    /// `global` spread over free space, the rest drawn around `mean` with
    /// standard deviations `sigma` (m, m, rad; independent).
    pub fn seed_around(
        &mut self,
        lookup: &FieldLookup<'_, '_>,
        count: usize,
        mean: [f32; 3],
        sigma: [f32; 3],
        global: f32,
    ) -> Result<(), ParticleError> {
        let count = count.min(N);
        if count == 0 {
            return Err(ParticleError::NoCapacity);
        }
        if !mean.iter().chain(sigma.iter()).all(|v| v.is_finite()) || sigma.iter().any(|&s| s < 0.0) {
            return Err(ParticleError::NotFinite);
        }
        let n_global = (global.clamp(0.0, 1.0) * count as f32) as usize;
        if n_global > 0 && lookup.field().free_nodes() == 0 {
            return Err(ParticleError::NoFreeSpace);
        }
        for i in 0..count {
            let p = if i < n_global {
                Self::free_pose(&mut self.rng, lookup).ok_or(ParticleError::NoFreeSpace)?
            } else {
                let r = &mut self.rng;
                [
                    mean[0] + sigma[0] * r.normal(),
                    mean[1] + sigma[1] * r.normal(),
                    wrap(mean[2] + sigma[2] * r.normal()),
                ]
            };
            if let Some(slot) = self.pose.get_mut(i) {
                *slot = p;
            }
        }
        self.set_uniform(count);
        self.reset_averages();
        Ok(())
    }

    /// Replaces the set by `poses` (at most `N`) with `weights` (normalised
    /// here; all non-negative, finite, and not all 0), for a caller with a
    /// belief of its own (a pose from another localizer, a test).
    pub fn load(&mut self, poses: &[[f32; 3]], weights: &[f32]) -> Result<(), ParticleError> {
        let n = poses.len().min(weights.len()).min(N);
        if n == 0 {
            return Err(ParticleError::NoCapacity);
        }
        let ok = |v: &f32| v.is_finite() && *v >= 0.0;
        let sum: f32 = weights.iter().take(n).sum();
        if !poses.iter().take(n).flatten().all(|v| v.is_finite()) || !weights.iter().take(n).all(ok) || sum <= 0.0 {
            return Err(ParticleError::NotFinite);
        }
        self.set_uniform(n);
        for ((d, w), (p, &v)) in self.pose.iter_mut().zip(self.weight.iter_mut()).zip(poses.iter().zip(weights)).take(n)
        {
            *d = *p;
            *w = v / sum;
        }
        Ok(())
    }

    fn set_uniform(&mut self, count: usize) {
        self.n = count.min(N);
        let w = 1.0 / self.n.max(1) as f32;
        for v in self.weight.iter_mut().take(self.n) {
            *v = w;
        }
        // Every particle's prior factor is 1.
        self.injected_from = N;
        self.injected_prior = 1.0;
    }

    fn reset_averages(&mut self) {
        self.w_slow = 0.0;
        self.w_fast = 0.0;
        self.injected = 0.0;
    }

    /// Moves every particle by the odometry `u` (in its own frame) with
    /// noise drawn from `noise`.
    pub fn motion(&mut self, u: &Motion, noise: &MotionNoise) -> Result<(), ParticleError> {
        if !u.is_finite() {
            return Err(ParticleError::NotFinite);
        }
        let d = sqrt(u.dx * u.dx + u.dy * u.dy);
        let turn = u.dphi.abs();
        let s_along = sqrt(noise.along_per_m * d) + noise.floor_m;
        let s_side = sqrt(noise.side_per_m * d) + noise.floor_m;
        let s_turn = sqrt(noise.turn_per_rad * turn + noise.turn_per_m * d) + noise.floor_rad;
        // Along and across the motion's direction (the robot's x when it stands).
        let (ux, uy) = if d > 1e-6 { (u.dx / d, u.dy / d) } else { (1.0, 0.0) };
        for p in self.pose.iter_mut().take(self.n) {
            let r = &mut self.rng;
            let (a, b, t) = (s_along * r.normal(), s_side * r.normal(), s_turn * r.normal());
            let dx = u.dx + a * ux - b * uy;
            let dy = u.dy + a * uy + b * ux;
            let (s, c) = sin_cos(p[2]);
            p[0] += c * dx - s * dy;
            p[1] += s * dx + c * dy;
            p[2] = wrap(p[2] + u.dphi + t);
        }
        Ok(())
    }

    /// The sum of the log-likelihoods of `sensed` at particle pose `p`.
    // Out of line: five callers (weighing, injection, the history, the fit
    // monitor) would each inline a copy (flash: issue #27's budget).
    #[inline(never)]
    pub(crate) fn log_likelihood(
        p: &[f32; 3],
        sensed: &[Sensed],
        lookup: &FieldLookup<'_, '_>,
        beam: &BeamModel,
        extra_var_mm2: f32,
    ) -> f32 {
        let (s, c) = sin_cos(p[2]);
        let mut ll = 0.0;
        if !lookup.is_free(p[0] * 1e3, p[1] * 1e3) {
            ll += ln_fast(beam.off_field);
        }
        for r in sensed {
            if r.reading == Reading::Invalid {
                continue;
            }
            let tx = p[0] + c * r.pose[0] - s * r.pose[1];
            let ty = p[1] + s * r.pose[0] + c * r.pose[1];
            let e = lookup.expected(tx * 1e3, ty * 1e3, p[2] + r.pose[2]);
            ll += ln_fast(beam.likelihood_with(r.reading, e, extra_var_mm2));
        }
        ll
    }

    /// Weighs every particle by the readings `sensed` (transducer poses in
    /// the particles' frame) and normalises the weights.
    pub fn weigh(&mut self, sensed: &[Sensed], lookup: &FieldLookup<'_, '_>, cfg: &McConfig) -> Weighed {
        let extra = self.extra_var(cfg);
        let k = Sensed::usable(sensed);
        if self.n == 0 {
            return Weighed::default();
        }
        let mut best = f32::NEG_INFINITY;
        for (p, w) in self.pose.iter().zip(self.weight.iter_mut()).take(self.n) {
            let ll = Self::log_likelihood(p, sensed, lookup, &cfg.beam, extra);
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
    fn extra_var(&self, cfg: &McConfig) -> f32 {
        let s = (0.5 * self.spread_m).min(cfg.spread_max_m) * 1e3;
        s * s
    }

    /// The exponent the last weighing took the likelihoods to.
    pub fn alpha(&self) -> f32 {
        self.alpha
    }

    /// The heaviest cluster: from the heaviest particle, the weighted mean of
    /// the particles within `radius_m` and `angle_rad` of it, three times
    /// over (a mean shift), and the weight and covariance of those
    /// particles; also the whole set's spread about that mean.
    pub fn cluster(&self, radius_m: f32, angle_rad: f32) -> Option<Cluster> {
        let poses = self.poses();
        let weights = self.weights();
        let r2 = radius_m * radius_m;
        let near = |p: &[f32; 3], c: &[f32; 3]| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            dx * dx + dy * dy <= r2 && wrap(p[2] - c[2]).abs() <= angle_rad
        };
        // A mean shift from `seed`: the cluster's mean and weight.
        let shift = |seed: [f32; 3]| {
            let (mut centre, mut weight) = (seed, 0.0f32);
            for _ in 0..3 {
                let (mut sw, mut sx, mut sy, mut sa) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
                for (p, &w) in poses.iter().zip(weights) {
                    if near(p, &centre) {
                        sw += w;
                        sx += w * (p[0] - centre[0]);
                        sy += w * (p[1] - centre[1]);
                        sa += w * wrap(p[2] - centre[2]);
                    }
                }
                if sw <= 0.0 {
                    break;
                }
                centre = [centre[0] + sx / sw, centre[1] + sy / sw, wrap(centre[2] + sa / sw)];
                weight = sw;
            }
            (centre, weight)
        };
        // Seeds at the weight's quantiles (the particles where the running
        // sum of the weights passes (j + ½)/SEEDS): a cluster holding a share
        // w of the weight holds about w·SEEDS of them, so the heaviest one is
        // found whatever single particle weighs most. Seeds inside a cluster
        // already found are skipped.
        const SEEDS: usize = 16;
        let mut found: heapless::Vec<([f32; 3], f32), SEEDS> = heapless::Vec::new();
        let (mut cum, mut j) = (0.0f32, 0usize);
        for (p, &w) in poses.iter().zip(weights) {
            cum += w;
            while j < SEEDS && cum >= (j as f32 + 0.5) / SEEDS as f32 {
                j += 1;
                if found.iter().any(|(c, _)| near(p, c)) {
                    continue;
                }
                let _ = found.push(shift(*p));
            }
        }
        if found.is_empty() {
            let _ = found.push(shift(*poses.first()?));
        }
        let (mut centre, mut weight) = (poses.first().copied()?, f32::NEG_INFINITY);
        for &(c, w) in &found {
            if w > weight {
                (centre, weight) = (c, w);
            }
        }
        let mut covariance = [[0.0f32; 3]; 3];
        let mut spread = [[0.0f32; 3]; 3];
        let mut sw = 0.0;
        for (p, &w) in poses.iter().zip(weights) {
            let d = [p[0] - centre[0], p[1] - centre[1], wrap(p[2] - centre[2])];
            let inside = near(p, &centre);
            if inside {
                sw += w;
            }
            for i in 0..3 {
                for j in 0..3 {
                    let v = w * d[i] * d[j];
                    spread[i][j] += v;
                    if inside {
                        covariance[i][j] += v;
                    }
                }
            }
        }
        if sw > 0.0 {
            for row in covariance.iter_mut() {
                for v in row.iter_mut() {
                    *v /= sw;
                }
            }
            weight = sw;
        }
        Some(Cluster { mean: centre, covariance, weight, spread })
    }

    /// Resamples the weighted set: low-variance resampling to the capacity,
    /// then KLD sampling's size from the bins the new set fills (at least
    /// `min_particles`), then augmented MCL's injection of poses drawn over
    /// free space (`1 − w_fast / w_slow`, at least `explore` and at most
    /// `max_inject` of the set), each drawn among `inject_tries` random poses
    /// in proportion to their likelihood under `sensed`. Weights become
    /// uniform.
    pub fn resample(
        &mut self,
        sensed: &[Sensed],
        lookup: &FieldLookup<'_, '_>,
        cfg: &McConfig,
        inject_prior: f32,
        candidates: &[Candidate],
    ) {
        let n = self.n;
        if n == 0 || N == 0 {
            return;
        }
        // 1. Copies of each particle: a comb of N teeth, one random offset.
        let step = 1.0 / N as f32;
        let mut u = self.rng.uniform() * step;
        let mut cum = 0.0f32;
        let mut teeth = 0usize;
        // Each weight, once added to the running sum, is replaced by the
        // particle's number of copies.
        for (i, c) in self.weight.iter_mut().take(n).enumerate() {
            cum += *c;
            // The last particle takes the teeth rounding leaves.
            let end = if i + 1 == n { f32::INFINITY } else { cum };
            let mut copies = 0u32;
            while u < end && teeth < N {
                copies += 1;
                teeth += 1;
                u += step;
            }
            *c = copies as f32;
        }
        // 2. In place: each particle keeps its slot for its first copy; each
        //    extra copy goes to a slot nobody keeps (a particle with no
        //    copies), then past the old set. The copies add up to N, so the
        //    N slots end up full.
        let mut free = 0usize;
        let mut next = n;
        for i in 0..n {
            let copies = self.weight.get(i).map_or(0, |&c| c as u32);
            let src = self.pose.get(i).copied().unwrap_or_default();
            for _ in 1..copies {
                while free < n && self.weight.get(free).is_some_and(|&c| c != 0.0) {
                    free += 1;
                }
                let slot = if free < n {
                    // Claimed: it holds one copy now, and is nobody's source.
                    if let Some(c) = self.weight.get_mut(free) {
                        *c = 1.0;
                    }
                    free
                } else {
                    let s = next;
                    next = next.saturating_add(1);
                    s
                };
                if let Some(p) = self.pose.get_mut(slot) {
                    *p = src;
                }
            }
        }
        let full = N;
        // 3. KLD: bins the new set fills (counted up to half the capacity,
        //    where the bound passes any capacity worth having), hashed into
        //    the weights' words (the weights are spent).
        let bins = self.count_bins(full, cfg);
        let want = libm::ceilf(kld_bound(bins, cfg.kld_epsilon, cfg.kld_z)) as usize;
        let m = want.max(usize::from(cfg.min_particles)).clamp(1, full);
        // 4. Keep m of them, evenly at random (a partial Fisher–Yates shuffle).
        if m < full {
            for t in 0..m {
                let j = t + self.rng.below((full - t) as u32) as usize;
                if j != t {
                    self.pose.swap(t, j.min(N - 1));
                }
            }
        }
        // 5. Augmented MCL's injection.
        let frac = if self.w_slow > 0.0 { (1.0 - self.w_fast / self.w_slow).max(0.0) } else { 0.0 };
        let frac = frac.min(cfg.max_inject);
        let inject = ((frac.max(cfg.explore) * m as f32) as usize).min(m / 2);
        self.injected = inject as f32 / m as f32;
        // The scan's candidates first (jittered within their node and
        // heading bin), then draws over free space.
        let wanted = candidates.iter().fold(0usize, |n, c| n.saturating_add(usize::from(c.copies.max(1))));
        let inject = inject.max(wanted.min(m / 2));
        self.injected = inject as f32 / m as f32;
        // (`inject ≤ m / 2`: saturating only shows it to the compiler.)
        let first_injected = m.saturating_sub(inject);
        let h = lookup.node_mm() * 1e-3;
        let bin = core::f32::consts::TAU / lookup.field().dirs().max(1) as f32;
        // Candidates in order, each as many times as it has copies.
        let mut copies = candidates.iter().flat_map(|c| core::iter::repeat_n(c, usize::from(c.copies.max(1))));
        for t in first_injected..m {
            let p = match copies.next() {
                Some(c) if c.copies > 1 => {
                    // A verified candidate: copies spread as a small cloud.
                    let r = &mut self.rng;
                    let (a, b, d) = (r.normal(), r.normal(), r.normal());
                    Some([c.pose[0] + 0.05 * a, c.pose[1] + 0.05 * b, wrap(c.pose[2] + 0.5 * bin * d)])
                }
                Some(c) => {
                    let r = &mut self.rng;
                    let (jx, jy, jt) = (r.uniform() - 0.5, r.uniform() - 0.5, r.uniform() - 0.5);
                    Some([c.pose[0] + jx * h, c.pose[1] + jy * h, wrap(c.pose[2] + jt * bin)])
                }
                None => self.inject_one(sensed, lookup, cfg),
            };
            if let (Some(p), Some(slot)) = (p, self.pose.get_mut(t)) {
                *slot = p;
            }
        }
        self.set_uniform(m);
        // Injected poses enter with the belief's mass outside its heaviest
        // cluster as their prior (Mixture MCL weighs its draws from the
        // readings by the belief at them): they take over from a cluster
        // only where the readings say so, not by sheer number.
        self.injected_from = first_injected;
        self.injected_prior = inject_prior.clamp(1e-3, 1.0);
    }

    /// One pose for injection: the likeliest-in-proportion of
    /// `inject_tries` drawn over free space.
    fn inject_one(&mut self, sensed: &[Sensed], lookup: &FieldLookup<'_, '_>, cfg: &McConfig) -> Option<[f32; 3]> {
        let tries = cfg.inject_tries.max(1);
        let first = self.candidate(sensed, lookup, cfg)?;
        if tries == 1 {
            return Some(first);
        }
        // A running weighted choice (reservoir of one), with weights relative
        // to the first candidate's.
        let extra = self.extra_var(cfg);
        let base = Self::log_likelihood(&first, sensed, lookup, &cfg.beam, extra);
        let (mut pick, mut total) = (first, 1.0f32);
        for _ in 1..tries {
            let p = self.candidate(sensed, lookup, cfg)?;
            let w =
                exp_fast(cfg.temper * (Self::log_likelihood(&p, sensed, lookup, &cfg.beam, extra) - base)).min(1e30);
            total += w;
            if self.rng.uniform() * total < w {
                pick = p;
            }
        }
        Some(pick)
    }

    /// A pose for injection: a free position, and the heading the cycle's
    /// readings favour there among `scan_headings` evenly spaced (at a
    /// random offset), or any heading when that is 0 or there are no
    /// readings.
    fn candidate(&mut self, sensed: &[Sensed], lookup: &FieldLookup<'_, '_>, cfg: &McConfig) -> Option<[f32; 3]> {
        let mut p = Self::free_pose(&mut self.rng, lookup)?;
        let h = u32::from(cfg.scan_headings);
        if h == 0 || sensed.is_empty() {
            return Some(p);
        }
        let step = core::f32::consts::TAU / h as f32;
        let off = self.rng.uniform() * step - core::f32::consts::PI;
        let mut best = (f32::NEG_INFINITY, p[2]);
        let extra = self.extra_var(cfg);
        for b in 0..h {
            let th = off + b as f32 * step;
            let ll = Self::log_likelihood(&[p[0], p[1], th], sensed, lookup, &cfg.beam, extra);
            if ll > best.0 {
                best = (ll, th);
            }
        }
        p[2] = wrap(best.1);
        Some(p)
    }

    /// Distinct KLD bins among the first `count` particles, counted in an
    /// open-addressing table in the weights' words (up to half of them).
    fn count_bins(&mut self, count: usize, cfg: &McConfig) -> u32 {
        let cap = N;
        for s in self.weight.iter_mut() {
            *s = f32::from_bits(0);
        }
        let (inv_xy, inv_t) = (1.0 / cfg.bin_m, 1.0 / cfg.bin_rad);
        let mut bins = 0u32;
        for p in self.pose.iter().take(count) {
            let bx = libm::floorf(p[0] * inv_xy) as i32 as u32;
            let by = libm::floorf(p[1] * inv_xy) as i32 as u32;
            let bt = libm::floorf((p[2] + core::f32::consts::PI) * inv_t) as i32 as u32;
            // Bit 30 clear: the word is never a NaN's or an infinity's bit
            // pattern, so it passes through the f32 slot unchanged on every
            // target; bit 0 set: never the empty slot's 0.
            let key = ((bx.wrapping_mul(0x9E37_79B1) ^ by.wrapping_mul(0x85EB_CA77) ^ bt.wrapping_mul(0xC2B2_AE3D))
                & 0xBFFF_FFFF)
                | 1;
            let mut h = (key.wrapping_mul(0x2545_F491) >> 7) as usize % cap;
            loop {
                match self.weight.get(h).map(|w| w.to_bits()) {
                    Some(0) => {
                        if let Some(s) = self.weight.get_mut(h) {
                            *s = f32::from_bits(key);
                        }
                        bins += 1;
                        break;
                    }
                    Some(k) if k == key => break,
                    Some(_) => h = (h + 1) % cap,
                    None => break,
                }
            }
            if bins as usize >= cap / 2 {
                break;
            }
        }
        bins
    }
}
