//! The search of one beacon's front edges: exact clipping to the window, the
//! nearest credible point of each (Cases I–III), and the subsurface walk.

use super::edge::{diff_f32, fmax, fmin, roots, EdgeCtx, Occluders};
use super::occlusion::occluded;
use super::{Case, PredictParams, PredictStats, Prediction, MAX_SUBSURFACE_STEPS};
use crate::credence::{Credence, EchoGeometry, Kappa};
use crate::geometry::{Point, Segment};
use crate::map::{MapSource, Piece};
use crate::window::Window;

/// Searches every front edge of one beacon that meets the window.
/// `occluders`: the window's nearest candidates (see [`occluded`]). `oblique_limit`:
/// `(sin, cos)` of an angle above δ_max, to pass over edges seen beyond it
/// everywhere (see [`seen_beyond`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn search_piece<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    window: &Window,
    piece: &Piece<'_>,
    params: &PredictParams,
    credence: &K,
    occluders: Option<Occluders<'_>>,
    oblique_limit: Option<(f32, f32)>,
    best: &mut Option<(f32, Prediction)>,
    stats: &mut PredictStats,
) {
    let sector = &window.sector;
    let o = sector.apex;
    let axis = sector.axis_unit();
    // None when the transducer is inside this obstacle: nothing to see of it.
    for (edge, a, b) in piece.front_edges(o) {
        // An edge wholly beyond the best echo cannot give a nearer one:
        // skip its exact clipping (its box's distance bounds every point).
        if let Some((r, _)) = best {
            let e = Segment::new(a, b).bbox();
            // Gaps below 2²⁴ convert exactly; the 1 mm margin dwarfs the rounding of the squares.
            let gap = |lo: i32, v: i32, hi: i32| {
                (lo as i64 - v as i64).max(v as i64 - hi as i64).clamp(0, 1 << 24) as i32 as f32
            };
            let (dx, dy) = (gap(e.min.x, o.x, e.max.x), gap(e.min.y, o.y, e.max.y));
            if dx * dx + dy * dy > (*r + 1.0) * (*r + 1.0) {
                continue;
            }
        }
        if oblique_limit.is_some_and(|lim| seen_beyond(o, a, b, lim)) {
            continue; // every point of it fails the δ test: no exact clipping
        }
        let Some((lo, hi)) = sector.edge_window(a, b) else { continue };
        stats.edges = stats.edges.wrapping_add(1);
        let ctx = EdgeCtx { o, a, b, axis, piece: piece.id, obstacle: piece.obstacle, edge, occluders };
        search_edge(map, &ctx, lo, hi, sector.r_min_mm, sector.r_max_mm, params, credence, best, stats);
    }
}

/// Whether every point of edge `a → b` is seen from `o` at an incidence δ
/// beyond the angle whose `(sin, cos)` is `lim` (below 90°). δ is least at
/// the point of the edge nearest the foot of the perpendicular from `o`
/// (Proposition 2: it grows with the distance from the foot), so with the
/// foot inside the edge nothing is passed over, and otherwise only the end
/// nearer the foot is tested: `tan δ = |e·v| / |e×v|` there, `v` that end
/// from `o`. In `f32` from the exact differences: each product is within a
/// few ulp of `|e|·|v|`, so the angle is within 10⁻⁶ rad (the caller's
/// margin is 0.01°). An oblique edge costs this instead of its exact
/// clipping and the first steps of its walk.
#[inline]
pub(super) fn seen_beyond(o: Point, a: Point, b: Point, lim: (f32, f32)) -> bool {
    let e = (diff_f32(b.x, a.x), diff_f32(b.y, a.y));
    let va = (diff_f32(a.x, o.x), diff_f32(a.y, o.y));
    let along_a = e.0 * va.0 + e.1 * va.1;
    let v = if along_a >= 0.0 {
        va // the foot lies before a
    } else {
        let vb = (diff_f32(b.x, o.x), diff_f32(b.y, o.y));
        if e.0 * vb.0 + e.1 * vb.1 > 0.0 {
            return false; // the foot lies on the edge: δ = 0 there
        }
        vb
    };
    let along = (e.0 * v.0 + e.1 * v.1).abs();
    let across = (e.0 * v.1 - e.1 * v.0).abs();
    along * lim.1 > across * lim.0
}

