//! The fixed-capacity obstacle map.
//!
//! A map holds *obstacles* (solids or walls), each made of convex *pieces*.
//! Every piece keeps its true vertices and, once [`Map::finish`] has run, its
//! C-space-buffered vertices; a uniform grid indexes pieces by the cells their
//! buffered bounding box overlaps, so a query near a point never scans the
//! whole map. Capacities are const generics: `PIECES` obstacles and pieces,
//! `VERTS` vertices (true and buffered together), `CELLS` grid cells and
//! `REFS` cell→piece references. Nothing allocates; a full map says so with a
//! typed error and is left as it was before the call.
//!
//! The map lives in one of two states: *building* (obstacles may be added) and
//! *finished* (buffers and grid built; queries answer). Adding an obstacle to
//! a finished map returns it to building.

mod blob;
#[cfg_attr(not(test), deny(clippy::indexing_slicing))]
mod compiled;
#[cfg_attr(not(test), deny(clippy::indexing_slicing))]
mod crc32;
#[cfg_attr(not(test), deny(clippy::indexing_slicing))]
pub mod field;
mod grid;
mod header;
mod source;

pub use blob::{EncodeError, BLOB_VERSION};
pub use compiled::{Aligned, MapView, COMPILED_VERSION};
pub use crc32::{crc32, Crc32};
pub use field::{Expected, FieldParts, FieldView};
pub use header::{BlobError, BLOB_HEADER_LEN, BLOB_MAGIC};
pub use source::MapSource;

use heapless::Vec;

use crate::buffer::{grow, BufferError};
use crate::geometry::{Convex, ConvexError, Point, Rect, Segment, MAX_PIECE_VERTICES};
use crate::tvector::Entry;
use compiled::PieceRec;
use grid::Grid;

/// The map every shipped firmware and `echoloc-lab` use: 1024 obstacles and
/// pieces, 12 288 vertices (true and buffered), 4096 grid cells and 12 288
/// cell references — about 160 KiB of RAM, sized for an STM32F4-class part.
/// `echoloc-lab map import` refuses maps that do not fit it.
pub type StandardMap = Map<1024, 12288, 4096, 12288>;

/// What an obstacle is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum ObstacleKind {
    /// A solid region made of convex pieces of three or more vertices.
    Solid = 0,
    /// A thin two-sided wall made of two-vertex pieces (segments).
    Wall = 1,
}

impl ObstacleKind {
    /// The kind from its blob code.
    pub const fn from_code(c: u8) -> Option<Self> {
        match c {
            0 => Some(Self::Solid),
            1 => Some(Self::Wall),
            _ => None,
        }
    }
}

/// Which outline of a piece a query tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Layer {
    /// The true edges: ranges, visibility, occlusion.
    True,
    /// The C-space-buffered outline: the search for in-range beacons.
    Buffered,
}

/// Which fixed capacity ran out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Capacity {
    /// More obstacles or pieces than `PIECES`.
    Pieces,
    /// More vertices than `VERTS`.
    Vertices,
    /// More grid cells than `CELLS`: use a coarser cell.
    Cells,
    /// More cell→piece references than `REFS`: use a coarser cell.
    CellRefs,
}

/// Why a map operation failed. The map is left as it was before the call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapError {
    /// A fixed capacity ran out.
    Full(Capacity),
    /// An obstacle with no pieces.
    EmptyObstacle,
    /// A piece is not a valid convex piece.
    BadPiece {
        /// Index of the piece within the call.
        index: usize,
        /// What is wrong with it.
        error: ConvexError,
    },
    /// A solid piece with two vertices, or a wall piece with more than two.
    KindMismatch {
        /// Index of the piece within the call.
        index: usize,
    },
    /// A true piece with more than [`MAX_PIECE_VERTICES`] vertices.
    PieceTooLarge {
        /// Index of the piece within the call.
        index: usize,
    },
    /// Growing a piece failed.
    Buffer(BufferError),
    /// A grid cell of zero size.
    ZeroCell,
    /// A query on a map that has not been finished.
    NotFinished,
}

/// One obstacle: a run of consecutive pieces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Obstacle {
    /// Solid or wall.
    pub kind: ObstacleKind,
    /// Index of its first piece.
    pub first_piece: u16,
    /// Number of pieces.
    pub piece_count: u16,
}

