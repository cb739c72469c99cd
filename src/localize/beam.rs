//! The sonar's measurement model for particles: the beam model's mixture
//! (*Probabilistic Robotics*, §6.3) on the expected reading the field gives
//! ([`super::expect`]).
//!
//! Where an echo is expected at range `r` (sure or not, [`Expected`]):
//!
//! - no echo at all: probability `p_miss` (a surface at a glancing angle, a
//!   mapped obstacle taken away);
//! - else an echo at `z` with density (per metre)
//!   `(1 − p_miss) · (z_hit · N(z; r, σ) + z_short · 1/(r − R_min)·[z < r] + z_rand · 1/(R_max − R_min))`,
//!   σ = `sigma_mm + sigma_rel · r` (times `unsure_sigma_scale` for an unsure
//!   prediction): a hit near `r`, a person or a box in front of it, or any
//!   stray echo.
//!
//! Where nothing is expected: no echo with probability `1 − p_unpredicted`,
//! else an echo spread evenly over the window. Where the field has no node
//! (the transducer cannot be there): `off_field`, for either reading.
//!
//! All particles of a cycle see the same readings, so the masses (no echo)
//! and the densities (an echo) are never compared with each other: only a
//! reading's value at one particle with its value at another.

use crate::map::field::Expected;
use crate::referencing::Reading;

/// The model's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BeamModel {
    /// The window the sonar hears in, mm: R_min ...
    pub r_min_mm: f32,
    /// ... and R_max. An echo beyond R_max counts as none.
    pub r_max_mm: f32,
    /// A sure hit's σ: this, mm, ...
    pub sigma_mm: f32,
    /// ... plus this fraction of the range.
    pub sigma_rel: f32,
    /// An unsure prediction's σ is this many times a sure one's.
    pub unsure_sigma_scale: f32,
    /// A sure prediction's mixture of an echo: hit, short, random (summing to 1).
    pub sure_mix: [f32; 3],
    /// An unsure prediction's.
    pub unsure_mix: [f32; 3],
    /// No echo where a sure echo is expected.
    pub p_miss_sure: f32,
    /// No echo where an unsure echo is expected.
    pub p_miss_unsure: f32,
    /// An echo where nothing is expected.
    pub p_unpredicted: f32,
    /// A reading's value where the transducer is off the field.
    pub off_field: f32,
}

impl BeamModel {
    /// Settings for the Polaroid window (R_min 408 mm, R_max 5 500 mm),
    /// measured on simulated runs at the true pose (`docs/localization.md`):
    /// σ 40 mm + 2 % (the range codes' 1 %, the interpolation, the echo's
    /// spread over a wide beam), twice that for an unsure prediction.
    pub const DEFAULT: Self = Self {
        r_min_mm: 408.0,
        r_max_mm: 5500.0,
        sigma_mm: 40.0,
        sigma_rel: 0.02,
        unsure_sigma_scale: 2.0,
        sure_mix: [0.7, 0.2, 0.1],
        unsure_mix: [0.45, 0.35, 0.2],
        p_miss_sure: 0.1,
        p_miss_unsure: 0.4,
        p_unpredicted: 0.25,
        off_field: 0.01,
    };

    /// A hit's σ, m, about the expected range `range_mm` (sure or not).
    pub fn sigma_m(&self, range_mm: f32, sure: bool) -> f32 {
        let scale = if sure { 1.0 } else { self.unsure_sigma_scale };
        (self.sigma_mm + self.sigma_rel * range_mm) * scale * 1e-3
    }

    /// The reading's likelihood given what is expected (`None`: the
    /// transducer is off the field). 1 for an invalid reading: it says
    /// nothing.
    #[inline]
    pub fn likelihood(&self, reading: Reading, expected: Option<Expected>) -> f32 {
        self.likelihood_with(reading, expected, 0.0)
    }

