//! Angles every room of the lab shares (the simulator, bags, logs, the
//! board's comparison): kept on the ground floor, so none reaches up for it.

/// Wraps an angle to (−π, π].
///
/// ```
/// use echoloc_lab::angle::wrap;
/// use std::f64::consts::PI;
/// assert!((wrap(3.0 * PI) - PI).abs() < 1e-12);
/// assert!((wrap(-PI) - PI).abs() < 1e-12);
/// assert_eq!(wrap(0.5), 0.5);
/// ```
pub fn wrap(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let r = a - TAU * libm::floor((a + PI) / TAU);
    if r <= -PI {
        r + TAU
    } else {
        r
    }
}
