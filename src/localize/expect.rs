//! What a transducer anywhere should hear, from the compiled map's field
//! ([`crate::map::field`]): the exact predictions stored at the four
//! surrounding nodes, for the nearest of the node's headings, interpolated
//! where they agree.
//!
//! A plane's range is affine in the transducer's position, so four corners
//! that see the same plane satisfy `r₀₀ + r₁₁ = r₁₀ + r₀₁`; when they do
//! (within the range codes' rounding) the range is interpolated bilinearly,
//! exact for a plane. Otherwise the corners see different things (an edge of
//! the window, a nearer box) and the nearest corner's prediction is taken.
//! `docs/localization.md` measures the result against the exact prediction.

use crate::map::field::{Expected, FieldView};

/// Corners agree when `|r₀₀ + r₁₁ − r₁₀ − r₀₁|` is within this, mm ...
const AGREE_MM: f32 = 40.0;
/// ... plus this fraction of the smallest range (four codes' rounding).
const AGREE_REL: f32 = 0.045;

/// The field with the floats a lookup needs.
#[derive(Clone, Copy, Debug)]
pub struct FieldLookup<'f, 'a> {
    field: &'f FieldView<'a>,
    ox: f32,
    oy: f32,
    inv_node: f32,
    node_mm: f32,
    dirs: i32,
    dirs_per_rad: f32,
    cols: u32,
    rows: u32,
}

impl<'f, 'a> FieldLookup<'f, 'a> {
    /// Over `field` (which may be empty: every lookup is then `None`).
    pub fn new(field: &'f FieldView<'a>) -> Self {
        let h = field.header();
        let node_mm = h.node_mm.max(1) as f32;
        Self {
            field,
            ox: h.origin_x as f32,
            oy: h.origin_y as f32,
            inv_node: 1.0 / node_mm,
            node_mm,
            dirs: h.dirs.max(1) as i32,
            dirs_per_rad: h.dirs as f32 / core::f32::consts::TAU,
            cols: h.cols,
            rows: h.rows,
        }
    }

    /// The field.
    pub fn field(&self) -> &'f FieldView<'a> {
        self.field
    }

    /// The heading's index among a node's headings (nearest).
    #[inline]
    fn dir(&self, heading_rad: f32) -> usize {
        let d = libm::roundf(heading_rad * self.dirs_per_rad) as i32;
        // `dirs` ≥ 1 (`new`); checked, so no division by zero is linked in.
        d.checked_rem_euclid(self.dirs).unwrap_or(0) as usize
    }

    /// The grid cell holding (x, y) and the position within it, or `None`
    /// off the grid.
    #[inline]
    fn cell(&self, x_mm: f32, y_mm: f32) -> Option<(u32, u32, f32, f32)> {
        let u = (x_mm - self.ox) * self.inv_node;
        let v = (y_mm - self.oy) * self.inv_node;
        // Also false for NaN.
        if !(u >= 0.0 && v >= 0.0) {
            return None;
        }
        let (i, j) = (u as u32, v as u32);
        // (Checked: a far-off position saturates the cast at `u32::MAX`.)
        let (Some(i1), Some(j1)) = (i.checked_add(1), j.checked_add(1)) else { return None };
        if i1 >= self.cols || j1 >= self.rows {
            return None;
        }
        Some((i, j, u - i as f32, v - j as f32))
    }

    /// What a transducer at (`x_mm`, `y_mm`) facing `heading_rad` should
    /// hear; `None` where the field stores no node near it (the transducer
    /// cannot be there).
    // Out of line: inlined into `Measure::log_likelihood` (its one hot
    // caller) it cost the M4's searching cycle 2 % more (issue #36).
    #[inline(never)]
    pub fn expected(&self, x_mm: f32, y_mm: f32, heading_rad: f32) -> Option<Expected> {
        self.look::<false>(x_mm, y_mm, heading_rad).map(|(e, _)| e)
    }

    /// [`FieldLookup::expected`] and, where the four corners see one plane
    /// (the range interpolated), the range's slope by the transducer's
    /// position (∂r/∂x, ∂r/∂y: mm per mm, a unit vector away from a plane
    /// seen square-on). A place the localizer keeps corrects its pose by it
    /// (`super::place`); `None` where the nearest corner's prediction is
    /// taken, whose range does not vary smoothly.
    #[inline(never)]
    pub fn expected_slope(&self, x_mm: f32, y_mm: f32, heading_rad: f32) -> Option<(Expected, Option<[f32; 2]>)> {
        self.look::<true>(x_mm, y_mm, heading_rad)
    }

    /// The lookup, the slope computed only when `SLOPE` (the particles'
    /// lookup stays as short as it was).
    #[inline(always)]
    fn look<const SLOPE: bool>(&self, x_mm: f32, y_mm: f32, heading_rad: f32) -> Option<(Expected, Option<[f32; 2]>)> {
        let (i, j, fu, fv) = self.cell(x_mm, y_mm)?;
        let d = self.dir(heading_rad);
        let f = self.field;
        let at = |n: Option<u32>| n.and_then(|n| f.entries(n)).and_then(|e| e.get(d)).map(|&b| Expected::decode(b));
        let (n00, n10) = f.pair_at(i, j);
        let (n01, n11) = f.pair_at(i, j + 1);
        let (e00, e10, e01, e11) = (at(n00), at(n10), at(n01), at(n11));
        if let (
            Some(Expected::Echo { range_mm: a, sure: sa }),
            Some(Expected::Echo { range_mm: b, sure: sb }),
            Some(Expected::Echo { range_mm: c, sure: sc }),
            Some(Expected::Echo { range_mm: e, sure: se }),
        ) = (e00, e10, e01, e11)
        {
            let lo = a.min(b).min(c).min(e);
            if sa == sb && sa == sc && sa == se && (a + e - b - c).abs() <= AGREE_MM + AGREE_REL * lo {
                let twist = a + e - b - c;
                let r = a + (b - a) * fu + (c - a) * fv + twist * fu * fv;
                // (Not `then_some`: its argument is built even when unused.)
                let slope = if SLOPE {
                    Some([((b - a) + twist * fv) * self.inv_node, ((c - a) + twist * fu) * self.inv_node])
                } else {
                    None
                };
                return Some((Expected::Echo { range_mm: r, sure: sa }, slope));
            }
        }
        let nearest = match (fu < 0.5, fv < 0.5) {
            (true, true) => e00,
            (false, true) => e10,
            (true, false) => e01,
            (false, false) => e11,
        };
        nearest.map(|e| (e, None))
    }

    /// Whether the robot's centre may stand at (`x_mm`, `y_mm`): the nearest
    /// node is stored and free.
    pub fn is_free(&self, x_mm: f32, y_mm: f32) -> bool {
        let u = libm::roundf((x_mm - self.ox) * self.inv_node);
        let v = libm::roundf((y_mm - self.oy) * self.inv_node);
        if !(u >= 0.0 && v >= 0.0) || u >= self.cols as f32 || v >= self.rows as f32 {
            return false;
        }
        self.field.node_at(u as u32, v as u32).is_some_and(|n| self.field.is_free(n))
    }

    /// Node spacing, mm.
    pub fn node_mm(&self) -> f32 {
        self.node_mm
    }
}
