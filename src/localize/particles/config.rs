//! Monte Carlo localization's settings.

use super::super::beam::BeamModel;
use super::MotionNoise;

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
