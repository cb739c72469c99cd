//! echoloc on QEMU's `mps2-an386` (Cortex-M4F): the README's main command.
//!
//! Both maps are compiled blobs (`echoloc-lab map import`) read in place
//! from flash through a [`MapView`]: no copy of a map is made in RAM.
//!
//! 1. The office map: a corrupted copy is refused with a typed error; segment
//!    queries through the grid; a Pioneer ring predicted by both
//!    beacon-collection strategies, which must agree.
//! 2. The real `depot` map (428 convex pieces): its validation cost, then the
//!    budgets of issue #11 as `metric NAME VALUE` lines: instructions per
//!    Pioneer ring and per window (full prediction with the quantised net,
//!    over poses spread through the depot's free space), per κ, the stack of
//!    a whole ring cycle (prediction, verdicts, EKF), static RAM and flash.
//!    `scripts/metrics.sh` compares them with the committed snapshot.
//!
//! Costs are SysTick counts, deterministic under the runner's
//! `-icount shift=0`, converted to instructions by the calibration loop.
//! Exits through semihosting: 0 when every check passed, 1 otherwise (a
//! HardFault or panic exits with 1 too).
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::credence::{Credence, EchoGeometry};
use echoloc::geometry::{isqrt, Point, Segment};
use echoloc::localize::{Localizer, Start};
use echoloc::map::{Aligned, BlobError, Layer, MapSource, MapView};
use echoloc::predict::{predict_ring, Pose, PredictParams, Prediction, PIONEER16};
use echoloc::referencing::{Ekf, EkfConfig, Motion, Reading, Referencer, VerdictConfig};
use echoloc::window::{Strategy, WindowParams};
use qemu_mps2_an386::replay::PARTICLES;
use qemu_mps2_an386::{
    calibrate, elapsed, exit, first_unpainted, flash_bytes, free_poses, metric, paint_free_stack, replay, stack_bounds,
    stack_high_water, start_systick, static_ram_bytes, ticks, time_rings, RingTimes,
};
use static_cell::ConstStaticCell;

/// The compiled maps, in flash, aligned for reading in place.
static OFFICE: &Aligned<[u8]> = &Aligned(*include_bytes!("../office.map"));
static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../depot.map"));
/// The scenario the whole loop replays: 40 m through the depot, half the
/// readings inconsistent with the map (`echoloc-lab simulate --seed 1`).
static SCENARIO: &[u8] = include_bytes!("../depot.scn");
/// The scenario the localizer must find itself in: the depot, no start pose
/// given, and a kidnap half-way (`docs/localization.md`).
static FIND_SCENARIO: &[u8] = include_bytes!("../depot-find.scn");
/// Its simulator seed, which the lab's localizer draws from too: the board
/// repeats the host's run (`echoloc-lab simulate --seed 6 …`).
const FIND_SEED: u64 = 6;
/// Scratch RAM for the corrupted copy of the office map.
static SCRATCH: ConstStaticCell<Aligned<[u8; 4096]>> = ConstStaticCell::new(Aligned([0; 4096]));

/// Segment queries on the office map, mm: (from, to, what a person would expect).
const QUERIES: [(Point, Point, &str); 6] = [
    (Point::new(1000, 3000), Point::new(9000, 3000), "east along y=3 m to the partition"),
    (Point::new(2800, 500), Point::new(2800, 4000), "north through the table"),
    (Point::new(8000, 4000), Point::new(6000, 4000), "west through the door gap"),
    (Point::new(5000, 4000), Point::new(5000, 7900), "north to the pillar"),
    (Point::new(10250, 4000), Point::new(10250, 500), "south into the U-shelf's mouth"),
    (Point::new(4000, 4000), Point::new(4500, 4500), "short diagonal in free space"),
];

/// Poses timed on the depot.
const POSES: u32 = 32;

