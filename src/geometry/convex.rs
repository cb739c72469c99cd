//! Validated convex pieces: the unit every collision test works on.

use super::{orient, Point, Rect};

/// Most vertices a true convex piece may have (splitting stops merging there).
pub const MAX_PIECE_VERTICES: usize = 24;
/// Most vertices of a buffered piece: a true piece plus the buffer octagon.
pub const MAX_BUFFERED_VERTICES: usize = MAX_PIECE_VERTICES + 8;

// A t-vector holds one bit per edge (walls use four bits: two faces, two caps).
const _: () = assert!(MAX_BUFFERED_VERTICES <= 32);

/// Why a vertex list is not a convex piece.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConvexError {
    /// Fewer than two vertices.
    TooFewVertices,
    /// More than [`MAX_BUFFERED_VERTICES`] vertices.
    TooManyVertices,
    /// A coordinate beyond `±COORD_MAX`.
    CoordinateOutOfRange,
    /// Two consecutive vertices coincide (or a wall of zero length).
    DuplicateVertex,
    /// A vertex where the boundary does not turn strictly left (collinear or
    /// reflex), or the vertices are clockwise.
    NotStrictlyConvex,
    /// All turns are left but the boundary winds around more than once.
    SelfIntersecting,
}

/// A validated convex piece borrowed from a vertex list.
///
/// Either a *solid* piece — three or more vertices, counter-clockwise, every
/// turn strictly left, winding once — or a *wall*: exactly two distinct
/// vertices, a thin two-sided obstacle whose two faces are the edges `a→b`
/// and `b→a`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Convex<'a> {
    verts: &'a [Point],
}

impl<'a> Convex<'a> {
    /// Validates `verts` as a convex piece (see the type's docs).
    ///
    /// ```
    /// use echoloc::geometry::{Convex, ConvexError, Point};
    /// let sq = [Point::new(0, 0), Point::new(10, 0), Point::new(10, 10), Point::new(0, 10)];
    /// assert!(Convex::new(&sq).is_ok());
    /// let cw = [sq[0], sq[3], sq[2], sq[1]];
    /// assert_eq!(Convex::new(&cw), Err(ConvexError::NotStrictlyConvex));
    /// ```
    pub fn new(verts: &'a [Point]) -> Result<Self, ConvexError> {
        let n = verts.len();
        if n < 2 {
            return Err(ConvexError::TooFewVertices);
        }
        if n > MAX_BUFFERED_VERTICES {
            return Err(ConvexError::TooManyVertices);
        }
        if !verts.iter().all(|p| p.in_range()) {
            return Err(ConvexError::CoordinateOutOfRange);
        }
        for i in 0..n {
            if verts[i] == verts[(i + 1) % n] {
                return Err(ConvexError::DuplicateVertex);
            }
        }
        if n == 2 {
            return Ok(Self { verts });
        }
        // Strict left turns everywhere, and the edge direction passes from the
        // upper to the lower half-plane exactly once: the boundary winds once.
        let upper = |a: Point, b: Point| {
            let (dx, dy) = b.sub(a);
            dy > 0 || (dy == 0 && dx > 0)
        };
        let mut crossings = 0u8;
        for i in 0..n {
            let (a, b, c) = (verts[i], verts[(i + 1) % n], verts[(i + 2) % n]);
            if orient(a, b, c) <= 0 {
                return Err(ConvexError::NotStrictlyConvex);
            }
            if upper(a, b) && !upper(b, c) {
                // Only "exactly one" matters: saturating is exact for that.
                crossings = crossings.saturating_add(1u8);
            }
        }
        if crossings != 1 {
            return Err(ConvexError::SelfIntersecting);
        }
        Ok(Self { verts })
    }

    /// Wraps a vertex list already known to be valid (for example one that
    /// came out of [`Convex::new`] before and was stored unchanged).
    pub(crate) const fn new_unchecked(verts: &'a [Point]) -> Self {
        Self { verts }
    }

    /// The vertices, counter-clockwise.
    #[inline]
    pub const fn vertices(&self) -> &'a [Point] {
        self.verts
    }

    /// Number of vertices (2 for a wall).
    #[inline]
    pub const fn len(&self) -> usize {
        self.verts.len()
    }

    /// Always false: a piece has at least two vertices.
    #[inline]
    pub const fn is_empty(&self) -> bool {
        false
    }

    /// Whether this is a two-vertex wall.
    #[inline]
    pub const fn is_wall(&self) -> bool {
        self.verts.len() == 2
    }

    /// Number of edges (surfaces): `n` for a solid, 2 for a wall (one per face).
    #[inline]
    pub const fn edge_count(&self) -> usize {
        self.verts.len()
    }

    /// Edge `i` as `(start, end)`, counter-clockwise; for a wall edge 0 is
    /// `a→b` and edge 1 is `b→a`.
    #[inline]
    pub fn edge(&self, i: usize) -> (Point, Point) {
        let n = self.verts.len();
        (self.verts[i], self.verts[(i + 1) % n])
    }

    /// Twice the area (0 for a wall), exact.
    pub fn area2(&self) -> i64 {
        let n = self.verts.len();
        let o = self.verts[0];
        (1..n.saturating_sub(1)).map(|i| orient(o, self.verts[i], self.verts[i + 1])).sum()
    }

    /// Bounding box.
    pub fn bbox(&self) -> Rect {
        // `verts` is never empty for a validated piece.
        Rect::of_points(self.verts).unwrap_or(Rect::around(Point::new(0, 0)))
    }
}
