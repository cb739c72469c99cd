//! Test 4: whether the ray to an echo point meets another piece.

use super::edge::{fmax, EdgeCtx};
use super::PredictStats;
use crate::geometry::{Point, Segment};
use crate::map::{Layer, MapSource};

/// Test 4: does the ray from the transducer to the point `v` (relative to
/// it) meet any other piece? The ray stops a millimetre short of the point,
/// so a neighbour that only touches the echo point does not hide it.
///
/// With the window's sorted candidates at hand (every piece whose box meets
/// the window's box, within `R_max`, up to the distance they are complete
/// to), and the ray inside that box and within that distance, only the
/// candidates whose box lies nearer than the point are tested: a piece the
/// ray meets at `q` has `q` in its box, so its box meets the window's box,
/// and its box is no farther than `q`. The answer is the grid query's,
/// without walking the grid again.
pub(super) fn occluded<M: MapSource + ?Sized>(
    map: &M,
    ctx: &EdgeCtx<'_>,
    v: (f32, f32),
    range: f32,
    stats: &mut PredictStats,
) -> bool {
    stats.occlusion_tests = stats.occlusion_tests.wrapping_add(1);
    let k = fmax((range - 1.0) / range, 0.0);
    let end = Point::new(
        ctx.o.x.saturating_add(libm::roundf(v.0 * k) as i32),
        ctx.o.y.saturating_add(libm::roundf(v.1 * k) as i32),
    );
    let seg = Segment::new(ctx.o, end);
    let reach = seg.bbox();
    let reach2 = (range + 1.0) * (range + 1.0);
    if let Some(c) =
        ctx.occluders.filter(|c| c.area.contains(reach.min) && c.area.contains(reach.max) && reach2 < c.complete)
    {
        for &key in c.keys {
            if (key >> 16) as f32 * c.scale > reach2 {
                break; // this box and every later one lie beyond the point
            }
            let id = key as u16;
            if id == ctx.piece {
                continue;
            }
            if let Some(p) = map.piece(id) {
                if p.bbox.overlaps(&reach) && p.shape.hits_segment(seg.a, seg.b) {
                    return true;
                }
            }
        }
        return false;
    }
    let mut hidden = false;
    let _ = map.for_each_hit(seg, Layer::True, |p| {
        if p.id != ctx.piece {
            hidden = true;
        }
    });
    hidden
}