    /// [`BeamModel::likelihood`] with a hit's variance grown by
    /// `extra_var_mm2` (mm²): the pose's own uncertainty, so that a spread
    /// particle set sees wide basins and a tight one a sharp model.
    #[inline]
    pub fn likelihood_with(&self, reading: Reading, expected: Option<Expected>, extra_var_mm2: f32) -> f32 {
        let z = match reading {
            Reading::Invalid => return 1.0,
            Reading::Echo { range_mm } if (range_mm as f32) <= self.r_max_mm => Some(range_mm as f32),
            _ => None,
        };
        let Some(expected) = expected else { return self.off_field };
        let span_m = (self.r_max_mm - self.r_min_mm) * 1e-3;
        let uniform = 1.0 / span_m;
        match (expected, z) {
            (Expected::Nothing, None) => 1.0 - self.p_unpredicted,
            (Expected::Nothing, Some(_)) => self.p_unpredicted * uniform,
            (Expected::Echo { sure, .. }, None) => {
                if sure {
                    self.p_miss_sure
                } else {
                    self.p_miss_unsure
                }
            }
            (Expected::Echo { range_mm: r, sure }, Some(z)) => {
                let (mix, miss, scale) = if sure {
                    (&self.sure_mix, self.p_miss_sure, 1.0)
                } else {
                    (&self.unsure_mix, self.p_miss_unsure, self.unsure_sigma_scale)
                };
                let own = (self.sigma_mm + self.sigma_rel * r) * scale;
                let sigma_m = crate::f32math::sqrt(own * own + extra_var_mm2) * 1e-3;
                let d = (z - r) * 1e-3 / sigma_m;
                let hit = crate::f32math::exp_fast(-0.5 * d * d) * (0.398_942_3 / sigma_m);
                let short = if z < r && r > self.r_min_mm { 1e3 / (r - self.r_min_mm) } else { 0.0 };
                (1.0 - miss) * (mix[0] * hit + mix[1] * short + mix[2] * uniform)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The echo density integrates to 1 − p_miss over the window, and the
    /// no-echo mass is p_miss: the mixture is a distribution over readings.
    #[test]
    fn the_mixture_is_a_distribution() {
        let m = BeamModel::DEFAULT;
        for expected in [
            // Hits more than a few σ inside the window (nearer its ends the
            // hit's tail outside it is lost, as the textbook's un-normalised
            // hit is).
            Expected::Echo { range_mm: 700.0, sure: true },
            Expected::Echo { range_mm: 2300.0, sure: true },
            Expected::Echo { range_mm: 2300.0, sure: false },
            Expected::Echo { range_mm: 4500.0, sure: false },
            Expected::Nothing,
        ] {
            let mut total = f64::from(m.likelihood(Reading::NoEcho, Some(expected)));
            // The density's integral over R_min..R_max by the midpoint rule, 0.1 mm steps.
            let mut z = m.r_min_mm as f64 + 0.05;
            while z < m.r_max_mm as f64 {
                total += f64::from(m.likelihood(Reading::Echo { range_mm: z as u32 }, Some(expected))) * 1e-4;
                z += 0.1;
            }
            // The hit's tails outside the window hold a little of its mass.
            assert!((total - 1.0).abs() < 0.01, "{expected:?}: {total}");
        }
    }

    #[test]
    fn a_hit_outweighs_a_miss_and_off_field_is_worst() {
        let m = BeamModel::DEFAULT;
        let e = Some(Expected::Echo { range_mm: 2000.0, sure: true });
        let hit = m.likelihood(Reading::Echo { range_mm: 2010 }, e);
        let far = m.likelihood(Reading::Echo { range_mm: 2600 }, e);
        let short = m.likelihood(Reading::Echo { range_mm: 1200 }, e);
        assert!(hit > 10.0 * far && short > far, "{hit} {far} {short}");
        assert!(m.likelihood(Reading::Echo { range_mm: 2010 }, None) < far);
        assert_eq!(m.likelihood(Reading::Invalid, e), 1.0);
        // An echo beyond R_max is no echo.
        assert_eq!(m.likelihood(Reading::Echo { range_mm: 6000 }, e), m.likelihood(Reading::NoEcho, e));
    }
}
