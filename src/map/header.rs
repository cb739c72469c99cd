//! The 16-byte header every map blob starts with (magic, version, flags,
//! payload length, CRC-32 of the payload; `docs/map-blob.md`), and why a
//! blob is refused: shared by the outlines-only blob ([`super::blob`]) and
//! the compiled map ([`super::compiled`]), so neither reads the other's.

use super::{Capacity, MapError};

/// The blob's first four bytes.
pub const BLOB_MAGIC: [u8; 4] = *b"ECHM";
/// Header length in bytes.
pub const BLOB_HEADER_LEN: usize = 16;

/// Why a blob was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BlobError {
    /// Shorter than the header.
    TooShort {
        /// Bytes given.
        len: usize,
    },
    /// The first four bytes are not [`BLOB_MAGIC`].
    BadMagic,
    /// A version this build does not read.
    UnsupportedVersion(u16),
    /// Reserved flag bits set.
    ReservedFlags(u16),
    /// The header's payload length disagrees with the bytes given.
    LengthMismatch {
        /// Payload length in the header.
        header: u32,
        /// Payload bytes present.
        actual: usize,
    },
    /// The payload's CRC-32 does not match the header's.
    BadCrc {
        /// CRC in the header.
        stored: u32,
        /// CRC of the payload.
        computed: u32,
    },
    /// The counts promise more data than the payload holds.
    Truncated,
    /// Bytes left over after the last vertex.
    TrailingBytes,
    /// A reserved byte is not zero.
    ReservedByte {
        /// Offset in the blob.
        offset: usize,
    },
    /// An obstacle kind code this build does not know.
    UnknownKind {
        /// Obstacle index.
        obstacle: u16,
        /// The code found.
        code: u8,
    },
    /// An obstacle with no pieces: nothing to detect, and a shifted table.
    EmptyObstacle {
        /// Obstacle index.
        obstacle: u16,
    },
    /// A piece names an obstacle that does not exist.
    ObstacleOutOfRange {
        /// Piece index.
        piece: u16,
        /// The obstacle id found.
        obstacle: u16,
    },
    /// A piece names an existing obstacle other than the one whose run it is in.
    PieceOutOfOrder {
        /// Piece index.
        piece: u16,
    },
    /// The obstacles' piece counts do not add up to the piece count, or the
    /// pieces' vertex counts to the vertex count.
    CountMismatch,
    /// A coordinate beyond `±COORD_MAX`.
    CoordinateOutOfRange {
        /// Vertex index.
        vertex: u32,
    },
    /// A piece that is not a valid convex outline for its obstacle's kind.
    BadPiece {
        /// Piece index.
        piece: u16,
        /// Why.
        error: MapError,
    },
    /// The map does not fit this build's fixed capacities.
    Capacity(Capacity),
    /// Building buffers or the grid failed (for example a buffer too large).
    Finish(MapError),
    /// A compiled map that does not start on a 4-byte boundary (see
    /// [`Aligned`](super::Aligned)).
    Misaligned,
    /// A compiled map's counts whose sections' sizes overflow.
    SizeMismatch,
    /// A compiled piece whose vertex range is out of bounds or out of order.
    VertexRange {
        /// Piece index.
        piece: u16,
    },
    /// A compiled piece whose buffered outline is not its true outline grown
    /// by the map's buffer.
    BufferMismatch {
        /// Piece index.
        piece: u16,
    },
    /// A compiled piece whose box is not its buffered outline's box.
    BoxMismatch {
        /// Piece index.
        piece: u16,
    },
    /// A compiled piece whose seams disagree with its neighbours.
    SeamMismatch {
        /// Piece index.
        piece: u16,
    },
    /// A compiled grid whose origin, cell size or dimensions disagree with
    /// the pieces' boxes.
    GridFrame,
    /// A compiled grid whose cell starts are out of order or past the refs.
    GridStart {
        /// Cell index.
        cell: u32,
    },
    /// A compiled grid reference to a piece that does not exist, whose box
    /// does not cover the cell, or out of descending order in its cell.
    GridRef {
        /// Cell index.
        cell: u32,
        /// The piece id found.
        piece: u16,
    },
    /// A compiled grid with more or fewer references than the boxes cover.
    GridCoverage,
    /// A compiled map of an older version, without what this build needs
    /// (version 2 has no localization field): compile the map again with
    /// `echoloc-lab map import`.
    Outdated {
        /// The version found.
        version: u16,
        /// The version this build reads.
        current: u16,
    },
    /// The compiled map's localization field does not validate.
    Field(super::field::FieldError),
}

/// The header's checks, shared by both versions (length, magic, `version`,
/// reserved flags, payload length, CRC); the payload on success.
pub(super) fn check_header(blob: &[u8], version: u16) -> Result<&[u8], BlobError> {
    let Some(h) = blob.get(..BLOB_HEADER_LEN).and_then(|h| <&[u8; BLOB_HEADER_LEN]>::try_from(h).ok()) else {
        return Err(BlobError::TooShort { len: blob.len() });
    };
    if [h[0], h[1], h[2], h[3]] != BLOB_MAGIC {
        return Err(BlobError::BadMagic);
    }
    let found = u16::from_le_bytes([h[4], h[5]]);
    if found != version {
        return Err(BlobError::UnsupportedVersion(found));
    }
    let flags = u16::from_le_bytes([h[6], h[7]]);
    if flags != 0 {
        return Err(BlobError::ReservedFlags(flags));
    }
    let payload_len = u32::from_le_bytes([h[8], h[9], h[10], h[11]]);
    let stored = u32::from_le_bytes([h[12], h[13], h[14], h[15]]);
    let payload = blob.get(BLOB_HEADER_LEN..).unwrap_or(&[]);
    if payload_len as usize != payload.len() {
        return Err(BlobError::LengthMismatch { header: payload_len, actual: payload.len() });
    }
    let computed = super::crc32(payload);
    if computed != stored {
        return Err(BlobError::BadCrc { stored, computed });
    }
    Ok(payload)
}

/// Writes the header for `payload_len` bytes of payload with CRC `crc`.
pub(super) fn write_header(out: &mut [u8], version: u16, payload_len: usize, crc: u32) {
    if let Some(h) = out.get_mut(..BLOB_HEADER_LEN) {
        h[0..4].copy_from_slice(&BLOB_MAGIC);
        h[4..6].copy_from_slice(&version.to_le_bytes());
        h[6..8].copy_from_slice(&0u16.to_le_bytes());
        h[8..12].copy_from_slice(&(payload_len as u32).to_le_bytes());
        h[12..16].copy_from_slice(&crc.to_le_bytes());
    }
}
