//! The compiled map: everything the predictor reads, written once by the
//! host in its final form and read in place (from flash) through a
//! [`MapView`]. RAM used by a view is a few slices, whatever the map's size.
//!
//! Version 3 of the blob (`docs/map-blob.md`). Little-endian, every section
//! 4-aligned from a 4-aligned start:
//!
//! ```text
//! header (16 bytes)  magic b"ECHM", version u16 = 2, flags u16 = 0,
//!                    payload_len u32, crc32 u32 (CRC-32 of the payload)
//! counts (48 bytes)  buffer_mm, cell_mm, obstacles, pieces, true_vertices,
//!                    vertices, grid origin x i32, origin y i32, cols, rows,
//!                    refs, field_len (the field's bytes)     (u32 unless said)
//! obstacles × 8      kind u8, 0 u8, piece_count u16, first_piece u16, 0 u16
//! pieces × 32        obstacle u16, true_len u8, buf_len u8, true_start u32,
//!                    buf_start u32, seams u32, buffered box [i32; 4]
//! vertices × 8       x i32, y i32   (all true outlines, then all buffered)
//! cell starts        u32 × (cols·rows + 1), the last = refs
//! refs               u16 × refs (piece ids, descending within a cell),
//!                    zero-padded to a multiple of 4 bytes
//! field              the localization field (`super::field`): header,
//!                    row starts, runs, free bits, entries; an empty one
//!                    when the map was compiled without it
//! ```
//!
//! [`MapView::new`] checks everything once, in one pass over the sections,
//! and copies nothing: CRC, sizes, alignment, every index and range, every
//! true piece convex and counter-clockwise, every buffered outline equal to
//! the buffer grown from its true piece, every box, the grid's exact
//! coverage (each piece in exactly the cells its box covers) and the seams.
//! A view therefore answers exactly as the [`Map`] it was compiled from.
//!
//! Zero copy through `bytemuck`'s checked casts (alignment and length are
//! checked at run time; no `unsafe` here): a hand-written reader would cost
//! a shift and an or per field on every query, and `zerocopy` needs more
//! derive machinery for the same casts.

use bytemuck::{Pod, Zeroable};

use super::field::{FieldParts, FieldView};
use super::grid::GridRef;
use super::source::{seams_of, MapSource};
use super::{BlobError, Map, MapError, Obstacle, ObstacleKind, Piece, QueryStats, BLOB_HEADER_LEN};
use crate::buffer::grow;
use crate::geometry::{Convex, Point, Rect, MAX_PIECE_VERTICES};

#[cfg(target_endian = "big")]
compile_error!("compiled maps are read in place as little-endian words");

/// The compiled map's blob version: 3 since the localization field
/// ([`super::field`]) was added; a version 2 blob is refused with
/// [`BlobError::Outdated`] (compile it again with `echoloc-lab map import`).
pub const COMPILED_VERSION: u16 = 3;

/// The compiled version before the localization field.
pub const OUTDATED_VERSION: u16 = 2;

const COUNTS_LEN: usize = 48;

/// Bytes aligned for a [`MapView`]: `static MAP: &Aligned<[u8]> =
/// &Aligned(*include_bytes!("depot.map"));` then `MapView::new(&MAP.0)`.
#[repr(C, align(8))]
pub struct Aligned<B: ?Sized>(pub B);

#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[repr(C)]
struct Counts {
    buffer_mm: u32,
    cell_mm: u32,
    obstacles: u32,
    pieces: u32,
    true_vertices: u32,
    vertices: u32,
    origin_x: i32,
    origin_y: i32,
    cols: u32,
    rows: u32,
    refs: u32,
    /// The field's bytes: with it the payload's size is fixed by the counts,
    /// so a lying count is a size error, not a misread field.
    field_len: u32,
}

#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[repr(C)]
struct ObstacleRec {
    kind: u8,
    reserved0: u8,
    piece_count: u16,
    first_piece: u16,
    reserved1: u16,
}

/// One piece's record: the same 32 bytes in the host's `Map` (in RAM) and
/// in a compiled map (in flash).
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[repr(C)]
pub(super) struct PieceRec {
    pub(super) obstacle: u16,
    pub(super) true_len: u8,
    pub(super) buf_len: u8,
    pub(super) true_start: u32,
    pub(super) buf_start: u32,
    /// Edges shared with another piece of the same obstacle (seams left by
    /// convex splitting): bit `i` for edge `i`. Not surfaces: no echo.
    pub(super) seams: u32,
    /// Box of the buffered outline (the true one until the map is
    /// finished): min x, min y, max x, max y.
    pub(super) bbox: [i32; 4],
}

