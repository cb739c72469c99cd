//! Credence κ: how far a predicted echo can be trusted (paper §4, DESIGN §4.4).
//!
//! Prediction asks a [`Credence`] model for κ at each candidate echo point;
//! the model is a trait so that prediction does not depend on which model a
//! board ships: the crisp model, the single-lobe Gaussian baseline, or the
//! quantised 2-10-1 neural net.
//!
//! κ is a probability in `[0, 1]`, carried in firmware as the fixed-point
//! [`Kappa`] (unsigned Q1.15: `Kappa::ONE` is exactly 1).
//!
//! The shipped model is [`net::CredenceNet`]: the paper's 2-10-1 net over
//! (R, |θ|), trained by `echoloc-lab train` on data from a physical model of
//! a Polaroid 600-series transducer (`docs/credence.md`), run in firmware with
//! integer arithmetic only.

/// κ as unsigned Q1.15 fixed point, `0 ..= 1`.
pub type Kappa = fixed::types::U1F15;

/// The geometry of one candidate echo, as the signature tests measure it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EchoGeometry {
    /// Range from the transducer to the echo point, mm.
    pub range_mm: u32,
    /// Angle of the echo point off the transducer axis, millidegrees
    /// (signed; the cone is symmetric, models use `|θ|`).
    pub theta_mdeg: i32,
    /// Angle between the surface normal and the ray to the echo point,
    /// millidegrees, `0 ..= 90 000`.
    pub delta_mdeg: i32,
}

/// A credence model: κ for a candidate echo.
pub trait Credence {
    /// κ for an echo with this geometry.
    fn kappa(&self, echo: &EchoGeometry) -> Kappa;

    /// Whether κ for this echo can be at least `tau`. `false` only where it
    /// provably cannot, so that prediction may skip [`kappa`](Self::kappa)
    /// there and answer the same. The default never skips.
    fn may_reach(&self, echo: &EchoGeometry, tau: Kappa) -> bool {
        let _ = (echo, tau);
        true
    }
}

impl<C: Credence + ?Sized> Credence for &C {
    fn kappa(&self, echo: &EchoGeometry) -> Kappa {
        (**self).kappa(echo)
    }

    fn may_reach(&self, echo: &EchoGeometry, tau: Kappa) -> bool {
        (**self).may_reach(echo, tau)
    }
}

pub mod crisp;
pub mod gaussian;
pub mod net;
mod weights;
