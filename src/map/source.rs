//! What the predictor reads from a map, whichever form it lives in: the
//! host's building [`Map`](super::Map) in RAM or a compiled
//! [`MapView`](super::MapView) read in place from flash. Both answer the
//! same queries from the same grid, in the same order, so predictions from
//! either are identical bit for bit (`host-tests/tests/map_view_identity.rs`).

use super::{Hit, Layer, MapError, Obstacle, Piece, QueryStats};
use crate::geometry::{dot, orient, point_on_segment, Convex, Point, Rect, Segment};

/// A finished map that answers queries. See the module docs.
pub trait MapSource {
    /// The buffer distance `t_b` the map was finished with, mm.
    fn buffer_mm(&self) -> u32;
    /// Number of obstacles.
    fn obstacle_count(&self) -> usize;
    /// The obstacle with id `id`, if any.
    fn obstacle(&self, id: u16) -> Option<Obstacle>;
    /// Number of pieces.
    fn piece_count(&self) -> usize;
    /// The piece with id `id`, if any.
    fn piece(&self, id: u16) -> Option<Piece<'_>>;
    /// Calls `f(id, box)` once for each piece whose buffered bounding box
    /// overlaps `area`, through the grid (never a scan of the whole map), in
    /// grid order: the cheap form, for callers that filter on the box before
    /// they need the piece.
    fn for_each_candidate_box(&self, area: Rect, f: impl FnMut(u16, Rect)) -> Result<QueryStats, MapError>;

    /// Calls `f` once for each piece whose buffered bounding box overlaps
    /// `area`, as [`MapSource::for_each_candidate_box`] finds them.
    fn for_each_candidate(&self, area: Rect, mut f: impl FnMut(Piece<'_>)) -> Result<QueryStats, MapError> {
        self.for_each_candidate_box(area, |id, _| {
            if let Some(p) = self.piece(id) {
                f(p)
            }
        })
    }

    /// Every obstacle, in id order.
    fn obstacles_iter(&self) -> impl Iterator<Item = Obstacle> + '_ {
        (0..self.obstacle_count() as u16).filter_map(|i| self.obstacle(i))
    }

    /// Every piece, in id order.
    fn pieces_iter(&self) -> impl Iterator<Item = Piece<'_>> + '_ {
        (0..self.piece_count() as u16).filter_map(|i| self.piece(i))
    }

    /// Bounding box of every buffered outline, or `None` for an empty map.
    fn bounds_of_pieces(&self) -> Option<Rect> {
        self.pieces_iter().map(|p| p.bbox).reduce(Rect::union)
    }

    /// Calls `f` for each piece whose chosen outline the closed segment meets
    /// (exact t-vector test), through the grid.
    fn for_each_hit(&self, seg: Segment, layer: Layer, mut f: impl FnMut(Piece<'_>)) -> Result<QueryStats, MapError> {
        self.for_each_candidate(seg.bbox(), |p| {
            let shape = match layer {
                Layer::True => p.shape,
                Layer::Buffered => p.buffered,
            };
            if shape.hits_segment(seg.a, seg.b) {
                f(p)
            }
        })
    }

    /// Where the segment first meets a true outline, going from `seg.a`;
    /// ties go to the lower piece id.
    fn first_hit(&self, seg: Segment) -> Result<Option<Hit>, MapError> {
        let mut best: Option<Hit> = None;
        self.for_each_candidate(seg.bbox(), |p| {
            if let Some(entry) = p.shape.entry(seg) {
                let better = match &best {
                    None => true,
                    Some(b) => entry.cmp_exact(&b.entry).then(p.id.cmp(&b.piece)).is_lt(),
                };
                if better {
                    best = Some(Hit { piece: p.id, obstacle: p.obstacle, entry, point: entry.point_on(seg) });
                }
            }
        })?;
        Ok(best)
    }
}

/// The seams of piece `id`: bit `i` when its edge `i` is covered by an edge
/// of another piece of the same obstacle running the other way (left by
/// convex splitting; never a surface). Reads only true outlines and the grid,
/// so a compiled map's stored seams can be checked against it.
pub(super) fn seams_of<M: MapSource + ?Sized>(m: &M, id: u16) -> Result<u32, MapError> {
    let Some(piece) = m.piece(id) else { return Ok(0) };
    let a = piece.shape;
    if a.is_wall() {
        return Ok(0);
    }
    let area = Rect::of_points(a.vertices()).unwrap_or(Rect::around(Point::new(0, 0)));
    let mut mask = 0u32;
    m.for_each_candidate(area, |other| {
        if other.id == id || other.obstacle != piece.obstacle {
            return;
        }
        mask |= covered_edges(a, other.shape);
    })?;
    Ok(mask)
}

/// Bit `i` for each edge of `a` that lies on an edge of `b` running the other way.
fn covered_edges(a: Convex<'_>, b: Convex<'_>) -> u32 {
    let mut mask = 0u32;
    // At most 32 edges (`Convex::new`): the `min` keeps the shift in range.
    for ea in 0..a.edge_count().min(32) {
        let (u, v) = a.edge(ea);
        for eb in 0..b.edge_count() {
            let (p, q) = b.edge(eb);
            let collinear = orient(p, q, u) == 0 && orient(p, q, v) == 0;
            let opposite = dot(v.sub(u), q.sub(p)) < 0;
            if collinear && opposite && point_on_segment(u, p, q) && point_on_segment(v, p, q) {
                mask |= 1 << ea;
            }
        }
    }
    mask
}