impl PieceRec {
    pub(super) fn true_range(&self) -> core::ops::Range<usize> {
        self.true_start as usize..self.true_start as usize + self.true_len as usize
    }

    pub(super) fn buf_range(&self) -> core::ops::Range<usize> {
        self.buf_start as usize..self.buf_start as usize + self.buf_len as usize
    }

    /// The box of a piece's vertices (all zero for none).
    pub(super) fn box_of(pts: &[Point]) -> [i32; 4] {
        Rect::of_points(pts).map_or([0; 4], |r| [r.min.x, r.min.y, r.max.x, r.max.y])
    }

    pub(super) fn set_bbox(&mut self, pts: &[Point]) {
        self.bbox = Self::box_of(pts);
    }

    pub(super) fn bbox(&self) -> Rect {
        Rect { min: Point::new(self.bbox[0], self.bbox[1]), max: Point::new(self.bbox[2], self.bbox[3]) }
    }
}

/// A compiled map read in place. See the module docs.
#[derive(Clone, Copy, Debug)]
pub struct MapView<'a> {
    counts: Counts,
    obstacles: &'a [ObstacleRec],
    pieces: &'a [PieceRec],
    verts: &'a [Point],
    start: &'a [u32],
    refs: &'a [u16],
    field: FieldView<'a>,
}

/// The byte sizes of the sections after the counts, from the counts.
fn section_sizes(c: &Counts) -> Option<[u64; 5]> {
    // Every count is u32: each product but the cells' fits u64 unchecked.
    let cells = (c.cols as u64).checked_mul(c.rows as u64)?;
    Some([
        8 * c.obstacles as u64,
        32 * c.pieces as u64,
        8 * c.vertices as u64,
        cells.checked_add(1)?.checked_mul(4)?,
        // Two bytes a ref, padded to 4: below 2³⁴, no overflow.
        (u64::from(c.refs) * 2 + 3) & !3,
    ])
}

/// A typed slice of `len` records at `*at`, advancing `*at`.
fn section<'a, T: Pod>(payload: &'a [u8], at: &mut usize, bytes: u64) -> Result<&'a [T], BlobError> {
    let end = at.checked_add(bytes as usize).ok_or(BlobError::Truncated)?;
    let s = payload.get(*at..end).ok_or(BlobError::Truncated)?;
    *at = end;
    bytemuck::try_cast_slice(s).map_err(|_| BlobError::Misaligned)
}

impl<'a> MapView<'a> {
    /// Validates a compiled map in place (see the module docs) and returns
    /// the view. `blob` must start on a 4-byte boundary (see [`Aligned`]).
    /// Allocation-free and panic-free; nothing is copied.
    pub fn new(blob: &'a [u8]) -> Result<Self, BlobError> {
        let payload = check_header(blob)?;
        let counts: Counts = *bytemuck::try_from_bytes(payload.get(..COUNTS_LEN).ok_or(BlobError::Truncated)?)
            .map_err(|_| BlobError::Misaligned)?;
        let sizes = section_sizes(&counts).ok_or(BlobError::SizeMismatch)?;
        let need = sizes.iter().try_fold(COUNTS_LEN as u64, |a, &s| a.checked_add(s)).ok_or(BlobError::SizeMismatch)?;
        // The field follows the refs and fills the rest of the payload.
        let total = need.saturating_add(u64::from(counts.field_len));
        if (payload.len() as u64) < total {
            return Err(BlobError::Truncated);
        }
        if (payload.len() as u64) > total {
            return Err(BlobError::TrailingBytes);
        }
        let mut at = COUNTS_LEN;
        let obstacles = section(payload, &mut at, sizes[0])?;
        let pieces = section(payload, &mut at, sizes[1])?;
        let verts = section(payload, &mut at, sizes[2])?;
        let start = section(payload, &mut at, sizes[3])?;
        let refs_end = at.checked_add(sizes[4] as usize).ok_or(BlobError::Truncated)?;
        let refs_bytes = payload.get(at..refs_end).ok_or(BlobError::Truncated)?;
        let (refs_bytes, pad) = refs_bytes.split_at((counts.refs as usize).saturating_mul(2).min(refs_bytes.len()));
        if let Some(i) = pad.iter().position(|&b| b != 0) {
            return Err(BlobError::ReservedByte {
                offset: (BLOB_HEADER_LEN + refs_end).saturating_sub(pad.len()).saturating_add(i),
            });
        }
        let refs = bytemuck::try_cast_slice(refs_bytes).map_err(|_| BlobError::Misaligned)?;
        let field = FieldView::parse(payload.get(refs_end..).ok_or(BlobError::Truncated)?)?;
        let view = Self { counts, obstacles, pieces, verts, start, refs, field };
        view.check_pieces()?;
        view.check_grid()?;
        view.check_seams()?;
        Ok(view)
    }

