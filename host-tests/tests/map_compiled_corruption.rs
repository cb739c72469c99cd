//! The compiled map (blob version 2, `src/map/compiled.rs`) refuses every way
//! a blob can lie, each with its typed error, and never reads out of bounds:
//! a table of targeted corruptions (the CRC recomputed after each, so that
//! the check it aims at is the one that answers), every single byte of the
//! payload flipped in turn, and a round trip through `Map::load`.

use echoloc::geometry::{Convex, ConvexError, Point, Segment};
use echoloc::map::{crc32, BlobError, Map, MapError, MapSource, MapView, ObstacleKind, BLOB_HEADER_LEN};

type Small = Map<16, 256, 64, 256>;

const H: usize = BLOB_HEADER_LEN; // the counts start here
const OBST: usize = H + 48; // obstacle records, 8 bytes each

const fn p(x: i32, y: i32) -> Point {
    Point::new(x, y)
}

/// An L-shaped solid of two pieces (a seam between them), a square, and a
/// wall of two segments.
fn map() -> Small {
    let mut m = Small::new();
    let a: &[Point] = &[p(0, 0), p(2000, 0), p(2000, 1000), p(0, 1000)];
    let b: &[Point] = &[p(0, 1000), p(1000, 1000), p(1000, 3000), p(0, 3000)];
    m.add_obstacle(ObstacleKind::Solid, &[a, b]).unwrap();
    let sq: &[Point] = &[p(5000, 5000), p(6000, 5000), p(6000, 6000), p(5000, 6000)];
    m.add_obstacle(ObstacleKind::Solid, &[sq]).unwrap();
    let w1: &[Point] = &[p(3000, 0), p(3000, 4000)];
    let w2: &[Point] = &[p(3000, 4000), p(4500, 4000)];
    m.add_obstacle(ObstacleKind::Wall, &[w1, w2]).unwrap();
    m.finish(100, 1000).unwrap();
    m
}

/// Bytes on an 8-byte boundary, with room to shift them by one.
struct Buf(Vec<u64>);

impl Buf {
    fn of(bytes: &[u8], offset: usize) -> (Self, usize) {
        let mut w = vec![0u64; (bytes.len() + offset).div_ceil(8) + 1];
        bytemuck::cast_slice_mut::<u64, u8>(&mut w)[offset..offset + bytes.len()].copy_from_slice(bytes);
        (Buf(w), bytes.len())
    }
    fn slice(&self, offset: usize, len: usize) -> &[u8] {
        &bytemuck::cast_slice::<u64, u8>(&self.0)[offset..offset + len]
    }
}

fn validate(bytes: &[u8]) -> Result<(), BlobError> {
    let (buf, n) = Buf::of(bytes, 0);
    MapView::new(buf.slice(0, n)).map(|_| ())
}

fn compiled() -> Vec<u8> {
    let m = map();
    let mut out = vec![0u8; m.compiled_len()];
    let n = m.compile(&mut out).unwrap();
    out.truncate(n);
    out
}

