//! The map blob: round trips, and every kind of corruption maps to its typed
//! error, leaves the map empty, and never panics.

use echoloc::geometry::{ConvexError, Point, COORD_MAX};
use echoloc::map::{crc32, BlobError, Capacity, Map, MapError, ObstacleKind, StandardMap, BLOB_HEADER_LEN};
use proptest::prelude::*;

type M = StandardMap;

fn p(x: i32, y: i32) -> Point {
    Point::new(x, y)
}

/// Two solids (one of two pieces) and a wall; t_b 100 mm, 1 m cells.
fn sample_map() -> Box<M> {
    let mut m: Box<M> = Box::default();
    let sq = [p(0, 0), p(1000, 0), p(1000, 1000), p(0, 1000)];
    let tri = [p(1000, 0), p(2000, 0), p(1000, 1000)];
    m.add_obstacle(ObstacleKind::Solid, &[&sq, &tri]).unwrap();
    m.add_obstacle(ObstacleKind::Wall, &[&[p(3000, 0), p(3000, 2000)], &[p(3000, 2000), p(5000, 2000)]]).unwrap();
    let hex = [p(500, 3000), p(900, 3000), p(1100, 3400), p(900, 3800), p(500, 3800), p(300, 3400)];
    m.add_obstacle(ObstacleKind::Solid, &[&hex]).unwrap();
    m.finish(100, 1000).unwrap();
    m
}

fn blob() -> Vec<u8> {
    let m = sample_map();
    let mut b = vec![0u8; m.encoded_len()];
    let n = m.encode(&mut b).unwrap();
    assert_eq!(n, b.len());
    b
}

/// Rewrites the header's payload length and CRC after a payload edit, so
/// that the edit reaches the payload checks.
fn reseal(b: &mut [u8]) {
    let len = (b.len() - BLOB_HEADER_LEN) as u32;
    b[8..12].copy_from_slice(&len.to_le_bytes());
    let crc = crc32(&b[BLOB_HEADER_LEN..]);
    b[12..16].copy_from_slice(&crc.to_le_bytes());
}

// Offsets in the sample blob's payload (see src/map/blob.rs).
const COUNTS: usize = BLOB_HEADER_LEN;
const OBST: usize = COUNTS + 16;
const PIECES: usize = OBST + 3 * 4;
const VERTS: usize = PIECES + 5 * 4;

fn load(b: &[u8]) -> Result<(), BlobError> {
    let mut m: Box<M> = Box::default();
    // Start from a loaded map: an error must leave it empty, not half-old.
    m.load(&blob()).unwrap();
    let r = m.load(b);
    if r.is_err() {
        assert_eq!(m.piece_count(), 0, "a refused blob leaves the map empty");
        assert_eq!(m.obstacles().len(), 0);
        assert!(!m.is_finished());
    }
    r
}

#[test]
fn round_trip_is_byte_exact_and_equal() {
    let b = blob();
    let mut m: Box<M> = Box::default();
    m.load(&b).unwrap();
    let orig = sample_map();
    assert_eq!(m.piece_count(), orig.piece_count());
    assert_eq!(m.obstacles(), orig.obstacles());
    assert_eq!(m.grid_dims(), orig.grid_dims());
    assert_eq!(m.vertex_count(), orig.vertex_count());
    for (a, b) in m.pieces().zip(orig.pieces()) {
        assert_eq!(a.shape.vertices(), b.shape.vertices());
        assert_eq!(a.buffered.vertices(), b.buffered.vertices());
    }
    let mut again = vec![0u8; m.encoded_len()];
    m.encode(&mut again).unwrap();
    assert_eq!(again, b);
    // The CRC is the standard CRC-32 (checked against crc32fast).
    assert_eq!(crc32(&b[16..]), crc32fast::hash(&b[16..]));
}

#[test]
fn empty_map_round_trips() {
    let mut m: Box<M> = Box::default();
    m.finish(100, 500).unwrap();
    let mut b = vec![0u8; m.encoded_len()];
    m.encode(&mut b).unwrap();
    let mut n: Box<M> = Box::default();
    n.load(&b).unwrap();
    assert_eq!(n.piece_count(), 0);
    assert!(n.is_finished());
}

#[test]
fn an_unfinished_map_is_not_encoded() {
    let mut m: Box<M> = Box::default();
    let sq = [p(0, 0), p(10, 0), p(10, 10), p(0, 10)];
    m.add_obstacle(ObstacleKind::Solid, &[&sq]).unwrap();
    let mut b = vec![0u8; m.encoded_len()];
    assert_eq!(m.encode(&mut b), Err(echoloc::map::EncodeError::NotFinished));
}