    /// Obstacle runs, piece ranges, outlines, buffers and boxes.
    fn check_pieces(&self) -> Result<(), BlobError> {
        let c = &self.counts;
        if c.pieces > u16::MAX as u32 || c.obstacles > c.pieces {
            return Err(BlobError::Capacity(super::Capacity::Pieces));
        }
        if c.true_vertices > c.vertices {
            return Err(BlobError::CountMismatch);
        }
        // Obstacles: known kinds, non-empty, consecutive runs covering every piece.
        let mut next = 0u32;
        for (o, r) in self.obstacles.iter().enumerate() {
            let obstacle = o as u16;
            if ObstacleKind::from_code(r.kind).is_none() {
                return Err(BlobError::UnknownKind { obstacle, code: r.kind });
            }
            if r.reserved0 != 0 || r.reserved1 != 0 {
                return Err(BlobError::ReservedByte {
                    offset: o.saturating_mul(8).saturating_add(BLOB_HEADER_LEN + COUNTS_LEN),
                });
            }
            if r.piece_count == 0 {
                return Err(BlobError::EmptyObstacle { obstacle });
            }
            if r.first_piece as u32 != next {
                return Err(BlobError::CountMismatch);
            }
            next += r.piece_count as u32;
        }
        if next != c.pieces {
            return Err(BlobError::CountMismatch);
        }
        // Pieces: true outlines packed first, buffered ones after, in order.
        let (mut true_next, mut buf_next) = (0u32, c.true_vertices);
        // Obstacles own consecutive runs of `piece_count` pieces: walk the
        // runs beside the pieces (by hand, so that no count can overflow).
        let mut runs = (0..self.obstacles.len()).zip(self.obstacles.iter().map(|r| r.piece_count));
        let mut current = None;
        for (i, r) in self.pieces.iter().enumerate() {
            let piece = i as u16;
            let owner = loop {
                match current {
                    Some((o, left)) if left > 0 => {
                        current = Some((o, left - 1));
                        break o;
                    }
                    _ => match runs.next() {
                        Some(run) => current = Some(run),
                        None => break usize::MAX,
                    },
                }
            };
            if r.obstacle as u32 >= c.obstacles {
                return Err(BlobError::ObstacleOutOfRange { piece, obstacle: r.obstacle });
            }
            if r.obstacle as usize != owner {
                return Err(BlobError::PieceOutOfOrder { piece });
            }
            if r.true_start != true_next || r.buf_start != buf_next {
                return Err(BlobError::VertexRange { piece });
            }
            true_next = true_next.checked_add(r.true_len as u32).ok_or(BlobError::VertexRange { piece })?;
            buf_next = buf_next.checked_add(r.buf_len as u32).ok_or(BlobError::VertexRange { piece })?;
            if true_next > c.true_vertices || buf_next > c.vertices {
                return Err(BlobError::VertexRange { piece });
            }
            let kind = self.obstacles.get(owner).and_then(|o| ObstacleKind::from_code(o.kind));
            self.check_piece(piece, r, kind)?;
        }
        if true_next != c.true_vertices || buf_next != c.vertices {
            return Err(BlobError::CountMismatch);
        }
        Ok(())
    }

