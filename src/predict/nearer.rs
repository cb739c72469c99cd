//! The nearer-surface check ([`Prediction::nearer_mm`]): a corner or a face
//! within the check's δ nearer than the echo point.

use super::edge::{diff_f32, fmax, fmin, roots, EdgeCtx, Occluders};
use super::occlusion::occluded;
use super::{PredictStats, Prediction};
use crate::map::MapSource;
use crate::window::Window;

/// The search for [`Prediction::nearer_mm`] once `p` is known: fed the
/// pieces (every piece with a point nearer than `p`'s echo must be among
/// them), it keeps the nearest point of a front edge inside the window
/// (from `R_min` to `p`'s range less its tolerance), not occluded, that is
/// an end of its edge (a corner) or is seen within the check's δ of the
/// edge's normal. `p`'s own edge is left out: its nearer part failed κ, not
/// the geometry. The nearest point of an edge's part also has its least δ
/// (Proposition 2), so that point and the edge's ends decide an edge; the
/// answer does not depend on the order of the pieces.
pub(super) struct Nearer<'w> {
    window: &'w Window,
    /// `(sin, cos)` of the δ limit.
    lim: (f32, f32),
    min_range: f32,
    piece: u16,
    edge: u8,
    limit: f32,
    nearest: f32,
}

impl<'w> Nearer<'w> {
    pub(super) fn new(window: &'w Window, delta_deg: f32, p: &Prediction) -> Self {
        let limit = p.range_mm.saturating_sub(p.tolerance_mm) as f32;
        let lim = crate::f32math::sin_cos(delta_deg.to_radians());
        let min_range = window.sector.r_min_mm as f32;
        Self { window, lim, min_range, piece: p.piece, edge: p.edge, limit, nearest: limit }
    }

    // One copy per map type, not one inlined into each caller (flash).
    #[inline(never)]
    pub(super) fn piece<M: MapSource + ?Sized>(
        &mut self,
        map: &M,
        id: u16,
        occluders: Option<Occluders<'_>>,
        stats: &mut PredictStats,
    ) {
        let sector = &self.window.sector;
        let o = sector.apex;
        let Some(piece) = map.piece(id) else { return };
        for (edge, a, b) in piece.front_edges(o) {
            if id == self.piece && edge == self.edge {
                continue;
            }
            // The wedge's part; the ranges cut it below.
            let Some(c) = sector.clip_edge(a, b) else { continue };
            let (lo, hi) = (c.lo.to_f32(), c.hi.to_f32());
            let ao = (diff_f32(a.x, o.x), diff_f32(a.y, o.y));
            let e = (diff_f32(b.x, a.x), diff_f32(b.y, a.y));
            let ee = e.0 * e.0 + e.1 * e.1;
            if ee == 0.0 {
                continue;
            }
            // The part nearer than the nearest so far, less what is blanked.
            let Some((q1, q2)) = roots(ao, e, self.nearest) else { continue };
            let (lo, hi) = (fmax(lo, q1), fmin(hi, q2));
            if lo > hi {
                continue;
            }
            let mut parts = [(lo, hi), (1.0, 0.0)];
            if let Some((p1, p2)) = roots(ao, e, self.min_range) {
                parts = [(lo, fmin(hi, p1)), (fmax(lo, p2), hi)];
            }
            let foot = -(ao.0 * e.0 + ao.1 * e.1) / ee;
            let ctx = EdgeCtx { o, a, b, axis: (0.0, 0.0), piece: id, obstacle: piece.obstacle, edge, occluders };
            for (x, y) in parts {
                if x > y {
                    continue;
                }
                // The part's nearest point (its least δ), and the edge's
                // ends where the part holds them: corners echo at any δ.
                self.point(map, &ctx, ao, e, crate::f32math::clamp(foot, x, y), stats);
                if x <= 0.0 {
                    self.point(map, &ctx, ao, e, 0.0, stats);
                }
                if y >= 1.0 {
                    self.point(map, &ctx, ao, e, 1.0, stats);
                }
            }
        }
    }

    /// The point at `s` along the edge (`ao`: its start from the
    /// transducer, `e`: the edge), if nearer than the nearest so far, a
    /// corner or seen within the δ limit, and not occluded. Not inlined: it
    /// is called from three places (flash).
    #[inline(never)]
    fn point<M: MapSource + ?Sized>(
        &mut self,
        map: &M,
        ctx: &EdgeCtx<'_>,
        ao: (f32, f32),
        e: (f32, f32),
        s: f32,
        stats: &mut PredictStats,
    ) {
        let v = (ao.0 + s * e.0, ao.1 + s * e.1);
        let range = crate::f32math::sqrt(v.0 * v.0 + v.1 * v.1);
        if range >= self.nearest {
            return;
        }
        // δ within the limit: |e·v|·cos ≤ |e×v|·sin.
        let along = (e.0 * v.0 + e.1 * v.1).abs();
        let across = (e.0 * v.1 - e.1 * v.0).abs();
        let corner = s <= 0.0 || s >= 1.0;
        if (corner || along * self.lim.1 <= across * self.lim.0) && !occluded(map, ctx, v, range, stats) {
            self.nearest = range;
        }
    }

    pub(super) fn found(&self) -> Option<u32> {
        (self.nearest < self.limit).then(|| libm::roundf(self.nearest) as u32)
    }
}