fn fix_crc(b: &mut [u8]) {
    let crc = crc32(&b[H..]);
    b[12..16].copy_from_slice(&crc.to_le_bytes());
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}
fn put_u16(b: &mut [u8], at: usize, v: u16) {
    b[at..at + 2].copy_from_slice(&v.to_le_bytes());
}
fn put_i32(b: &mut [u8], at: usize, v: i32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// The layout of the test map's blob, read from its counts.
struct Layout {
    obstacles: usize,
    pieces: usize,
    true_vertices: usize,
    vertices: usize,
    cells: usize,
    refs: usize,
}

impl Layout {
    fn of(b: &[u8]) -> Self {
        let c = |i: usize| u32_at(b, H + 4 * i) as usize;
        Layout { obstacles: c(2), pieces: c(3), true_vertices: c(4), vertices: c(5), cells: c(8) * c(9), refs: c(10) }
    }
    fn piece(&self, i: usize) -> usize {
        OBST + 8 * self.obstacles + 32 * i
    }
    fn vertex(&self, i: usize) -> usize {
        OBST + 8 * self.obstacles + 32 * self.pieces + 8 * i
    }
    fn start(&self, c: usize) -> usize {
        self.vertex(self.vertices) + 4 * c
    }
    fn refs_at(&self) -> usize {
        self.start(self.cells + 1)
    }
}

/// The id stored in ref `r` and the cell it is in.
fn refs(b: &[u8], l: &Layout) -> Vec<(usize, u16)> {
    let mut out = Vec::new();
    for c in 0..l.cells {
        let (lo, hi) = (u32_at(b, l.start(c)) as usize, u32_at(b, l.start(c + 1)) as usize);
        for r in lo..hi {
            let at = l.refs_at() + 2 * r;
            out.push((c, u16::from_le_bytes([b[at], b[at + 1]])));
        }
    }
    out
}

type Edit = Box<dyn Fn(&mut Vec<u8>, &Layout)>;

#[test]
fn every_lie_of_a_compiled_map_has_its_own_error() {
    let good = compiled();
    let l = Layout::of(&good);
    assert_eq!((l.obstacles, l.pieces), (3, 5), "the test map's shape");
    assert!(validate(&good).is_ok());
    let grid_refs = refs(&good, &l);
    assert_eq!(grid_refs.len(), l.refs);
    // A cell holding two refs, and a ref whose piece's box misses some cell.
    let (two_cell, _) = *grid_refs
        .iter()
        .find(|(c, _)| grid_refs.iter().filter(|(d, _)| d == c).count() >= 2)
        .expect("a cell with two pieces");
    let square = 2u16; // the square at (5..6 m, 5..6 m): far from the first cells
    let first = grid_refs[0].0;
    // A cell whose start is past 0, to put its end before it.
    let late = (1..l.cells).find(|&c| u32_at(&good, l.start(c)) > 0).expect("a cell after refs");
    assert_ne!(u32_at(&good, l.piece(1) + 12), 0, "the L's second piece has its seam");

    let header: Vec<(&str, Edit, BlobError)> = vec![
        ("empty", Box::new(|b, _| b.clear()), BlobError::TooShort { len: 0 }),
        ("header cut", Box::new(|b, _| b.truncate(10)), BlobError::TooShort { len: 10 }),
        ("bad magic", Box::new(|b, _| b[0] = b'X'), BlobError::BadMagic),
        ("version 4", Box::new(|b, _| b[4] = 4), BlobError::UnsupportedVersion(4)),
        // The version before the localization field: refused as outdated.
        ("version 2", Box::new(|b, _| b[4] = 2), BlobError::Outdated { version: 2, current: 3 }),
        ("flags set", Box::new(|b, _| b[6] = 1), BlobError::ReservedFlags(1)),
    ];
    for (what, edit, expect) in header {
        let mut b = good.clone();
        edit(&mut b, &l);
        assert_eq!(validate(&b), Err(expect), "{what}");
    }
    let payload = (good.len() - H) as u32;
    let mut b = good.clone();
    b.truncate(good.len() - 4);
    assert_eq!(validate(&b), Err(BlobError::LengthMismatch { header: payload, actual: payload as usize - 4 }));
    let mut b = good.clone();
    b.extend_from_slice(&[0; 4]);
    assert_eq!(validate(&b), Err(BlobError::LengthMismatch { header: payload, actual: payload as usize + 4 }));
    let mut b = good.clone();
    b[l.vertex(0)] ^= 1;
    assert!(matches!(validate(&b), Err(BlobError::BadCrc { .. })), "a flipped bit without its CRC");
    let (buf, n) = Buf::of(&good, 1);
    assert_eq!(MapView::new(buf.slice(1, n)).err(), Some(BlobError::Misaligned), "a start off the 4-byte boundary");

    let obstacles = l.obstacles;
    let pc = move |i: usize| OBST + 8 * obstacles + 32 * i;
    let rows: Vec<(&str, Edit, BlobError)> = vec![
        ("one obstacle more than the payload holds", Box::new(|b, _| put_u32(b, H + 8, 4)), BlobError::Truncated),
        (
            "one vertex fewer than the payload holds",
            Box::new(|b, _| {
                let v = u32_at(b, H + 20);
                put_u32(b, H + 20, v - 1)
            }),
            BlobError::TrailingBytes,
        ),
        (
            "cells whose size overflows",
            Box::new(|b, _| {
                put_u32(b, H + 32, u32::MAX);
                put_u32(b, H + 36, u32::MAX)
            }),
            BlobError::SizeMismatch,
        ),
        (
            "a field one word longer than the payload holds",
            Box::new(|b, _| {
                let f = u32_at(b, H + 44);
                put_u32(b, H + 44, f + 4)
            }),
            BlobError::Truncated,
        ),
        (
            "a field one word shorter than the payload holds",
            Box::new(|b, _| {
                let f = u32_at(b, H + 44);
                put_u32(b, H + 44, f - 4)
            }),
            BlobError::TrailingBytes,
        ),
        ("unknown obstacle kind", Box::new(|b, _| b[OBST] = 7), BlobError::UnknownKind { obstacle: 0, code: 7 }),
        ("reserved obstacle byte", Box::new(|b, _| b[OBST + 9] = 1), BlobError::ReservedByte { offset: OBST + 8 }),
        ("an empty obstacle", Box::new(|b, _| put_u16(b, OBST + 8 + 2, 0)), BlobError::EmptyObstacle { obstacle: 1 }),
        ("a wrong first piece", Box::new(|b, _| put_u16(b, OBST + 8 + 4, 3)), BlobError::CountMismatch),
        (
            "a piece naming an obstacle out of range",
            Box::new(move |b, _| put_u16(b, pc(0), 9)),
            BlobError::ObstacleOutOfRange { piece: 0, obstacle: 9 },
        ),
        (
            "a piece in another obstacle's run",
            Box::new(move |b, _| put_u16(b, pc(0), 1)),
            BlobError::PieceOutOfOrder { piece: 0 },
        ),
        (
            "a vertex range out of order",
            Box::new(move |b, _| put_u32(b, pc(1) + 4, 5)),
            BlobError::VertexRange { piece: 1 },
        ),
        (
            "a vertex range past the end",
            Box::new(move |b, l| put_u32(b, pc(4) + 8, l.vertices as u32 - 1)),
            BlobError::VertexRange { piece: 4 },
        ),
        (
            "a non-convex piece (a vertex pulled in)",
            Box::new(|b, l| {
                // (2000, 1000) → (800, 500): a right turn at it.
                put_i32(b, l.vertex(2), 800);
                put_i32(b, l.vertex(2) + 4, 500)
            }),
            BlobError::BadPiece {
                piece: 0,
                error: MapError::BadPiece { index: 0, error: ConvexError::NotStrictlyConvex },
            },
        ),
        (
            "a clockwise piece",
            Box::new(|b, l| {
                // The square (piece 2, true vertices 8..12) in reverse order.
                let v: Vec<[u8; 8]> = (8..12).map(|i| b[l.vertex(i)..l.vertex(i) + 8].try_into().unwrap()).collect();
                for (k, i) in (8..12).enumerate() {
                    let at = l.vertex(i);
                    b[at..at + 8].copy_from_slice(&v[3 - k]);
                }
            }),
            BlobError::BadPiece {
                piece: 2,
                error: MapError::BadPiece { index: 0, error: ConvexError::NotStrictlyConvex },
            },
        ),
        (
            "a solid obstacle marked as a wall",
            Box::new(|b, _| b[OBST + 8] = 1),
            BlobError::BadPiece { piece: 2, error: MapError::KindMismatch { index: 0 } },
        ),
        (
            "a coordinate beyond ±COORD_MAX",
            Box::new(|b, l| put_i32(b, l.vertex(9), i32::MAX)),
            BlobError::CoordinateOutOfRange { vertex: 9 },
        ),
        (
            "a buffered vertex moved",
            Box::new(|b, l| {
                let at = l.vertex(l.true_vertices) + 4;
                let y = i32::from_le_bytes(b[at..at + 4].try_into().unwrap());
                put_i32(b, at, y - 1)
            }),
            BlobError::BufferMismatch { piece: 0 },
        ),
        (
            "a box changed",
            Box::new(move |b, _| put_i32(b, pc(3) + 16, -1_000_000)),
            BlobError::BoxMismatch { piece: 3 },
        ),
        (
            "a seam bit past the edges",
            Box::new(move |b, _| put_u32(b, pc(2) + 12, 1 << 4)),
            BlobError::SeamMismatch { piece: 2 },
        ),
        (
            "a seam where there is none",
            Box::new(move |b, _| put_u32(b, pc(2) + 12, 1)),
            BlobError::SeamMismatch { piece: 2 },
        ),
        ("a seam cleared", Box::new(move |b, _| put_u32(b, pc(1) + 12, 0)), BlobError::SeamMismatch { piece: 1 }),
        (
            "the grid's origin moved",
            Box::new(|b, _| {
                let x = u32_at(b, H + 24) as i32;
                put_i32(b, H + 24, x + 1)
            }),
            BlobError::GridFrame,
        ),
        ("the first cell start", Box::new(|b, l| put_u32(b, l.start(0), 1)), BlobError::GridStart { cell: 0 }),
        (
            "a cell start past the refs",
            Box::new(|b, l| put_u32(b, l.start(1), l.refs as u32 + 5)),
            BlobError::GridStart { cell: 0 },
        ),
        (
            "a cell ending before it starts",
            Box::new(move |b, l| {
                let s = u32_at(b, l.start(late));
                put_u32(b, l.start(late + 1), s - 1)
            }),
            BlobError::GridStart { cell: late as u32 },
        ),
        (
            "a ref past the last piece",
            Box::new(|b, l| put_u16(b, l.refs_at(), 999)),
            BlobError::GridRef { cell: first as u32, piece: 999 },
        ),
        (
            "a ref to a piece whose box misses the cell",
            Box::new(move |b, l| put_u16(b, l.refs_at(), square)),
            BlobError::GridRef { cell: first as u32, piece: square },
        ),
        (
            "two refs of a cell in ascending order",
            Box::new(move |b, l| {
                let lo = u32_at(b, l.start(two_cell)) as usize;
                let at = l.refs_at() + 2 * lo;
                let (x, y) = ([b[at], b[at + 1]], [b[at + 2], b[at + 3]]);
                b[at..at + 2].copy_from_slice(&y);
                b[at + 2..at + 4].copy_from_slice(&x);
            }),
            BlobError::GridRef { cell: two_cell as u32, piece: 0 },
        ),
        (
            "two refs dropped from the end",
            Box::new(|b, l| {
                // Counts, the last cell's end and the sentinel agree; only
                // the boxes say two refs are missing.
                put_u32(b, H + 40, l.refs as u32 - 2);
                put_u32(b, l.start(l.cells), l.refs as u32 - 2);
                // The field after the refs stays as it was.
                let field = b.split_off(l.refs_at() + (2 * l.refs).next_multiple_of(4));
                let end = l.refs_at() + 2 * (l.refs - 2);
                b.truncate(end);
                b.resize(end.next_multiple_of(4), 0);
                b.extend_from_slice(&field);
                let len = (b.len() - H) as u32;
                put_u32(b, 8, len);
            }),
            BlobError::GridCoverage,
        ),
    ];
    for (what, edit, expect) in rows {
        let mut b = good.clone();
        edit(&mut b, &l);
        fix_crc(&mut b);
        let got = validate(&b);
        match (&got, &expect) {
            // The id found in a reordered cell is whichever comes second.
            (Err(BlobError::GridRef { cell: c, .. }), BlobError::GridRef { cell: e, piece: 0 })
                if what.starts_with("two refs") =>
            {
                assert_eq!(c, e, "{what}")
            }
            _ => assert_eq!(got, Err(expect), "{what}"),
        }
    }
    // The padding after the refs, when there is some.
    if l.refs % 2 == 1 {
        let mut b = good.clone();
        let last = l.refs_at() + (2 * l.refs).next_multiple_of(4) - 1;
        b[last] = 1;
        fix_crc(&mut b);
        assert_eq!(validate(&b), Err(BlobError::ReservedByte { offset: last }));
    }
}

/// Segments across the test map: what a view answers, it must answer the
/// same whenever a corrupted copy is accepted at all.
fn probes() -> Vec<Segment> {
    let mut out = Vec::new();
    for k in 0..12 {
        let a = p(-500 + 600 * k, -500);
        out.push(Segment::new(a, p(7000 - 500 * k, 7000)));
        out.push(Segment::new(p(-500, 500 * k), p(7000, 6500 - 400 * k)));
    }
    out
}

#[test]
fn every_single_byte_flip_is_refused_or_harmless() {
    // With the CRC recomputed, so that the structural checks are the ones
    // that must catch it. Debug build: an out-of-range index or an overflow
    // would panic.
    let good = compiled();
    let (gbuf, n) = Buf::of(&good, 0);
    let reference = MapView::new(gbuf.slice(0, n)).unwrap();
    let answers: Vec<_> = probes().iter().map(|s| reference.first_hit(*s).unwrap()).collect();
    let (mut refused, mut accepted) = (0, 0);
    for i in H..good.len() {
        for bit in [0x01u8, 0x80] {
            let mut b = good.clone();
            b[i] ^= bit;
            fix_crc(&mut b);
            let (buf, n) = Buf::of(&b, 0);
            match MapView::new(buf.slice(0, n)) {
                Err(_) => refused += 1,
                Ok(v) => {
                    accepted += 1;
                    for (s, a) in probes().iter().zip(&answers) {
                        assert_eq!(
                            v.first_hit(*s).unwrap(),
                            *a,
                            "byte {i} ^ {bit:#x} accepted but answers differently"
                        );
                    }
                }
            }
        }
    }
    // Accepted flips can only be bytes nothing reads differently (none here:
    // every field is checked), so almost all must be refused.
    eprintln!("{refused} flips refused, {accepted} accepted (and answering as before)");
    assert!(refused > 0 && accepted <= refused / 20, "{refused} refused, {accepted} accepted");
}

#[test]
fn a_compiled_map_loads_into_a_map_that_compiles_back_to_the_same_bytes() {
    let good = compiled();
    let (buf, n) = Buf::of(&good, 0);
    let mut m = Small::new();
    m.load(buf.slice(0, n)).unwrap();
    let mut again = vec![0u8; m.compiled_len()];
    let k = m.compile(&mut again).unwrap();
    assert_eq!(&again[..k], &good[..]);
    // And the view and the map agree on every piece.
    let v = MapView::new(buf.slice(0, n)).unwrap();
    for id in 0..v.piece_count() as u16 {
        let (a, b) = (MapSource::piece(&m, id).unwrap(), v.piece(id).unwrap());
        assert_eq!((a.shape, a.buffered, a.bbox, a.internal), (b.shape, b.buffered, b.bbox, b.internal));
        assert!(Convex::new(b.shape.vertices()).is_ok());
    }
}
