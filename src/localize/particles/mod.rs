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
//!
//! | module | what it does |
//! |---|---|
//! | this one | [`ParticleSet`]: the poses and weights, seeding over free space or around a pose, the odometry's motion with noise |
//! | [`config`] | [`McConfig`]: the beam model, tempering, KLD sampling and injection settings |
//! | [`weigh`] | scoring the cycle's readings at every particle ([`ParticleSet::weigh`], [`Weighed`]) |
//! | [`cluster`] | the heaviest cluster ([`ParticleSet::cluster`], [`Cluster`]) |
//! | [`resample`] | low-variance, KLD-sized resampling in place with augmented MCL's injection ([`ParticleSet::resample`], [`kld_bound`]) |

pub mod cluster;
pub mod config;
pub mod resample;
pub mod weigh;

pub use cluster::Cluster;
pub use config::McConfig;
pub use resample::kld_bound;
pub use weigh::Weighed;

pub use super::measure::Sensed;

use super::expect::FieldLookup;
use super::rng::Rng;
use crate::f32math::{sin_cos, sqrt};
use crate::referencing::{wrap, Motion};

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
}