    /// One piece: a convex counter-clockwise outline of its obstacle's kind,
    /// its buffer exactly the grown outline, its box that buffer's box.
    fn check_piece(&self, piece: u16, r: &PieceRec, kind: Option<ObstacleKind>) -> Result<(), BlobError> {
        let bad = |error| BlobError::BadPiece { piece, error };
        let range = |s: u32, n: u8| self.verts.get(s as usize..s as usize + n as usize);
        let (Some(tv), Some(bv)) = (range(r.true_start, r.true_len), range(r.buf_start, r.buf_len)) else {
            return Err(BlobError::VertexRange { piece });
        };
        if let Some(v) = tv.iter().position(|p| !p.in_range()) {
            return Err(BlobError::CoordinateOutOfRange { vertex: r.true_start.saturating_add(v as u32) });
        }
        let shape = Convex::new(tv).map_err(|error| bad(MapError::BadPiece { index: 0, error }))?;
        if (kind == Some(ObstacleKind::Wall)) != shape.is_wall() {
            return Err(bad(MapError::KindMismatch { index: 0 }));
        }
        if tv.len() > MAX_PIECE_VERTICES {
            return Err(bad(MapError::PieceTooLarge { index: 0 }));
        }
        let grown = grow(shape, self.counts.buffer_mm).map_err(|e| bad(MapError::Buffer(e)))?;
        if grown.as_slice() != bv {
            return Err(BlobError::BufferMismatch { piece });
        }
        if Rect::of_points(bv) != Some(r.bbox()) {
            return Err(BlobError::BoxMismatch { piece });
        }
        // A piece has at most 24 edges; `checked_shr` keeps a 32-bit shift total.
        if r.seams.checked_shr(shape.edge_count() as u32).unwrap_or(0) != 0 {
            return Err(BlobError::SeamMismatch { piece });
        }
        Ok(())
    }

    /// The grid: its frame from the boxes, starts in order, every ref a
    /// piece whose box covers the cell, ids strictly descending in a cell
    /// (as the builder fills them; so none twice), and as many
    /// refs as the boxes cover cells (so every covered cell holds its piece).
    fn check_grid(&self) -> Result<(), BlobError> {
        let c = &self.counts;
        let bounds = self.pieces.iter().map(PieceRec::bbox).reduce(Rect::union);
        match bounds {
            None if c.cols == 0 && c.rows == 0 && c.refs == 0 => {}
            None => return Err(BlobError::GridFrame),
            Some(b) => {
                let cell = c.cell_mm as i64;
                if cell == 0 || c.origin_x != b.min.x || c.origin_y != b.min.y {
                    return Err(BlobError::GridFrame);
                }
                let cols = (b.max.x as i64 - b.min.x as i64) / cell + 1;
                let rows = (b.max.y as i64 - b.min.y as i64) / cell + 1;
                if cols != c.cols as i64 || rows != c.rows as i64 || cols > u16::MAX as i64 || rows > u16::MAX as i64 {
                    return Err(BlobError::GridFrame);
                }
            }
        }
        let grid = self.grid();
        let cells = (c.cols as usize).checked_mul(c.rows as usize).ok_or(BlobError::SizeMismatch)?;
        if self.start.first() != Some(&0) || self.start.get(cells) != Some(&c.refs) {
            return Err(BlobError::GridStart { cell: 0 });
        }
        let mut expected = 0u64;
        for r in self.pieces {
            let (x0, y0, x1, y1) = grid.cell_range(r.bbox());
            let span = |lo: u16, hi: u16| u64::from(hi.saturating_sub(lo)) + 1;
            expected = expected.saturating_add(span(x0, x1) * span(y0, y1));
        }
        if expected != c.refs as u64 {
            return Err(BlobError::GridCoverage);
        }
        for cell in 0..cells {
            let (Some(&lo), Some(&hi)) = (self.start.get(cell), self.start.get(cell + 1)) else {
                return Err(BlobError::GridStart { cell: cell as u32 });
            };
            if lo > hi || hi > c.refs {
                return Err(BlobError::GridStart { cell: cell as u32 });
            }
            let cols = (c.cols as usize).max(1); // non-zero here (cells > 0); max keeps the division total
            let (x, y) = ((cell % cols) as u16, (cell / cols) as u16);
            let mut last: Option<u16> = None;
            for &id in self.refs.get(lo as usize..hi as usize).unwrap_or(&[]) {
                let Some(p) = self.pieces.get(id as usize) else {
                    return Err(BlobError::GridRef { cell: cell as u32, piece: id });
                };
                let (x0, y0, x1, y1) = grid.cell_range(p.bbox());
                if last.is_some_and(|l| l <= id) || x < x0 || x > x1 || y < y0 || y > y1 {
                    return Err(BlobError::GridRef { cell: cell as u32, piece: id });
                }
                last = Some(id);
            }
        }
        Ok(())
    }

