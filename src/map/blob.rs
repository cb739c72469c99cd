//! The versioned binary map blob that the host writes and the firmware loads.
//!
//! Little-endian, fixed layout (see `docs/map-blob.md`):
//!
//! ```text
//! header (16 bytes)
//!   0  magic        4  b"ECHM"
//!   4  version      2  1
//!   6  flags        2  0 (reserved)
//!   8  payload_len  4  bytes after the header
//!  12  crc32        4  CRC-32 of the payload
//! payload
//!      buffer_mm u32, cell_mm u32, obstacles u16, pieces u16, vertices u32
//!      obstacles × { kind u8, reserved u8 = 0, piece_count u16 }
//!      pieces    × { obstacle u16, vertex_count u8, reserved u8 = 0 }
//!      vertices  × { x i32, y i32 }            (true outlines only)
//! ```
//!
//! This is version 1, which [`Map::load`] still reads; `echoloc-lab map
//! import` writes version 3, the compiled map (`compiled.rs`), which
//! [`Map::load`] reads too and the firmware reads in place. The header and
//! [`BlobError`] are both versions' (`header.rs`).
//!
//! Only true outlines travel: the loader re-validates every piece and grows
//! the buffers and the grid itself, so a blob cannot carry a buffer or index
//! that disagrees with its geometry. Decoding never allocates and never
//! panics; every malformed blob gives a [`BlobError`] and leaves the map
//! empty.

use super::header::{check_header, write_header, BlobError, BLOB_HEADER_LEN};
use super::{Capacity, Map, MapError, ObstacleKind};
use crate::geometry::{Point, MAX_PIECE_VERTICES};

/// The only version this build reads and writes.
pub const BLOB_VERSION: u16 = 1;
const COUNTS_LEN: usize = 16;

/// Why a map could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output buffer is too small.
    BufferTooSmall {
        /// Bytes needed.
        need: usize,
    },
    /// The map is not finished: its buffer and cell size are not fixed yet.
    NotFinished,
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take<const K: usize>(&mut self) -> Result<[u8; K], BlobError> {
        let end = self.pos.checked_add(K).ok_or(BlobError::Truncated)?;
        let s = self.data.get(self.pos..end).ok_or(BlobError::Truncated)?;
        self.pos = end;
        let mut out = [0u8; K];
        out.copy_from_slice(s);
        Ok(out)
    }
    fn u8(&mut self) -> Result<u8, BlobError> {
        Ok(self.take::<1>()?[0])
    }
    fn u16(&mut self) -> Result<u16, BlobError> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    fn u32(&mut self) -> Result<u32, BlobError> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    fn i32(&mut self) -> Result<i32, BlobError> {
        Ok(i32::from_le_bytes(self.take()?))
    }
    fn reserved(&mut self) -> Result<(), BlobError> {
        let offset = self.pos;
        if self.u8()? != 0 {
            return Err(BlobError::ReservedByte { offset });
        }
        Ok(())
    }
}

impl<const PIECES: usize, const VERTS: usize, const CELLS: usize, const REFS: usize> Map<PIECES, VERTS, CELLS, REFS> {
    /// The blob's length for this map.
    pub fn encoded_len(&self) -> usize {
        BLOB_HEADER_LEN + COUNTS_LEN + 4 * self.obstacles.len() + 4 * self.pieces.len() + 8 * self.true_verts
    }

    /// Writes the map as a blob into `out`, returning the bytes written. The
    /// map must have been finished (its `buffer_mm` and cell size travel).
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, EncodeError> {
        if !self.finished {
            return Err(EncodeError::NotFinished);
        }
        let need = self.encoded_len();
        let out = out.get_mut(..need).ok_or(EncodeError::BufferTooSmall { need })?;
        let mut pos = BLOB_HEADER_LEN;
        let mut put = |bytes: &[u8]| {
            out[pos..pos + bytes.len()].copy_from_slice(bytes);
            pos += bytes.len();
        };
        put(&self.buffer_mm.to_le_bytes());
        put(&self.grid.dims().0.to_le_bytes());
        put(&(self.obstacles.len() as u16).to_le_bytes());
        put(&(self.pieces.len() as u16).to_le_bytes());
        put(&(self.true_verts as u32).to_le_bytes());
        for o in &self.obstacles {
            put(&[o.kind as u8, 0]);
            put(&o.piece_count.to_le_bytes());
        }
        for p in &self.pieces {
            put(&p.obstacle.to_le_bytes());
            put(&[p.true_len, 0]);
        }
        for v in &self.verts[..self.true_verts] {
            put(&v.x.to_le_bytes());
            put(&v.y.to_le_bytes());
        }
        let crc = super::crc32(&out[BLOB_HEADER_LEN..]);
        write_header(out, BLOB_VERSION, need - BLOB_HEADER_LEN, crc);
        Ok(need)
    }