/// A read-only view of one piece.
#[derive(Clone, Copy, Debug)]
pub struct Piece<'a> {
    /// Its index in the map.
    pub id: u16,
    /// The obstacle it belongs to.
    pub obstacle: u16,
    /// The true outline.
    pub shape: Convex<'a>,
    /// The buffered outline (equal to `shape` until the map is finished).
    pub buffered: Convex<'a>,
    /// Bounding box of `buffered`.
    pub bbox: Rect,
    /// Seams: edges covered by an edge of another piece of the same
    /// obstacle (bit `i` for edge `i`). They are inside the obstacle, so they
    /// are never surfaces.
    pub internal: u32,
}

impl<'a> Piece<'a> {
    /// The edges of its true outline that face `o` (the t-vector's front
    /// surfaces), seams left out, as `(index, start, end)`; none when `o`
    /// is inside it (nothing of it is seen from there). The window search
    /// and the nearer-surface check both walk these.
    #[inline]
    pub fn front_edges(&self, o: Point) -> FrontEdges<'a> {
        let t = self.shape.tvector(o);
        let mask = if t.is_inside() { 0 } else { self.shape.front_surfaces(t) & !self.internal };
        FrontEdges { shape: self.shape, mask }
    }
}

/// A piece's front edges ([`Piece::front_edges`]), lowest index first.
#[derive(Clone, Copy, Debug)]
pub struct FrontEdges<'a> {
    shape: Convex<'a>,
    /// Bit `i`: edge `i` is still to come.
    mask: u32,
}

impl Iterator for FrontEdges<'_> {
    type Item = (u8, Point, Point);

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        if self.mask == 0 {
            return None;
        }
        let i = self.mask.trailing_zeros() as usize;
        self.mask &= self.mask - 1;
        // Edge i runs from vertex i to the next (the last closes the
        // outline); `get`, so no index can panic (the mask is the shape's).
        let v = self.shape.vertices();
        let a = *v.get(i)?;
        let b = *v.get(i + 1).or_else(|| v.first())?;
        Some((i as u8, a, b))
    }
}

/// Where a segment first meets the true map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Hit {
    /// The piece hit.
    pub piece: u16,
    /// Its obstacle.
    pub obstacle: u16,
    /// Exact parameter along the segment.
    pub entry: Entry,
    /// The entry point, rounded to the nearest mm.
    pub point: Point,
}

/// Counts of one query's work, for reports and benchmarks (modulo 2³²).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QueryStats {
    /// Grid cells visited.
    pub cells: u32,
    /// Distinct candidate pieces whose box overlaps the query box.
    pub candidates: u32,
}

/// The map. See the module docs.
pub struct Map<const PIECES: usize, const VERTS: usize, const CELLS: usize, const REFS: usize> {
    obstacles: Vec<Obstacle, PIECES>,
    pieces: Vec<PieceRec, PIECES>,
    verts: Vec<Point, VERTS>,
    true_verts: usize,
    buffer_mm: u32,
    grid: Grid<CELLS, REFS>,
    finished: bool,
}

