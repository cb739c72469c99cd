//! echoloc on QEMU's `mps2-an386` with a real map: the Nav2 `depot`
//! occupancy grid, imported by `echoloc-lab map import
//! ../shared/data/maps/depot.yaml` (marching squares, 50 mm simplification,
//! convex pieces with holes), compiled and read in place from flash through
//! a `MapView` (no copy in RAM). Prints what it holds, runs segment queries
//! across the depot and exits through
//! semihosting: 0 when the map loaded and every query found what a person
//! looking at the depot would expect, 1 otherwise (HardFault and panic too).
//!
//! `cargo run -p qemu-mps2-an386 --bin depot --target thumbv7em-none-eabihf --release`
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::geometry::{isqrt, Point, Segment};
use echoloc::map::{Aligned, Layer, MapSource, MapView};
use qemu_mps2_an386::exit;

/// The compiled map stays in flash, aligned for reading in place.
static BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

/// Segment queries, mm: (from, to, whether the true map should be hit, what).
/// The depot is 30.2 m × 15.35 m with its origin at the lower-left corner.
const QUERIES: [(Point, Point, bool, &str); 5] = [
    (Point::new(5000, 10000), Point::new(-1000, 10000), true, "west from the open floor to the outer wall"),
    (Point::new(5000, 10000), Point::new(5000, 16000), true, "north to the outer wall"),
    (Point::new(5000, 10000), Point::new(12000, 10000), false, "east across the open floor"),
    (Point::new(8000, 2000), Point::new(8000, 20000), true, "north along x = 8 m through the whole depot"),
    (Point::new(1000, 1000), Point::new(29000, 14000), true, "the long diagonal, through the rooms"),
];

#[entry]
fn main() -> ! {
    hprintln!("echoloc {} on mps2-an386: depot map", env!("CARGO_PKG_VERSION"));
    let map = match MapView::new(&BLOB.0) {
        Ok(v) => v,
        Err(e) => {
            hprintln!("FAIL: depot blob refused: {:?}", e);
            exit(false);
        }
    };
    let (cell, cols, rows) = map.grid_dims();
    let b = map.bounds();
    hprintln!(
        "map: {} bytes, {} obstacles, {} convex pieces, {} true vertices ({} with buffers), t_b {} mm, grid {}x{} of {} mm, {} refs",
        BLOB.0.len(),
        map.obstacle_count(),
        map.piece_count(),
        map.true_vertex_count(),
        map.vertex_count(),
        map.buffer_mm(),
        cols,
        rows,
        cell,
        map.grid_refs()
    );
    if let Some(b) = b {
        hprintln!("bounds: ({}, {}) .. ({}, {}) mm", b.min.x, b.min.y, b.max.x, b.max.y);
    }
    let mut ok = true;
    for (i, &(a, z, expect, what)) in QUERIES.iter().enumerate() {
        let seg = Segment::new(a, z);
        let mut buffered = 0u32;
        let (Ok(first), Ok(stats)) = (map.first_hit(seg), map.for_each_hit(seg, Layer::Buffered, |_| buffered += 1))
        else {
            hprintln!("FAIL: query on an unfinished map");
            exit(false);
        };
        match first {
            Some(h) => hprintln!(
                "q{} {}: first hit obstacle {} piece {} at ({}, {}) mm, range {} mm; {} buffered hits; {} cells, {} candidates",
                i,
                what,
                h.obstacle,
                h.piece,
                h.point.x,
                h.point.y,
                isqrt(a.dist2(h.point) as u64),
                buffered,
                stats.cells,
                stats.candidates
            ),
            None => hprintln!(
                "q{} {}: no hit; {} buffered hits; {} cells, {} candidates",
                i,
                what,
                buffered,
                stats.cells,
                stats.candidates
            ),
        }
        if first.is_some() != expect {
            hprintln!("FAIL: q{} expected {}", i, if expect { "a hit" } else { "no hit" });
            ok = false;
        }
    }
    exit(ok);
}
