//! The crisp credence model: κ = 1 inside the window's half-angle with a
//! cone arc deviation within `δ_max`, else 0 (the paper's crisp reading of
//! §5.2, before credence is learnt).

use super::{Credence, EchoGeometry, Kappa};

/// κ = 1 when `|θ| ≤ θ_o` and `δ ≤ δ_max`, else 0.
///
/// `θ_o` is met with a tolerance of [`Crisp::EDGE_TOLERANCE_MDEG`]: a window's
/// cone edges are integer directions (resolution 1/16384 rad = 0.0035°), so a
/// point clipped exactly onto the edge can measure a few thousandths of a
/// degree beyond `θ_o` from the float axis; it is still in the window.
///
/// ```
/// use echoloc::credence::{crisp::Crisp, Credence, EchoGeometry, Kappa};
/// let c = Crisp { half_angle_mdeg: 15_000, delta_max_mdeg: 15_000 };
/// let on = EchoGeometry { range_mm: 2000, theta_mdeg: -10_000, delta_mdeg: 3_000 };
/// assert_eq!(c.kappa(&on), Kappa::ONE);
/// assert_eq!(c.kappa(&EchoGeometry { delta_mdeg: 20_000, ..on }), Kappa::ZERO);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Crisp {
    /// `θ_o`, millidegrees.
    pub half_angle_mdeg: i32,
    /// `δ_max`, millidegrees.
    pub delta_max_mdeg: i32,
}

impl Crisp {
    /// How far past `θ_o` a point still counts as inside, millidegrees.
    pub const EDGE_TOLERANCE_MDEG: u32 = 5;
}

impl Credence for Crisp {
    fn kappa(&self, echo: &EchoGeometry) -> Kappa {
        let half = self.half_angle_mdeg.unsigned_abs().saturating_add(Self::EDGE_TOLERANCE_MDEG);
        if echo.theta_mdeg.unsigned_abs() <= half && echo.delta_mdeg <= self.delta_max_mdeg {
            Kappa::ONE
        } else {
            Kappa::ZERO
        }
    }
}