    /// The stored seams against the seams found through the (checked) grid.
    fn check_seams(&self) -> Result<(), BlobError> {
        for (i, r) in self.pieces.iter().enumerate() {
            if seams_of(self, i as u16).map_err(BlobError::Finish)? != r.seams {
                return Err(BlobError::SeamMismatch { piece: i as u16 });
            }
        }
        Ok(())
    }

    fn grid(&self) -> GridRef<'a> {
        let c = &self.counts;
        GridRef {
            origin: Point::new(c.origin_x, c.origin_y),
            cell_mm: c.cell_mm,
            cols: c.cols as u16,
            rows: c.rows as u16,
            start: self.start,
            refs: self.refs,
        }
    }

    /// The grid's cell size (mm), columns and rows.
    pub fn grid_dims(&self) -> (u32, u16, u16) {
        (self.counts.cell_mm, self.counts.cols as u16, self.counts.rows as u16)
    }

    /// Number of cell→piece references in the grid.
    pub fn grid_refs(&self) -> usize {
        self.refs.len()
    }

    /// Number of true vertices (= true edges, counting a wall's two faces).
    pub fn true_vertex_count(&self) -> usize {
        self.counts.true_vertices as usize
    }

    /// Number of vertices stored, true and buffered.
    pub fn vertex_count(&self) -> usize {
        self.verts.len()
    }

    /// Bounding box of every buffered outline, or `None` for an empty map.
    pub fn bounds(&self) -> Option<Rect> {
        self.pieces.iter().map(PieceRec::bbox).reduce(Rect::union)
    }

    /// The localization field (empty when the map was compiled without one).
    pub fn field(&self) -> &FieldView<'a> {
        &self.field
    }
}

impl MapSource for MapView<'_> {
    fn buffer_mm(&self) -> u32 {
        self.counts.buffer_mm
    }

    fn obstacle_count(&self) -> usize {
        self.obstacles.len()
    }

    fn obstacle(&self, id: u16) -> Option<Obstacle> {
        let r = self.obstacles.get(id as usize)?;
        Some(Obstacle {
            kind: ObstacleKind::from_code(r.kind)?,
            first_piece: r.first_piece,
            piece_count: r.piece_count,
        })
    }

    fn piece_count(&self) -> usize {
        self.pieces.len()
    }

    #[inline]
    fn piece(&self, id: u16) -> Option<Piece<'_>> {
        let r = self.pieces.get(id as usize)?;
        let tv = self.verts.get(r.true_start as usize..(r.true_start as usize).checked_add(r.true_len as usize)?)?;
        let bv = self.verts.get(r.buf_start as usize..(r.buf_start as usize).checked_add(r.buf_len as usize)?)?;
        Some(Piece {
            id,
            obstacle: r.obstacle,
            shape: Convex::new_unchecked(tv),
            buffered: Convex::new_unchecked(bv),
            bbox: r.bbox(),
            internal: r.seams,
        })
    }

    fn for_each_candidate_box(&self, area: Rect, f: impl FnMut(u16, Rect)) -> Result<QueryStats, MapError> {
        let pieces = self.pieces;
        Ok(self.grid().query(
            area,
            |id| pieces.get(id as usize).map_or(Rect::around(Point::new(0, 0)), PieceRec::bbox),
            f,
        ))
    }
}

/// The header's checks (after the alignment); the payload on success.
fn check_header(blob: &[u8]) -> Result<&[u8], BlobError> {
    if blob.as_ptr() as usize % 4 != 0 {
        return Err(BlobError::Misaligned);
    }
    match super::header::check_header(blob, COMPILED_VERSION) {
        Err(BlobError::UnsupportedVersion(OUTDATED_VERSION)) => {
            Err(BlobError::Outdated { version: OUTDATED_VERSION, current: COMPILED_VERSION })
        }
        r => r,
    }
}

impl<const PIECES: usize, const VERTS: usize, const CELLS: usize, const REFS: usize> Map<PIECES, VERTS, CELLS, REFS> {
    /// The compiled blob's length for this map, without a field.
    pub fn compiled_len(&self) -> usize {
        self.compiled_len_with(&FieldParts::NONE)
    }

