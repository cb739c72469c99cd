//! The single-lobe Gaussian credence model (paper §4: "the Gaussian curve
//! that is commonly used to model pressure amplitude"): the baseline the
//! neural net is compared with. One lobe, so it cannot see side lobes.

use super::{Credence, EchoGeometry, Kappa};

/// κ = `peak · exp(−θ² / 2σ²)` when `δ ≤ δ_max`, else 0.
///
/// `echoloc-lab train` fits a range-dependent version of this model to the
/// credence data (`lab/src/credence/gaussian.rs`); its width at 3 m is
/// about 14.8° (see `docs/credence.md`).
///
/// ```
/// use echoloc::credence::{gaussian::GaussianLobe, Credence, EchoGeometry};
/// let g = GaussianLobe { peak: 1.0, sigma_deg: 10.0, delta_max_mdeg: 15_000 };
/// let at = |t: i32| g.kappa(&EchoGeometry { range_mm: 2000, theta_mdeg: t, delta_mdeg: 0 }).to_num::<f32>();
/// assert!((at(0) - 1.0).abs() < 1e-4);
/// assert!((at(10_000) - 0.6065).abs() < 1e-3); // one σ off the axis
/// assert!(at(-25_000) < 0.05);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GaussianLobe {
    /// κ on the axis, `0 ..= 1`.
    pub peak: f32,
    /// The lobe's standard deviation, degrees.
    pub sigma_deg: f32,
    /// `δ_max`, millidegrees.
    pub delta_max_mdeg: i32,
}

impl Credence for GaussianLobe {
    fn kappa(&self, echo: &EchoGeometry) -> Kappa {
        if echo.delta_mdeg > self.delta_max_mdeg
            || self.sigma_deg.is_nan()
            || self.sigma_deg <= 0.0
            || !self.peak.is_finite()
        {
            return Kappa::ZERO;
        }
        let t = echo.theta_mdeg as f32 / 1000.0 / self.sigma_deg;
        let k = crate::f32math::clamp(self.peak, 0.0, 1.0) * libm::expf(-0.5 * t * t);
        Kappa::saturating_from_num(k)
    }
}
