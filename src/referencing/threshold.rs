//! The paper's threshold method (§5.5), the baseline: "setting a threshold
//! on the difference between R_obs and R_calc and immediately changing the
//! dead reckoning values when the difference exceeds a threshold".
//!
//! Our reading: on a reading that matches a credible beacon (κ ≥ τ and
//! |R_obs − R_calc| within an association window), when the difference
//! exceeds the threshold the pose moves at once by the smallest step (in a
//! metric that weighs heading by a lever arm) that makes the linearised range
//! equal the observed one: Δ = W Hᵀ (z − h) / (H W Hᵀ). No covariance, no
//! memory of earlier readings: that is what makes it crude.
//!
//! ```
//! use echoloc::referencing::{MountM, Target, Threshold, ThresholdConfig};
//! let mut t = Threshold::new([1.0, 0.0, 0.0], ThresholdConfig::DEFAULT);
//! let wall = Target::Plane { point: [3.0, 0.0], normal: [-1.0, 0.0] };
//! // Reads 2.1 m: the robot is 0.1 m short of where it thinks.
//! assert!(t.update(2.1, 1.0, MountM { x: 0.0, y: 0.0 }, &wall));
//! assert!((t.state()[0] - 0.9).abs() < 1e-5);
//! ```

use super::model::{compose, range_model, wrap, Motion, MountM, Target};

/// Threshold method settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThresholdConfig {
    /// Differences up to this are left alone, m.
    pub threshold_m: f32,
    /// Differences beyond this are another object, not a pose error, m.
    pub window_m: f32,
    /// Readings with κ below this are not used.
    pub min_kappa: f32,
    /// Heading is weighted as a lever of this length, m (a heading change
    /// of 1 rad costs as much as moving this far).
    pub lever_m: f32,
}

impl ThresholdConfig {
    /// 50 mm threshold (above the ranging tolerance at a few metres), a
    /// 300 mm association window, κ ≥ 0.5, a 1 m lever.
    pub const DEFAULT: Self = Self { threshold_m: 0.05, window_m: 0.3, min_kappa: 0.5, lever_m: 1.0 };
}

/// Dead reckoning corrected by the threshold method.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Threshold {
    x: [f32; 3],
    cfg: ThresholdConfig,
    corrections: u32,
}

impl Threshold {
    /// Starts at pose `x` (m, m, rad).
    pub fn new(x: [f32; 3], cfg: ThresholdConfig) -> Self {
        Self { x: [x[0], x[1], wrap(x[2])], cfg, corrections: 0 }
    }

    /// The pose (x m, y m, φ rad).
    pub fn state(&self) -> [f32; 3] {
        self.x
    }

    /// How many readings moved the pose.
    pub fn corrections(&self) -> u32 {
        self.corrections
    }

    /// Dead reckoning: `x ← x ⊕ u` (a non-finite motion is ignored).
    pub fn predict(&mut self, u: &Motion) {
        if u.is_finite() {
            self.x = compose(&self.x, u).0;
        }
    }

    /// One reading `z` (m) of `target` with credence `kappa`; returns whether
    /// it moved the pose.
    pub fn update(&mut self, z: f32, kappa: f32, mount: MountM, target: &Target) -> bool {
        if !(z.is_finite() && kappa >= self.cfg.min_kappa) {
            return false;
        }
        let Some((h, j)) = range_model(&self.x, mount, target) else { return false };
        let nu = z - h;
        let a = libm::fabsf(nu);
        if !(a > self.cfg.threshold_m && a <= self.cfg.window_m) {
            return false;
        }
        let l2 = self.cfg.lever_m * self.cfg.lever_m;
        let w = [1.0, 1.0, 1.0 / l2];
        let den = j[0] * j[0] * w[0] + j[1] * j[1] * w[1] + j[2] * j[2] * w[2];
        if den.is_nan() || den <= 1e-9 {
            return false;
        }
        for i in 0..3 {
            self.x[i] += w[i] * j[i] * nu / den;
        }
        self.x[2] = wrap(self.x[2]);
        self.corrections = self.corrections.saturating_add(1);
        true
    }
}