    /// The compiled blob's length for this map with `field`.
    pub fn compiled_len_with(&self, field: &FieldParts<'_>) -> usize {
        let (_, cols, rows) = self.grid.dims();
        BLOB_HEADER_LEN
            + COUNTS_LEN
            + 8 * self.obstacles.len()
            + 32 * self.pieces.len()
            + 8 * self.verts.len()
            + 4 * (cols as usize * rows as usize + 1)
            + (2 * self.grid.refs_len()).next_multiple_of(4)
            + field.len()
    }

    /// Writes the finished map in its compiled form (version 3) without a
    /// localization field into `out`, returning the bytes written.
    pub fn compile(&self, out: &mut [u8]) -> Result<usize, super::EncodeError> {
        self.compile_with_field(&FieldParts::NONE, out)
    }

    /// Writes the finished map in its compiled form (version 3) with the
    /// localization field `field` (made on the host: `echoloc-lab map
    /// import`) into `out`, returning the bytes written. The field is
    /// written as given: a view of the blob checks it.
    pub fn compile_with_field(&self, field: &FieldParts<'_>, out: &mut [u8]) -> Result<usize, super::EncodeError> {
        if !self.finished {
            return Err(super::EncodeError::NotFinished);
        }
        let need = self.compiled_len_with(field);
        let out = out.get_mut(..need).ok_or(super::EncodeError::BufferTooSmall { need })?;
        out.fill(0);
        let g = self.grid.index();
        let counts = Counts {
            buffer_mm: self.buffer_mm,
            cell_mm: g.cell_mm,
            obstacles: self.obstacles.len() as u32,
            pieces: self.pieces.len() as u32,
            true_vertices: self.true_verts as u32,
            vertices: self.verts.len() as u32,
            origin_x: g.origin.x,
            origin_y: g.origin.y,
            cols: g.cols as u32,
            rows: g.rows as u32,
            refs: g.refs.len() as u32,
            field_len: field.len() as u32,
        };
        let mut pos = BLOB_HEADER_LEN;
        let mut put = |bytes: &[u8]| {
            if let Some(d) = out.get_mut(pos..pos + bytes.len()) {
                d.copy_from_slice(bytes);
            }
            pos += bytes.len();
        };
        put(bytemuck::bytes_of(&counts));
        for o in &self.obstacles {
            let r = ObstacleRec {
                kind: o.kind as u8,
                reserved0: 0,
                piece_count: o.piece_count,
                first_piece: o.first_piece,
                reserved1: 0,
            };
            put(bytemuck::bytes_of(&r));
        }
        for p in &self.pieces {
            put(bytemuck::bytes_of(p));
        }
        for v in &self.verts {
            put(bytemuck::bytes_of(v));
        }
        for s in g.start {
            put(&s.to_le_bytes());
        }
        put(&counts.refs.to_le_bytes());
        for r in g.refs {
            put(&r.to_le_bytes());
        }
        if g.refs.len() % 2 == 1 {
            put(&[0, 0]);
        }
        field.write(&mut put);
        let crc = super::crc32(out.get(BLOB_HEADER_LEN..).unwrap_or(&[]));
        super::header::write_header(out, COMPILED_VERSION, need - BLOB_HEADER_LEN, crc);
        Ok(need)
    }

    /// Replaces this map with the compiled map `view`: its true outlines,
    /// finished with its buffer and cell size. (The view was checked, so the
    /// rebuilt buffers, grid and seams are the stored ones.)
    pub(super) fn load_view(&mut self, view: &MapView<'_>) -> Result<(), BlobError> {
        for o in 0..view.obstacle_count() as u16 {
            let Some(ob) = view.obstacle(o) else { return Err(BlobError::CountMismatch) };
            for k in 0..ob.piece_count {
                let id = ob.first_piece + k;
                let Some(p) = view.piece(id) else { return Err(BlobError::CountMismatch) };
                self.push_piece(ob.kind, k == 0, p.shape.vertices()).map_err(|e| match e {
                    MapError::Full(c) => BlobError::Capacity(c),
                    error => BlobError::BadPiece { piece: id, error },
                })?;
            }
        }
        self.finish(view.counts.buffer_mm, view.counts.cell_mm.max(1)).map_err(|e| match e {
            MapError::Full(c) => BlobError::Capacity(c),
            e => BlobError::Finish(e),
        })
    }
}