#[allow(clippy::too_many_arguments)]
fn search_edge<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    ctx: &EdgeCtx<'_>,
    lo: f32,
    hi: f32,
    r_min: u32,
    r_max: u32,
    params: &PredictParams,
    credence: &K,
    best: &mut Option<(f32, Prediction)>,
    stats: &mut PredictStats,
) {
    let ao = (diff_f32(ctx.a.x, ctx.o.x), diff_f32(ctx.a.y, ctx.o.y));
    let e = (diff_f32(ctx.b.x, ctx.a.x), diff_f32(ctx.b.y, ctx.a.y));
    let len = crate::f32math::sqrt(e.0 * e.0 + e.1 * e.1);
    if len == 0.0 {
        return;
    }
    let foot = -(ao.0 * e.0 + ao.1 * e.1) / (len * len);
    let delta_max_mdeg = libm::roundf(params.window.delta_max_deg * 1000.0) as i32;
    // The window's ranges cut [lo, hi] into at most two intervals.
    let Some((q1, q2)) = roots(ao, e, r_max as f32) else { return };
    let (lo, hi) = (fmax(lo, q1), fmin(hi, q2));
    let whole = lo <= 0.0 && hi >= 1.0;
    let mut parts = [(lo, hi), (1.0, 0.0)];
    if r_min > 0 {
        if let Some((p1, p2)) = roots(ao, e, r_min as f32) {
            parts = [(lo, fmin(hi, p1)), (fmax(lo, p2), hi)];
        }
    }
    for (x, y) in parts {
        if x > y {
            continue;
        }
        let ds = fmax(params.step_mm.max(1) as f32 / len, (y - x) / MAX_SUBSURFACE_STEPS as f32);
        // Walk away from the point nearest the transducer: towards y from it
        // (itself included), then towards x when the foot lies inside.
        let near = crate::f32math::clamp(foot, x, y);
        for (end, dir, include_start) in [(y, 1.0f32, true), (x, -1.0f32, false)] {
            if !include_start && x >= near {
                continue;
            }
            let mut s = near;
            if !include_start {
                s = fmax(s - ds, end);
            }
            // A hard bound too: f32 steps on a very long edge could stall.
            let mut steps = 0;
            loop {
                steps += 1;
                if steps > MAX_SUBSURFACE_STEPS + 1 {
                    break;
                }
                let v = (ao.0 + s * e.0, ao.1 + s * e.1);
                let range = crate::f32math::sqrt(v.0 * v.0 + v.1 * v.1);
                // Farther along only gets farther; an equal range goes to the lower piece id.
                if best.is_some_and(|(r, p)| range > r || (range == r && ctx.piece >= p.piece)) {
                    break;
                }
                let delta = crate::f32math::atan2((e.0 * v.0 + e.1 * v.1).abs(), (e.0 * v.1 - e.1 * v.0).abs());
                let delta_mdeg = libm::roundf(delta.to_degrees() * 1000.0) as i32;
                // Test 2: δ grows with distance from the foot (Proposition 2),
                // so past δ_max nothing farther along this way can echo. (Before
                // θ: a step that fails it needs no second arctangent.)
                if delta_mdeg > delta_max_mdeg {
                    break;
                }
                let theta =
                    crate::f32math::atan2(ctx.axis.0 * v.1 - ctx.axis.1 * v.0, ctx.axis.0 * v.0 + ctx.axis.1 * v.1);
                let echo = EchoGeometry {
                    range_mm: libm::roundf(range) as u32,
                    theta_mdeg: libm::roundf(theta.to_degrees() * 1000.0) as i32,
                    delta_mdeg,
                };
                // Where κ provably cannot reach τ the net need not run: the
                // candidate is passed over either way.
                let kappa = if credence.may_reach(&echo, params.tau_kappa) {
                    stats.kappa_evals = stats.kappa_evals.wrapping_add(1);
                    credence.kappa(&echo)
                } else {
                    stats.kappa_bounded = stats.kappa_bounded.wrapping_add(1);
                    Kappa::ZERO
                };
                if kappa >= params.tau_kappa && !occluded(map, ctx, v, range, stats) {
                    let case = if (s - foot).abs() * len < 0.5 {
                        Case::I
                    } else if whole {
                        Case::II
                    } else {
                        Case::III
                    };
                    // (Within R_max of an in-range apex: saturating is exact there.)
                    let point = Point::new(
                        ctx.o.x.saturating_add(libm::roundf(v.0) as i32),
                        ctx.o.y.saturating_add(libm::roundf(v.1) as i32),
                    );
                    let tol = (params.tolerance_mm as u64
                        + echo.range_mm as u64 * params.tolerance_permille as u64 / 1000)
                        .min(u32::MAX as u64) as u32;
                    *best = Some((
                        range,
                        Prediction {
                            range_mm: echo.range_mm,
                            kappa,
                            theta_mdeg: echo.theta_mdeg,
                            delta_mdeg: if case == Case::I { 0 } else { echo.delta_mdeg },
                            piece: ctx.piece,
                            obstacle: ctx.obstacle,
                            edge: ctx.edge,
                            point,
                            tolerance_mm: tol,
                            case,
                            nearer_mm: None,
                        },
                    ));
                    break;
                }
                if (end - s) * dir <= 0.0 {
                    break;
                }
                s += ds * dir;
                if (end - s) * dir < 0.0 {
                    s = end;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::seen_beyond;
    use crate::geometry::Point;

    /// Against a brute force in `f64`: the least δ over 2 001 points of the
    /// edge (and its foot, when inside). An edge passed over must be seen
    /// beyond δ_max + 0.009° everywhere; one kept must come within 0.011°
    /// of the limit somewhere (the test is not much looser than it says).
    #[test]
    fn oblique_edges_are_passed_over_exactly_when_seen_beyond_the_limit() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = |span: i64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x >> 11) as i64 % (2 * span + 1) - span) as i32
        };
        let delta_max = 15.0f32;
        let lim = crate::f32math::sin_cos((delta_max + 0.01).to_radians());
        let (mut passed, mut kept) = (0, 0);
        for i in 0..20_000 {
            let span = [300, 5_000, 60_000][i % 3];
            let (o, a) = (Point::new(next(span), next(span)), Point::new(next(span), next(span)));
            let b = Point::new(a.x + next(span / 2), a.y + next(span / 2));
            if a == b {
                continue;
            }
            let e = ((b.x - a.x) as f64, (b.y - a.y) as f64);
            let delta_at = |s: f64| {
                let v = ((a.x - o.x) as f64 + s * e.0, (a.y - o.y) as f64 + s * e.1);
                (e.0 * v.0 + e.1 * v.1).abs().atan2((e.0 * v.1 - e.1 * v.0).abs()).to_degrees()
            };
            let foot = -(((a.x - o.x) as f64) * e.0 + ((a.y - o.y) as f64) * e.1) / (e.0 * e.0 + e.1 * e.1);
            let mut least = (0..=2_000).map(|k| delta_at(k as f64 / 2_000.0)).fold(f64::INFINITY, f64::min);
            if (0.0..=1.0).contains(&foot) {
                least = least.min(delta_at(foot));
            }
            if seen_beyond(o, a, b, lim) {
                passed += 1;
                assert!(least > f64::from(delta_max) + 0.009, "{o:?} {a:?} {b:?}: least δ {least}° passed over");
            } else {
                kept += 1;
                assert!(least < f64::from(delta_max) + 0.011, "{o:?} {a:?} {b:?}: least δ {least}° kept");
            }
        }
        assert!(passed > 5_000 && kept > 2_000, "passed over {passed}, kept {kept}");
    }
}
