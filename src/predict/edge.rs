//! One edge as the search sees it from the transducer, and the `f32`
//! helpers the searches share.

use crate::geometry::{Point, Rect};

pub(super) struct EdgeCtx<'k> {
    pub(super) o: Point,
    pub(super) a: Point,
    pub(super) b: Point,
    pub(super) axis: (f32, f32),
    pub(super) piece: u16,
    pub(super) obstacle: u16,
    pub(super) edge: u8,
    /// The window's nearest candidates, when known.
    pub(super) occluders: Option<Occluders<'k>>,
}

/// The window's candidates as the occlusion test may use them.
#[derive(Clone, Copy)]
pub(super) struct Occluders<'k> {
    /// Their keys, sorted by box distance.
    pub(super) keys: &'k [u32],
    /// The box they were found in.
    pub(super) area: Rect,
    /// A key's distance bound times this is a lower bound of its box's squared distance, mm².
    pub(super) scale: f32,
    /// Every candidate whose box lies nearer than this (squared, mm²) is among the keys.
    pub(super) complete: f32,
}

/// The larger of two numbers that are not NaN (`f32::max` is a library call
/// on a Cortex-M4, for its NaN rule).
#[inline(always)]
pub(super) fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The smaller of two numbers that are not NaN.
#[inline(always)]
pub(super) fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `a − b` as `f32`, rounded once: through `i32` (the FPU converts it) when
/// the difference fits, else through `i64` (a library call on a Cortex-M4).
#[inline]
pub(super) fn diff_f32(a: i32, b: i32) -> f32 {
    match a.checked_sub(b) {
        Some(d) => d as f32,
        None => (a as i64 - b as i64) as f32,
    }
}

/// The roots of `|ao + s·e|² = r²` as `(s1, s2)`, `s1 ≤ s2`, if any.
pub(super) fn roots(ao: (f32, f32), e: (f32, f32), r: f32) -> Option<(f32, f32)> {
    let ee = e.0 * e.0 + e.1 * e.1;
    let b = ao.0 * e.0 + ao.1 * e.1;
    let c = ao.0 * ao.0 + ao.1 * ao.1 - r * r;
    let disc = b * b - ee * c;
    if disc < 0.0 || ee == 0.0 {
        return None;
    }
    let sq = crate::f32math::sqrt(disc);
    Some(((-b - sq) / ee, (-b + sq) / ee))
}