impl<const PIECES: usize, const VERTS: usize, const CELLS: usize, const REFS: usize> Default
    for Map<PIECES, VERTS, CELLS, REFS>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<const PIECES: usize, const VERTS: usize, const CELLS: usize, const REFS: usize> Map<PIECES, VERTS, CELLS, REFS> {
    // Piece ids are u16 and vertex offsets u32.
    const CAPACITY_OK: () = assert!(PIECES <= u16::MAX as usize && VERTS <= u32::MAX as usize);

    /// An empty map, building. `const`, so it can initialise a `static`
    /// without a stack copy.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CAPACITY_OK;
        Self {
            obstacles: Vec::new(),
            pieces: Vec::new(),
            verts: Vec::new(),
            true_verts: 0,
            buffer_mm: 0,
            grid: Grid::new(),
            finished: false,
        }
    }

    /// Removes everything.
    pub fn clear(&mut self) {
        self.obstacles.clear();
        self.pieces.clear();
        self.verts.clear();
        self.true_verts = 0;
        self.buffer_mm = 0;
        self.grid.clear();
        self.finished = false;
    }

    /// Back to building: drops buffered outlines and the grid.
    fn unfinish(&mut self) {
        if !self.finished && self.verts.len() == self.true_verts {
            return;
        }
        self.verts.truncate(self.true_verts);
        for p in self.pieces.iter_mut() {
            p.buf_start = p.true_start;
            p.buf_len = p.true_len;
            p.seams = 0;
            p.set_bbox(&self.verts[p.true_range()]);
        }
        self.grid.clear();
        self.finished = false;
    }

    /// Adds an obstacle made of the given convex pieces (counter-clockwise
    /// vertex lists; two-vertex segments for a wall). Returns its id. On any
    /// error nothing is added.
    pub fn add_obstacle(&mut self, kind: ObstacleKind, pieces: &[&[Point]]) -> Result<u16, MapError> {
        if pieces.is_empty() {
            return Err(MapError::EmptyObstacle);
        }
        for (index, p) in pieces.iter().enumerate() {
            Self::check_piece(kind, p).map_err(|e| match e {
                MapError::BadPiece { error, .. } => MapError::BadPiece { index, error },
                MapError::KindMismatch { .. } => MapError::KindMismatch { index },
                MapError::PieceTooLarge { .. } => MapError::PieceTooLarge { index },
                e => e,
            })?;
        }
        let nverts: usize = pieces.iter().map(|p| p.len()).sum();
        if self.obstacles.len() == PIECES || self.pieces.len() + pieces.len() > PIECES {
            return Err(MapError::Full(Capacity::Pieces));
        }
        if self.true_verts + nverts > VERTS {
            return Err(MapError::Full(Capacity::Vertices));
        }
        let mut id = 0;
        for (i, p) in pieces.iter().enumerate() {
            // Every check was made above: this cannot fail half-way.
            id = self.push_checked(kind, i == 0, p);
        }
        Ok(id)
    }

    fn check_piece(kind: ObstacleKind, p: &[Point]) -> Result<(), MapError> {
        Convex::new(p).map_err(|error| MapError::BadPiece { index: 0, error })?;
        if (kind == ObstacleKind::Wall) != (p.len() == 2) {
            return Err(MapError::KindMismatch { index: 0 });
        }
        if p.len() > MAX_PIECE_VERTICES {
            return Err(MapError::PieceTooLarge { index: 0 });
        }
        Ok(())
    }

    /// Adds one convex piece: the first of a new obstacle of `kind` when
    /// `new_obstacle`, else one more piece of the last obstacle (which must be
    /// of the same kind). Returns the obstacle's id. On error nothing is
    /// added. Lets an importer stream pieces without collecting them.
    pub fn push_piece(&mut self, kind: ObstacleKind, new_obstacle: bool, p: &[Point]) -> Result<u16, MapError> {
        Self::check_piece(kind, p)?;
        if !new_obstacle && self.obstacles.last().map(|o| o.kind) != Some(kind) {
            return Err(MapError::KindMismatch { index: 0 });
        }
        if self.pieces.len() == PIECES || (new_obstacle && self.obstacles.len() == PIECES) {
            return Err(MapError::Full(Capacity::Pieces));
        }
        // Checked against the true vertices, before anything changes.
        if self.true_verts + p.len() > VERTS {
            return Err(MapError::Full(Capacity::Vertices));
        }
        Ok(self.push_checked(kind, new_obstacle, p))
    }

    /// `push_piece` once its checks have passed.
    fn push_checked(&mut self, kind: ObstacleKind, new_obstacle: bool, p: &[Point]) -> u16 {
        self.unfinish();
        if new_obstacle {
            let first_piece = self.pieces.len() as u16;
            let _ = self.obstacles.push(Obstacle { kind, first_piece, piece_count: 0 });
        }
        let id = self.obstacles.len() as u16 - 1;
        let start = self.verts.len() as u32;
        // The caller checked the capacities: these pushes cannot fail.
        let _ = self.verts.extend_from_slice(p);
        let len = p.len() as u8;
        let _ = self.pieces.push(PieceRec {
            obstacle: id,
            true_len: len,
            buf_len: len,
            true_start: start,
            buf_start: start,
            seams: 0,
            bbox: PieceRec::box_of(p),
        });
        self.true_verts = self.verts.len();
        if let Some(o) = self.obstacles.last_mut() {
            o.piece_count += 1;
        }
        id
    }

    /// Grows every piece by `buffer_mm` and builds the grid index with square
    /// cells of `cell_mm`. May be called again with other parameters. On
    /// error the map is left building (unfinished), its obstacles intact.
    pub fn finish(&mut self, buffer_mm: u32, cell_mm: u32) -> Result<(), MapError> {
        self.unfinish();
        if cell_mm == 0 {
            return Err(MapError::ZeroCell);
        }
        let r = self.build(buffer_mm, cell_mm);
        match r {
            Ok(()) => {
                self.finished = true;
                self.mark_seams();
            }
            Err(_) => {
                self.unfinish();
                self.buffer_mm = 0;
            }
        }
        r
    }

    fn build(&mut self, buffer_mm: u32, cell_mm: u32) -> Result<(), MapError> {
        self.buffer_mm = buffer_mm;
        for i in 0..self.pieces.len() {
            let rec = self.pieces[i];
            let shape = Convex::new_unchecked(&self.verts[rec.true_range()]);
            let grown = grow(shape, buffer_mm).map_err(MapError::Buffer)?;
            let start = self.verts.len() as u32;
            self.verts.extend_from_slice(&grown).map_err(|_| MapError::Full(Capacity::Vertices))?;
            let rec = &mut self.pieces[i];
            rec.buf_start = start;
            rec.buf_len = grown.len() as u8;
            rec.set_bbox(&grown);
        }
        let boxes = self.pieces.iter().map(PieceRec::bbox);
        self.grid.build(boxes, cell_mm)
    }

    /// Marks every seam (see [`source::seams_of`]) once the grid is built.
    fn mark_seams(&mut self) {
        for i in 0..self.pieces.len() {
            let mask = source::seams_of(&*self, i as u16).unwrap_or(0);
            self.pieces[i].seams = mask;
        }
    }

    /// Whether buffers and grid are built.
    pub const fn is_finished(&self) -> bool {
        self.finished
    }

    /// The buffer distance `t_b` the map was finished with, mm.
    pub const fn buffer_mm(&self) -> u32 {
        self.buffer_mm
    }

    /// The grid's cell size (mm), columns and rows.
    pub fn grid_dims(&self) -> (u32, u16, u16) {
        self.grid.dims()
    }

    /// Number of cell→piece references in the grid.
    pub fn grid_refs(&self) -> usize {
        self.grid.refs_len()
    }

    /// The obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Number of pieces.
    pub fn piece_count(&self) -> usize {
        self.pieces.len()
    }

    /// Number of true vertices (= true edges, counting a wall's two faces).
    pub fn true_vertex_count(&self) -> usize {
        self.true_verts
    }

    /// Number of vertices stored, true and buffered.
    pub fn vertex_count(&self) -> usize {
        self.verts.len()
    }

    /// Bounding box of every buffered outline, or `None` for an empty map.
    pub fn bounds(&self) -> Option<Rect> {
        self.pieces.iter().map(PieceRec::bbox).reduce(Rect::union)
    }

    /// The piece with id `id`, if any.
    pub fn piece(&self, id: u16) -> Option<Piece<'_>> {
        let r = self.pieces.get(id as usize)?;
        Some(Piece {
            id,
            obstacle: r.obstacle,
            shape: Convex::new_unchecked(&self.verts[r.true_range()]),
            buffered: Convex::new_unchecked(&self.verts[r.buf_range()]),
            bbox: r.bbox(),
            internal: r.seams,
        })
    }

    /// Every piece.
    pub fn pieces(&self) -> impl Iterator<Item = Piece<'_>> + '_ {
        (0..self.pieces.len() as u16).filter_map(|i| self.piece(i))
    }

    /// See [`MapSource::for_each_candidate`].
    pub fn for_each_candidate(&self, area: Rect, f: impl FnMut(Piece<'_>)) -> Result<QueryStats, MapError> {
        MapSource::for_each_candidate(self, area, f)
    }

    /// See [`MapSource::for_each_hit`].
    pub fn for_each_hit(&self, seg: Segment, layer: Layer, f: impl FnMut(Piece<'_>)) -> Result<QueryStats, MapError> {
        MapSource::for_each_hit(self, seg, layer, f)
    }

    /// See [`MapSource::first_hit`].
    pub fn first_hit(&self, seg: Segment) -> Result<Option<Hit>, MapError> {
        MapSource::first_hit(self, seg)
    }
}

impl<const PIECES: usize, const VERTS: usize, const CELLS: usize, const REFS: usize> MapSource
    for Map<PIECES, VERTS, CELLS, REFS>
{
    fn buffer_mm(&self) -> u32 {
        self.buffer_mm
    }

    fn obstacle_count(&self) -> usize {
        self.obstacles.len()
    }

    fn obstacle(&self, id: u16) -> Option<Obstacle> {
        self.obstacles.get(id as usize).copied()
    }

    fn piece_count(&self) -> usize {
        self.pieces.len()
    }

    fn piece(&self, id: u16) -> Option<Piece<'_>> {
        Map::piece(self, id)
    }

    fn for_each_candidate_box(&self, area: Rect, f: impl FnMut(u16, Rect)) -> Result<QueryStats, MapError> {
        if !self.finished {
            return Err(MapError::NotFinished);
        }
        let pieces = &self.pieces;
        Ok(self.grid.index().query(
            area,
            |id| pieces.get(id as usize).map_or(Rect::around(Point::new(0, 0)), PieceRec::bbox),
            f,
        ))
    }
}