#[test]
fn a_failed_push_leaves_a_finished_map_finished() {
    let mut m: Map<8, 16, 16, 64> = Map::new();
    let sq = [p(0, 0), p(10, 0), p(10, 10), p(0, 10)];
    m.add_obstacle(ObstacleKind::Solid, &[&sq]).unwrap();
    m.finish(0, 100).unwrap();
    let big: Vec<Point> = (0..13).map(|k| p(k * 10, k * k)).collect();
    assert!(m.push_piece(ObstacleKind::Solid, true, &big).is_err());
    assert!(m.is_finished(), "a refused push changes nothing");
}

#[test]
fn encode_into_a_short_buffer_is_refused() {
    let m = sample_map();
    let mut b = vec![0u8; m.encoded_len() - 1];
    assert_eq!(m.encode(&mut b), Err(echoloc::map::EncodeError::BufferTooSmall { need: m.encoded_len() }));
}

/// Each corruption and the exact error it must give.
#[test]
fn malformed_blob_table() {
    type Edit = fn(&mut Vec<u8>);
    let good = blob();
    let table: Vec<(&str, Edit, BlobError)> = vec![
        ("empty", |b| b.clear(), BlobError::TooShort { len: 0 }),
        ("header cut", |b| b.truncate(10), BlobError::TooShort { len: 10 }),
        ("bad magic", |b| b[0] = b'X', BlobError::BadMagic),
        ("version 4", |b| b[4] = 4, BlobError::UnsupportedVersion(4)),
        ("flags set", |b| b[6] = 1, BlobError::ReservedFlags(1)),
        ("payload cut", |b| b.truncate(b.len() - 3), BlobError::LengthMismatch { header: 0, actual: 0 }),
        ("extra byte", |b| b.push(0), BlobError::LengthMismatch { header: 0, actual: 0 }),
        ("bit flip", |b| b[VERTS + 5] ^= 0x10, BlobError::BadCrc { stored: 0, computed: 0 }),
        ("crc flip", |b| b[13] ^= 1, BlobError::BadCrc { stored: 0, computed: 0 }),
        (
            "payload cut, resealed",
            |b| {
                b.truncate(b.len() - 8);
                reseal(b)
            },
            BlobError::Truncated,
        ),
        (
            "trailing bytes, resealed",
            |b| {
                b.extend([0; 4]);
                reseal(b)
            },
            BlobError::TrailingBytes,
        ),
        (
            "unknown kind",
            |b| {
                b[OBST + 4] = 7;
                reseal(b)
            },
            BlobError::UnknownKind { obstacle: 1, code: 7 },
        ),
        (
            "reserved byte",
            |b| {
                b[OBST + 1] = 1;
                reseal(b)
            },
            BlobError::ReservedByte { offset: OBST + 1 },
        ),
        (
            "an empty obstacle at the end of the table",
            |b| {
                // One more obstacle (a wall with 0 pieces) after the three.
                b.splice(PIECES..PIECES, [1u8, 0, 0, 0]);
                b[COUNTS + 8] = 4;
                reseal(b)
            },
            BlobError::EmptyObstacle { obstacle: 3 },
        ),
        (
            "an empty obstacle in the middle, counts still adding up",
            |b| {
                // Obstacle 2 (the hexagon) empty, obstacle 1 (the wall) claiming its piece.
                b[OBST + 4 + 2] = 3;
                b[OBST + 4 * 2 + 2] = 0;
                reseal(b)
            },
            BlobError::EmptyObstacle { obstacle: 2 },
        ),
        (
            "obstacle id out of range",
            |b| {
                b[PIECES + 4 * 4] = 9;
                reseal(b)
            },
            BlobError::ObstacleOutOfRange { piece: 4, obstacle: 9 },
        ),
        (
            "piece out of order",
            |b| {
                b[PIECES + 4] = 1;
                reseal(b)
            },
            BlobError::PieceOutOfOrder { piece: 1 },
        ),
        (
            "piece counts do not add up",
            |b| {
                b[OBST + 2] = 3;
                reseal(b)
            },
            BlobError::CountMismatch,
        ),
        (
            "coordinate out of range",
            |b| {
                let off = VERTS + 8 * 2;
                b[off..off + 4].copy_from_slice(&(COORD_MAX + 1).to_le_bytes());
                reseal(b)
            },
            BlobError::CoordinateOutOfRange { vertex: 2 },
        ),
        (
            "non-convex piece (reflex vertex)",
            |b| {
                // Pull the square's third vertex (1000,1000) inside to (400,400).
                let off = VERTS + 8 * 2;
                b[off..off + 4].copy_from_slice(&400i32.to_le_bytes());
                b[off + 4..off + 8].copy_from_slice(&400i32.to_le_bytes());
                reseal(b)
            },
            BlobError::BadPiece {
                piece: 0,
                error: MapError::BadPiece { index: 0, error: ConvexError::NotStrictlyConvex },
            },
        ),
        (
            "clockwise piece",
            |b| {
                // Swap the triangle's 2nd and 3rd vertices.
                let t = VERTS + 8 * 4;
                let (v1, v2) = (b[t + 8..t + 16].to_vec(), b[t + 16..t + 24].to_vec());
                b[t + 8..t + 16].copy_from_slice(&v2);
                b[t + 16..t + 24].copy_from_slice(&v1);
                reseal(b)
            },
            BlobError::BadPiece {
                piece: 1,
                error: MapError::BadPiece { index: 0, error: ConvexError::NotStrictlyConvex },
            },
        ),
        (
            "wall of zero length",
            |b| {
                // Wall piece 2 is (3000,0)-(3000,2000): make both ends equal.
                let w = VERTS + 8 * 7;
                let a = b[w..w + 8].to_vec();
                b[w + 8..w + 16].copy_from_slice(&a);
                reseal(b)
            },
            BlobError::BadPiece {
                piece: 2,
                error: MapError::BadPiece { index: 0, error: ConvexError::DuplicateVertex },
            },
        ),
        (
            "solid given as a wall",
            |b| {
                b[OBST] = 1;
                reseal(b)
            },
            BlobError::BadPiece { piece: 0, error: MapError::KindMismatch { index: 0 } },
        ),
        (
            "buffer too large",
            |b| {
                b[COUNTS..COUNTS + 4].copy_from_slice(&1_000_000u32.to_le_bytes());
                reseal(b)
            },
            BlobError::Finish(MapError::Buffer(echoloc::buffer::BufferError::BufferTooLarge)),
        ),
        (
            "cell size zero",
            |b| {
                b[COUNTS + 4..COUNTS + 8].copy_from_slice(&0u32.to_le_bytes());
                reseal(b)
            },
            BlobError::Finish(MapError::ZeroCell),
        ),
        (
            "grid too fine for the capacity",
            |b| {
                b[COUNTS + 4..COUNTS + 8].copy_from_slice(&1u32.to_le_bytes());
                reseal(b)
            },
            BlobError::Capacity(Capacity::Cells),
        ),
        (
            "vertex count larger than the payload",
            |b| {
                b[COUNTS + 12..COUNTS + 16].copy_from_slice(&1_000_000u32.to_le_bytes());
                reseal(b)
            },
            BlobError::Truncated,
        ),
    ];
    for (name, edit, want) in table {
        let mut b = good.clone();
        edit(&mut b);
        let got = load(&b).expect_err(name);
        // Variants whose numbers depend on the blob are compared by kind.
        let same = match (&got, &want) {
            (BlobError::LengthMismatch { .. }, BlobError::LengthMismatch { .. }) => true,
            (BlobError::BadCrc { stored, computed }, BlobError::BadCrc { .. }) => stored != computed,
            _ => got == want,
        };
        assert!(same, "{name}: got {got:?}, want {want:?}");
    }
}

