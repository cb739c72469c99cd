//! echoloc on QEMU's `mps2-an386` (Cortex-M4F).
//!
//! Loads the office map blob (built by `echoloc-lab map import
//! maps/office.geojson`), refuses a corrupted copy of it, runs segment
//! queries through the grid index, prints what it found with the SysTick cost
//! of each query (deterministic under `-icount shift=0`), then the stack's
//! high-water mark (cortex-m-rt `paint-stack`), and exits through
//! semihosting: 0 when every check passed, 1 otherwise. A HardFault or panic
//! exits with 1 too, so a crash can never look like success.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::geometry::{isqrt, Point, Segment};
use echoloc::map::{BlobError, Layer, StandardMap};
use echoloc::predict::{predict_ring, Pose, PredictParams, PIONEER16};
use echoloc::window::{Strategy, WindowParams};
use qemu_mps2_an386::{calibrate, elapsed, exit, stack_high_water, start_systick, ticks};
use static_cell::ConstStaticCell;

/// The map lives in a static, initialised at compile time: no stack copy.
static MAP: ConstStaticCell<StandardMap> = ConstStaticCell::new(StandardMap::new());
/// The blob stays in flash.
static BLOB: &[u8] = include_bytes!("../office.map");
/// Scratch RAM for the corrupted copy.
static SCRATCH: ConstStaticCell<[u8; 1024]> = ConstStaticCell::new([0; 1024]);

/// Segment queries, mm: (from, to, what a person would expect).
const QUERIES: [(Point, Point, &str); 6] = [
    (Point::new(1000, 3000), Point::new(9000, 3000), "east along y=3 m to the partition"),
    (Point::new(2800, 500), Point::new(2800, 4000), "north through the table"),
    (Point::new(8000, 4000), Point::new(6000, 4000), "west through the door gap"),
    (Point::new(5000, 4000), Point::new(5000, 7900), "north to the pillar"),
    (Point::new(10250, 4000), Point::new(10250, 500), "south into the U-shelf's mouth"),
    (Point::new(4000, 4000), Point::new(4500, 4500), "short diagonal in free space"),
];

#[entry]
fn main() -> ! {
    let mut ok = true;
    let syst = start_systick();

    hprintln!("echoloc {} on mps2-an386 (Cortex-M4F)", env!("CARGO_PKG_VERSION"));
    calibrate(&syst);
    let map = MAP.take();

    // A corrupted copy must be refused with a typed error, and leave the map empty.
    let scratch = SCRATCH.take();
    let n = BLOB.len().min(scratch.len());
    scratch[..n].copy_from_slice(&BLOB[..n]);
    scratch[n - 1] ^= 0x40;
    match map.load(&scratch[..n]) {
        Err(BlobError::BadCrc { .. }) if map.piece_count() == 0 => hprintln!("corrupted blob: refused (BadCrc)"),
        other => {
            hprintln!("FAIL: corrupted blob gave {:?}", other);
            ok = false;
        }
    }

    let t0 = ticks(&syst);
    let loaded = map.load(BLOB);
    let load_ticks = elapsed(t0, ticks(&syst));
    if let Err(e) = loaded {
        hprintln!("FAIL: map blob refused: {:?}", e);
        exit(false);
    }
    let (cell, cols, rows) = map.grid_dims();
    hprintln!(
        "map: {} bytes, {} obstacles, {} convex pieces, {} edges, t_b {} mm, grid {}x{} of {} mm, {} refs; load {} ticks",
        BLOB.len(),
        map.obstacles().len(),
        map.piece_count(),
        map.true_vertex_count(),
        map.buffer_mm(),
        cols,
        rows,
        cell,
        map.grid_refs(),
        load_ticks
    );

    for (i, &(a, b, what)) in QUERIES.iter().enumerate() {
        let seg = Segment::new(a, b);
        let t0 = ticks(&syst);
        let first = map.first_hit(seg);
        let t1 = ticks(&syst);
        let mut buffered = 0u32;
        let stats = map.for_each_hit(seg, Layer::Buffered, |_| buffered += 1);
        let (Ok(first), Ok(stats)) = (first, stats) else {
            hprintln!("FAIL: query on an unfinished map");
            exit(false);
        };
        match first {
            Some(h) => {
                let kind = map.obstacles()[h.obstacle as usize].kind;
                let range = isqrt(a.dist2(h.point) as u64);
                hprintln!(
                    "q{} {}: first hit obstacle {} ({:?}) piece {} at ({}, {}) mm, range {} mm; {} buffered hits; {} cells, {} candidates; {} ticks",
                    i, what, h.obstacle, kind, h.piece, h.point.x, h.point.y, range, buffered, stats.cells, stats.candidates, elapsed(t0, t1)
                );
            }
            None => hprintln!(
                "q{} {}: no hit; {} buffered hits; {} cells, {} candidates; {} ticks",
                i,
                what,
                buffered,
                stats.cells,
                stats.candidates,
                elapsed(t0, t1)
            ),
        }
    }

    // A full Pioneer ring prediction with the quantised credence net, by
    // both beacon-collection strategies: they must agree.
    let pose = Pose { x_mm: 4000.0, y_mm: 4000.0, heading_rad: 0.0 };
    let net = CredenceNet::shipped();
    let window = WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE };
    let mut rings = [[None; 16]; 2];
    for (k, strategy) in [Strategy::Exact, Strategy::PseudoPaths].into_iter().enumerate() {
        let params = PredictParams { strategy, ..PredictParams::new(window) };
        let t0 = ticks(&syst);
        let stats = predict_ring(&*map, &pose, &PIONEER16, &params, &net, &mut rings[k]);
        let t = elapsed(t0, ticks(&syst));
        match stats {
            Ok(st) => hprintln!(
                "ring16 {:?} at (4.0, 4.0) m, 0 deg: {} ticks; {} candidates, {} beacons, {} edges, {} kappa, {} occlusion tests",
                strategy, t, st.collect.candidates, st.beacons, st.edges, st.kappa_evals, st.occlusion_tests
            ),
            Err(e) => {
                hprintln!("FAIL: ring prediction: {:?}", e);
                ok = false;
            }
        }
    }
    for (i, p) in rings[0].iter().enumerate() {
        match p {
            Some(p) => hprintln!(
                "  sonar {}: {} mm, kappa {}, theta {} mdeg, delta {} mdeg, obstacle {}, case {:?}",
                i,
                p.range_mm,
                p.kappa.to_bits(),
                p.theta_mdeg,
                p.delta_mdeg,
                p.obstacle,
                p.case
            ),
            None => hprintln!("  sonar {}: nothing credible in range", i),
        }
    }
    if rings[0] != rings[1] {
        hprintln!("FAIL: the two strategies predicted differently");
        ok = false;
    }

    let (used, size) = stack_high_water();
    hprintln!("stack high-water mark: {} of {} bytes", used, size);
    exit(ok);
}