#[entry]
fn main() -> ! {
    let mut ok = true;
    let syst = start_systick();
    hprintln!("echoloc {} on mps2-an386 (Cortex-M4F)", env!("CARGO_PKG_VERSION"));
    let per_tick = calibrate(&syst);
    let net = CredenceNet::shipped();

    // --- The office map.
    let scratch = &mut SCRATCH.take().0;
    let n = OFFICE.0.len().min(scratch.len());
    scratch[..n].copy_from_slice(&OFFICE.0[..n]);
    scratch[n - 1] ^= 0x40;
    match MapView::new(&scratch[..n]) {
        Err(BlobError::BadCrc { .. }) => hprintln!("corrupted blob: refused (BadCrc)"),
        other => {
            hprintln!("FAIL: corrupted blob gave {:?}", other.err());
            ok = false;
        }
    }
    let office = match MapView::new(&OFFICE.0) {
        Ok(v) => v,
        Err(e) => {
            hprintln!("FAIL: office map refused: {:?}", e);
            exit(false);
        }
    };
    let (cell, cols, rows) = office.grid_dims();
    hprintln!(
        "office: {} bytes in flash, {} obstacles, {} convex pieces, {} edges, t_b {} mm, grid {}x{} of {} mm, {} refs",
        OFFICE.0.len(),
        office.obstacle_count(),
        office.piece_count(),
        office.true_vertex_count(),
        office.buffer_mm(),
        cols,
        rows,
        cell,
        office.grid_refs()
    );
    for (i, &(a, b, what)) in QUERIES.iter().enumerate() {
        let seg = Segment::new(a, b);
        let t0 = ticks(&syst);
        let first = office.first_hit(seg);
        let t1 = ticks(&syst);
        let mut buffered = 0u32;
        let stats = office.for_each_hit(seg, Layer::Buffered, |_| buffered += 1);
        let (Ok(first), Ok(stats)) = (first, stats) else {
            hprintln!("FAIL: query refused");
            exit(false);
        };
        match first {
            Some(h) => {
                let kind = office.obstacle(h.obstacle).map(|o| o.kind);
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
    let pose = Pose { x_mm: 4000.0, y_mm: 4000.0, heading_rad: 0.0 };
    let window = WindowParams { tb_mm: office.buffer_mm(), ..WindowParams::MARGE };
    let mut rings = [[None; 16]; 2];
    for (k, strategy) in [Strategy::Exact, Strategy::PseudoPaths].into_iter().enumerate() {
        let params = PredictParams { strategy, ..PredictParams::new(window) };
        let t0 = ticks(&syst);
        let stats = predict_ring(&office, &pose, &PIONEER16, &params, &net, &mut rings[k]);
        let t = elapsed(t0, ticks(&syst));
        match stats {
            Ok(st) => hprintln!(
                "ring16 {:?} at (4.0, 4.0) m, 0 deg: {} instructions; {} candidates, {} beacons, {} edges, {} kappa, {} occlusion tests",
                strategy, t * per_tick, st.collect.candidates, st.beacons, st.edges, st.kappa_evals, st.occlusion_tests
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
    // The nearer-surface check runs with the exact strategy only.
    let exact = rings[0].map(|p| p.map(|p| Prediction { nearer_mm: None, ..p }));
    if exact != rings[1] || rings[1].iter().flatten().any(|p| p.nearer_mm.is_some()) {
        hprintln!("FAIL: the two strategies predicted differently");
        ok = false;
    }

    // The FPU square root (echoloc::f32math::sqrt is VSQRT on this target):
    // exact on perfect squares, correctly rounded on known roots.
    let roots_ok = (1..=4096u32).all(|i| {
        let x = black_box(i as f32);
        echoloc::f32math::sqrt(x * x) == x
    }) && echoloc::f32math::sqrt(black_box(2.0)).to_bits() == 0x3FB5_04F3
        && echoloc::f32math::sqrt(black_box(-1.0)).is_nan();
    if !roots_ok {
        hprintln!("FAIL: the FPU square root");
        ok = false;
    }

    // --- The depot map: validation, then the budgets.
    let t0 = ticks(&syst);
    let depot = MapView::new(black_box(&DEPOT.0));
    let validate = elapsed(t0, ticks(&syst)) * per_tick;
    let depot = match depot {
        Ok(v) => v,
        Err(e) => {
            hprintln!("FAIL: depot map refused: {:?}", e);
            exit(false);
        }
    };
    hprintln!(
        "depot: {} bytes in flash, {} obstacles, {} convex pieces, {} edges; validated in place",
        DEPOT.0.len(),
        depot.obstacle_count(),
        depot.piece_count(),
        depot.true_vertex_count()
    );
    metric("map_validate_insns", validate as u64);
    metric("map_bytes_depot", DEPOT.0.len() as u64);

    let params = PredictParams::new(WindowParams { tb_mm: depot.buffer_mm(), ..WindowParams::MARGE });
    let poses = free_poses::<{ POSES as usize }>(&depot, u32::MAX);
    let RingTimes { total, worst, predicted, ok: rings_ok } =
        time_rings(&depot, &poses, &params, &net, &syst, per_tick);
    ok &= rings_ok;
    let rings = poses.len().max(1) as u64;
    hprintln!("depot: {} rings at free poses, {} of {} windows predicted an echo", rings, predicted, rings * 16);
    if predicted < POSES as usize * 4 {
        hprintln!("FAIL: too few predictions for the timing to mean anything");
        ok = false;
    }
    metric("insns_per_ring", total / rings);
    metric("insns_per_ring_max", worst);
    metric("insns_per_window", total / (rings * 16));
    metric("insns_per_kappa", kappa_cost(&syst, per_tick, &net) as u64);

    // Stack of a whole ring cycle (16 × odometry, prediction, verdict, EKF
    // update, then the lost monitor), below this frame. The filter's state
    // (the EKF with the readings its recovery keeps) lives for the whole run
    // in the caller, as on a robot: it is made here and its size reported
    // apart.
    let x = [poses[0].x_mm / 1000.0, poses[0].y_mm / 1000.0, poses[0].heading_rad];
    let Ok(ekf) = Ekf::new([x[0] + 0.03, x[1], x[2]], [0.05, 0.05, 0.03], EkfConfig::DEFAULT) else {
        hprintln!("FAIL: the filter refused its start");
        exit(false);
    };
    let mut filter = Referencer::new(ekf, VerdictConfig::POLAROID);
    metric("filter_state_bytes", core::mem::size_of::<Referencer>() as u64);
    let (_, bottom) = stack_bounds();
    let sp = paint_free_stack(bottom);
    let cycle_ok = ring_cycle(&depot, &net, &params, &poses[0], &mut filter);
    let stack = sp - first_unpainted(bottom, sp);
    if !cycle_ok || stack == 0 {
        hprintln!("FAIL: ring cycle failed or measured no stack");
        ok = false;
    }
    metric("stack_bytes", stack as u64);
    metric("ram_static_bytes", static_ram_bytes() as u64);
    let data = OFFICE.0.len() + DEPOT.0.len() + SCENARIO.len() + FIND_SCENARIO.len();
    metric("flash_bytes", (flash_bytes() - data) as u64);
    hprintln!("(flash_bytes is the image without its {} bytes of compiled maps and scenario)", data);

    // --- The whole loop: the depot scenario through the ring driver, the
    // quantised credence, the verdicts and the EKF, against its truth.
    match replay::replay::<PARTICLES>(SCENARIO, &depot, echoloc::map::crc32(&DEPOT.0), &net, &syst, per_tick, None, 1) {
        Some(r) => {
            let h = echoloc::scenario::Scenario::parse(SCENARIO).map(|s| *s.header()).ok();
            let bounds = h.map_or((0.0, 0.0), |h| (h.bound_position_m, h.bound_heading_deg));
            ok &= replay::report(&r, bounds);
            metric("loc_tracking_insns_per_cycle", r.insns_per_cycle[0].0);
            metric("loc_tracking_insns_per_cycle_max", r.insns_per_cycle[0].1);
        }
        None => ok = false,
    }
    metric("localizer_state_bytes", core::mem::size_of::<Localizer<PARTICLES>>() as u64);

    // Finding itself (issue #27): a run that starts with no pose at all and
    // is carried away on the way, through the same loop with the particles.
    hprintln!("find: a depot run started with no pose, with a kidnap, through the whole loop");
    let find = replay::replay::<PARTICLES>(
        FIND_SCENARIO,
        &depot,
        echoloc::map::crc32(&DEPOT.0),
        &net,
        &syst,
        per_tick,
        Some(Start::Unknown),
        FIND_SEED,
    );
    match find {
        Some(r) => ok &= replay::report_find(&r),
        None => ok = false,
    }

    let (used, size) = stack_high_water();
    hprintln!("stack high-water mark: {} of {} bytes", used, size);
    exit(ok);
}

/// One whole ring cycle through the core's `Referencer` `r`, never inlined
/// so that its frames lie below the caller's stack pointer. Each reading is
/// the prediction from the true pose, 30 mm off the filter's estimate.
#[inline(never)]
fn ring_cycle(
    map: &MapView<'_>,
    net: &CredenceNet<'_>,
    params: &PredictParams,
    pose: &Pose,
    r: &mut Referencer,
) -> bool {
    let mut truth: [Option<Prediction>; 16] = [None; 16];
    if predict_ring(map, pose, &PIONEER16, params, net, &mut truth).is_err() {
        return false;
    }
    for (mount, p) in PIONEER16.iter().zip(truth.iter()) {
        let reading = p.map_or(Reading::NoEcho, |p| Reading::Echo { range_mm: p.range_mm });
        if r.odometry(&Motion { dx: 0.0, dy: 0.0, dphi: 0.0 }).is_err()
            || black_box(r.reading(map, mount, params, net, reading)).is_err()
        {
            return false;
        }
    }
    black_box(r.end_cycle());
    true
}

/// Instructions per κ of the shipped net: a sweep of the input domain timed
/// with the net and without it.
fn kappa_cost(syst: &Option<cortex_m::peripheral::SYST>, per_tick: u32, net: &CredenceNet<'_>) -> u32 {
    const N: u32 = 256;
    let sweep = |i: u32| EchoGeometry {
        range_mm: 500 + (i % 16) * 333,
        theta_mdeg: (i / 16) as i32 * 3000 - 22_500,
        delta_mdeg: 0,
    };
    let t0 = ticks(syst);
    let mut sum = 0u32;
    for i in 0..N {
        sum = sum.wrapping_add(u32::from(net.kappa(&black_box(sweep(i))).to_bits()));
    }
    let with = elapsed(t0, ticks(syst));
    black_box(sum);
    let t0 = ticks(syst);
    let mut base = 0u32;
    for i in 0..N {
        let e = black_box(sweep(i));
        base = base.wrapping_add(e.range_mm ^ e.theta_mdeg as u32);
    }
    let without = elapsed(t0, ticks(syst));
    black_box(base);
    with.saturating_sub(without) * per_tick / N
}