    /// Replaces this map with the one in `blob`, validated and finished. On
    /// error the map is left empty. Allocation-free and panic-free; works in
    /// place, so a large map in a `static` needs no stack copy.
    pub fn load(&mut self, blob: &[u8]) -> Result<(), BlobError> {
        self.clear();
        let r = self.load_inner(blob);
        if r.is_err() {
            self.clear();
        }
        r
    }

    fn load_inner(&mut self, blob: &[u8]) -> Result<(), BlobError> {
        let compiled = [super::COMPILED_VERSION, super::compiled::OUTDATED_VERSION].map(u16::to_le_bytes);
        if blob.len() >= 6 && compiled.iter().any(|v| blob[4..6] == *v) {
            let view = super::MapView::new(blob)?;
            return self.load_view(&view);
        }
        let payload = check_header(blob, BLOB_VERSION)?;
        // Counts, then every section's size checked before reading it.
        let mut r = Reader { data: blob, pos: BLOB_HEADER_LEN };
        let buffer_mm = r.u32()?;
        let cell_mm = r.u32()?;
        let n_obst = r.u16()? as usize;
        let n_pieces = r.u16()? as usize;
        let n_verts = r.u32()? as usize;
        let need = COUNTS_LEN as u64 + 4 * n_obst as u64 + 4 * n_pieces as u64 + 8 * n_verts as u64;
        if (payload.len() as u64) < need {
            return Err(BlobError::Truncated);
        }
        if payload.len() as u64 > need {
            return Err(BlobError::TrailingBytes);
        }
        if n_obst > PIECES || n_pieces > PIECES {
            return Err(BlobError::Capacity(Capacity::Pieces));
        }
        if n_verts > VERTS {
            return Err(BlobError::Capacity(Capacity::Vertices));
        }
        let obst_at = r.pos;
        let piece_at = obst_at + 4 * n_obst;
        let vert_at = piece_at + 4 * n_pieces;
        // Obstacles: kinds and piece counts must add up.
        let mut sum_pieces = 0usize;
        for o in 0..n_obst {
            let code = r.u8()?;
            r.reserved()?;
            let count = r.u16()? as usize;
            if ObstacleKind::from_code(code).is_none() {
                return Err(BlobError::UnknownKind { obstacle: o as u16, code });
            }
            if count == 0 {
                // Anywhere in the table, even last where no piece would reach it.
                return Err(BlobError::EmptyObstacle { obstacle: o as u16 });
            }
            sum_pieces += count;
        }
        if sum_pieces != n_pieces {
            return Err(BlobError::CountMismatch);
        }
        // Pieces, in obstacle runs: ids in range and in order, each piece
        // validated by the map itself (convexity, kind, size) as it is added.
        let mut or = Reader { data: blob, pos: obst_at };
        let mut pr = Reader { data: blob, pos: piece_at };
        let mut vr = Reader { data: blob, pos: vert_at };
        let (mut cur, mut kind, mut left) = (0u16, ObstacleKind::Solid, 0usize);
        let mut started = false;
        let mut vertex_id = 0u32;
        for piece in 0..n_pieces as u16 {
            let first_of_run = left == 0;
            while left == 0 {
                if started {
                    cur += 1;
                }
                started = true;
                kind = ObstacleKind::from_code(or.u8()?).ok_or(BlobError::Truncated)?;
                or.reserved()?;
                left = or.u16()? as usize;
                if left == 0 {
                    return Err(BlobError::BadPiece { piece, error: MapError::EmptyObstacle });
                }
            }
            let obstacle = pr.u16()?;
            let nv = pr.u8()? as usize;
            pr.reserved()?;
            if obstacle as usize >= n_obst {
                return Err(BlobError::ObstacleOutOfRange { piece, obstacle });
            }
            if obstacle != cur {
                return Err(BlobError::PieceOutOfOrder { piece });
            }
            left -= 1;
            if nv > MAX_PIECE_VERTICES {
                return Err(BlobError::BadPiece { piece, error: MapError::PieceTooLarge { index: 0 } });
            }
            let mut buf = [Point::new(0, 0); MAX_PIECE_VERTICES];
            for slot in buf.iter_mut().take(nv) {
                let p = Point::new(vr.i32()?, vr.i32()?);
                if !p.in_range() {
                    return Err(BlobError::CoordinateOutOfRange { vertex: vertex_id });
                }
                *slot = p;
                vertex_id += 1;
            }
            self.push_piece(kind, first_of_run, &buf[..nv]).map_err(|e| match e {
                MapError::Full(c) => BlobError::Capacity(c),
                MapError::BadPiece { error, .. } => {
                    BlobError::BadPiece { piece, error: MapError::BadPiece { index: 0, error } }
                }
                error => BlobError::BadPiece { piece, error },
            })?;
        }
        if vertex_id as usize != n_verts {
            return Err(BlobError::CountMismatch);
        }
        self.finish(buffer_mm, cell_mm).map_err(|e| match e {
            MapError::Full(c) => BlobError::Capacity(c),
            e => BlobError::Finish(e),
        })
    }
}