#[test]
fn a_map_larger_than_the_build_is_refused_with_capacity() {
    let b = blob();
    let mut small: Map<2, 64, 64, 64> = Map::new();
    assert_eq!(small.load(&b), Err(BlobError::Capacity(Capacity::Pieces)));
    let mut few_verts: Map<16, 40, 64, 256> = Map::new();
    assert_eq!(few_verts.load(&b), Err(BlobError::Capacity(Capacity::Vertices)));
    let mut few_refs: Map<16, 1024, 256, 4> = Map::new();
    assert_eq!(few_refs.load(&b), Err(BlobError::Capacity(Capacity::CellRefs)));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    /// Random damage never panics; if the CRC still matches (resealed), the
    /// loader either accepts a valid map or names what is wrong.
    #[test]
    fn random_damage_never_panics(edits in prop::collection::vec((0usize..400, any::<u8>()), 1..6), cut in 0usize..400, seal in any::<bool>()) {
        let mut b = blob();
        for (at, v) in edits {
            let n = b.len();
            b[at % n] = v;
        }
        if cut % 5 == 0 {
            b.truncate(cut % (b.len() + 1));
        }
        if seal && b.len() >= BLOB_HEADER_LEN {
            reseal(&mut b);
        }
        let mut m: Box<M> = Box::default();
        match m.load(&b) {
            Ok(()) => prop_assert!(m.is_finished()),
            Err(_) => prop_assert_eq!(m.piece_count(), 0),
        }
    }
}
