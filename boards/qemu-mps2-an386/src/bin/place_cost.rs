//! The cost of #48's places on QEMU's `mps2-an386` (Cortex-M4F): one ring
//! cycle of one place (16 readings of the Pioneer ring, each a field
//! lookup with its slope, scored by hit or null, at most one scalar update,
//! then the odometry) and the null hypothesis's scoring of the same 16
//! readings, in instructions; a bank of 8 places' cycle beside the
//! tracker's 380 k (docs/benchmarks.md) is `8 × place + null`.
//!
//! The places stand at 8 free poses of the depot's field, each 3 cm and
//! 1° from the pose its readings were made at (the field's own expected
//! ranges there, 5 of 16 readings made clutter 0.6 m short), so the cycles
//! score, gate and correct as on a real run. Each figure times `N` cycles
//! with SysTick (deterministic under `-icount shift=0`) and subtracts the
//! same loop without the call. Checks on the way that the places took
//! readings and came nearer their truths. Then the bank itself
//! (`Places<8>::cycle`: the 8 places on one robot's readings, the merges,
//! the drops and the test over their common cycles), its bound so wide
//! that all 8 stay alive (the most a cycle can cost). Exits 0 when every
//! check passed.
//!
//! `cargo run -p qemu-mps2-an386 --bin place_cost --target thumbv7em-none-eabihf --release`
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::localize::place::{Place, PlaceCycle, Tracking};
use echoloc::localize::places::{Places, Proposal, Standing};
use echoloc::localize::scan::{Candidate, ScanConfig, Sweep, SCAN_KEEP};
use echoloc::localize::{BeamModel, FieldLookup, NullModel, Sensed};
use echoloc::map::{Aligned, Expected, MapView};
use echoloc::predict::PIONEER16;
use echoloc::referencing::{EkfConfig, Motion, Reading};
use qemu_mps2_an386::{calibrate, elapsed, exit, free_poses, start_systick, ticks};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

const PLACES: usize = 8;
const N: u32 = 8;

#[inline(never)]
fn place_call(p: &mut Place, sensed: &[Sensed], null: &[f32], u: &Motion, t: &Tracking<'_>) -> PlaceCycle {
    p.cycle(sensed, null, u, t).unwrap_or_default()
}

#[inline(never)]
fn null_call(n: &mut NullModel, sensed: &[Sensed], out: &mut [f32; 16]) {
    for (o, s) in out.iter_mut().zip(sensed) {
        *o = n.log_likelihood(s.reading);
    }
}

#[inline(never)]
fn sweep_call(
    w: &mut Sweep,
    sensed: &[Sensed],
    lookup: &FieldLookup<'_, '_>,
    cfg: &ScanConfig,
    out: &mut heapless::Vec<Candidate, SCAN_KEEP>,
) {
    w.scan(sensed, lookup, &BeamModel::DEFAULT, cfg, out);
}

#[inline(never)]
fn bank_call(b: &mut Places<PLACES>, sensed: &[Sensed], null: &[f32], u: &Motion, t: &Tracking<'_>) -> Standing {
    b.cycle(sensed, null, u, t).unwrap_or(Standing::Searching)
}

#[inline(never)]
fn beside_call(b: &mut Places<PLACES>, p: Place, sensed: &[Sensed], null: &[f32], t: &Tracking<'_>) -> Proposal {
    b.propose_beside(p, None, sensed, null, t)
}

#[entry]
fn main() -> ! {
    let mut ok = true;
    let syst = start_systick();
    hprintln!("echoloc {} place cost on mps2-an386 (Cortex-M4F)", env!("CARGO_PKG_VERSION"));
    let per_tick = calibrate(&syst);
    let Ok(map) = MapView::new(&DEPOT.0) else {
        hprintln!("FAIL: the depot map refused");
        exit(false)
    };
    let lookup = FieldLookup::new(map.field());
    let beam = BeamModel::DEFAULT;
    let cfg = EkfConfig::DEFAULT;
    let t = Tracking { lookup: &lookup, beam: &beam, ekf: &cfg, clip: 2.0, hit_share: 0.5 };
    let poses = free_poses::<PLACES>(&map, 10_000);
    if poses.len() < PLACES {
        hprintln!("FAIL: only {} free poses", poses.len());
        exit(false);
    }
    // Each place's readings: what the field expects at its truth, a few
    // made clutter, in the robot's frame (a still robot: the mounts).
    let mut places: heapless::Vec<Place, PLACES> = heapless::Vec::new();
    let mut truths = [[0f32; 3]; PLACES];
    let mut sensed = [[Sensed { pose: [0.0; 3], reading: Reading::NoEcho }; 16]; PLACES];
    for (k, p) in poses.iter().enumerate() {
        let truth = [p.x_mm * 1e-3, p.y_mm * 1e-3, p.heading_rad];
        truths[k] = truth;
        let (s, c) = (libm::sinf(truth[2]), libm::cosf(truth[2]));
        for (j, m) in PIONEER16.iter().enumerate() {
            let local = [m.x_mm as f32 * 1e-3, m.y_mm as f32 * 1e-3, (m.heading_mdeg as f32 * 1e-3).to_radians()];
            let (x, y) = (truth[0] + c * local[0] - s * local[1], truth[1] + s * local[0] + c * local[1]);
            let reading = match lookup.expected(x * 1e3, y * 1e3, truth[2] + local[2]) {
                Some(Expected::Echo { range_mm, .. }) if j % 3 == 0 && range_mm > 1200.0 => {
                    Reading::Echo { range_mm: (range_mm - 600.0) as u32 }
                }
                Some(Expected::Echo { range_mm, .. }) => Reading::Echo { range_mm: range_mm as u32 },
                _ => Reading::NoEcho,
            };
            sensed[k][j] = Sensed { pose: local, reading };
        }
        let start = [truth[0] + 0.03, truth[1] - 0.01, truth[2] + 0.017];
        match Place::new(start, [0.1, 0.1, 0.05], &cfg) {
            Ok(pl) => {
                let _ = places.push(pl);
            }
            Err(_) => exit(false),
        }
    }
    let still = Motion::default();
    let null_scores = [-1.6f32; 16];

    // One place's cycle, over the 8 places in turn.
    let (mut tested, mut accepted) = (0u32, 0u32);
    let t0 = ticks(&syst);
    for _ in 0..N {
        for (p, s) in places.iter_mut().zip(&sensed) {
            let c = place_call(black_box(p), black_box(s), black_box(&null_scores), &still, &t);
            tested += u32::from(c.tested);
            accepted += u32::from(c.accepted);
        }
    }
    let with = elapsed(t0, ticks(&syst));
    let t0 = ticks(&syst);
    for _ in 0..N {
        for (p, s) in places.iter_mut().zip(&sensed) {
            black_box(p);
            black_box(s);
            black_box(&null_scores);
        }
    }
    let base = elapsed(t0, ticks(&syst));
    let place = with.saturating_sub(base) * per_tick / (N * PLACES as u32);
    hprintln!("metric place_cycle_insns {} (16 readings: {} tested, {} accepted over all)", place, tested, accepted);

    // The null's scoring of a cycle's 16 readings.
    let Ok(mut null) = NullModel::new(beam.r_min_mm, beam.r_max_mm, 400.0) else { exit(false) };
    let mut out = [0f32; 16];
    let t0 = ticks(&syst);
    for i in 0..N {
        null_call(black_box(&mut null), black_box(&sensed[(i as usize) % PLACES]), &mut out);
    }
    let with = elapsed(t0, ticks(&syst));
    let t0 = ticks(&syst);
    for i in 0..N {
        black_box(&mut null);
        black_box(&sensed[(i as usize) % PLACES]);
        black_box(&mut out);
    }
    let base = elapsed(t0, ticks(&syst));
    let null_insns = with.saturating_sub(base) * per_tick / N;
    hprintln!("metric null_cycle_insns {} (16 readings)", null_insns);
    hprintln!("metric place_state_bytes {}", core::mem::size_of::<Place>());

    // The bank: the same 8 places (as they are now) on the first one's
    // readings, as one robot's bank hears one ring.
    let Ok(mut bank) = Places::<PLACES>::new(1.0e9) else { exit(false) };
    for p in &places {
        let _ = bank.propose(*p);
    }
    if bank.living().len() != PLACES {
        hprintln!("FAIL: {} of {} places joined the bank", bank.living().len(), PLACES);
        exit(false);
    }
    let t0 = ticks(&syst);
    for _ in 0..N {
        black_box(bank_call(black_box(&mut bank), black_box(&sensed[0]), black_box(&null_scores), &still, &t));
    }
    let with = elapsed(t0, ticks(&syst));
    let t0 = ticks(&syst);
    for _ in 0..N {
        black_box(&mut bank);
        black_box(&sensed[0]);
        black_box(&null_scores);
    }
    let base = elapsed(t0, ticks(&syst));
    let bank_insns = with.saturating_sub(base) * per_tick / N;
    hprintln!(
        "metric bank8_cycle_insns {} (Places<8>::cycle, all 8 alive, and the null; {} alive after)",
        bank_insns + null_insns,
        bank.living().len()
    );
    hprintln!("metric places8_state_bytes {}", core::mem::size_of::<Places<PLACES>>());
    if bank.living().len() != PLACES {
        hprintln!("FAIL: the bank lost places at a bound of 10⁹ nats");
        ok = false;
    }

    // A proposal beside a living place (`PlaceTest::join_beside`): half a
    // metre from the first place, on its readings, so both are scored and
    // it is held (the most a proposal costs; at most 5 a cycle).
    let q = bank.living().first().map_or([0.0; 3], Place::pose);
    let Ok(beside) = Place::new([q[0] + 0.5, q[1], q[2]], [0.15, 0.15, 0.05], &cfg) else { exit(false) };
    let mut held = 0u32;
    let t0 = ticks(&syst);
    for _ in 0..N {
        let r = beside_call(black_box(&mut bank), black_box(beside), black_box(&sensed[0]), &null_scores, &t);
        held += u32::from(matches!(r, Proposal::Held(_)));
    }
    let with = elapsed(t0, ticks(&syst));
    let t0 = ticks(&syst);
    for _ in 0..N {
        black_box(&mut bank);
        black_box(beside);
        black_box(&sensed[0]);
    }
    let base = elapsed(t0, ticks(&syst));
    hprintln!(
        "metric beside_proposal_insns {} (scored against its neighbour; held {} of {})",
        with.saturating_sub(base) * per_tick / N,
        held,
        N
    );
    if held != N {
        hprintln!("FAIL: a proposal half a metre off its place's truth was not held");
        ok = false;
    }

    // The rivals' slow sweep while tracking (`PlaceTest::rival_nodes`): 96
    // free nodes a cycle on one ring, as `simulate --place-rivals 96` runs it.
    let scan = ScanConfig { nodes_per_cycle: 96, ..ScanConfig::DEFAULT };
    let mut sweep = Sweep::default();
    let mut out: heapless::Vec<Candidate, SCAN_KEEP> = heapless::Vec::new();
    let t0 = ticks(&syst);
    for _ in 0..N {
        sweep_call(black_box(&mut sweep), black_box(&sensed[0]), &lookup, &scan, &mut out);
    }
    let with = elapsed(t0, ticks(&syst));
    let t0 = ticks(&syst);
    for _ in 0..N {
        black_box(&mut sweep);
        black_box(&sensed[0]);
    }
    let base = elapsed(t0, ticks(&syst));
    hprintln!("metric sweep96_cycle_insns {} ({} candidates)", with.saturating_sub(base) * per_tick / N, out.len());
    if out.is_empty() {
        hprintln!("FAIL: the sweep proposed nothing");
        ok = false;
    }

    // The places took readings and ended nearer their truths than they began.
    let near = places.iter().zip(&truths).filter(|(p, tr)| {
        let q = p.pose();
        libm::hypotf(q[0] - tr[0], q[1] - tr[1]) < libm::hypotf(0.03, 0.01)
    });
    let near = near.count();
    if accepted == 0 || near < PLACES / 2 {
        hprintln!("FAIL: {} readings accepted, {} of {} places nearer their truth", accepted, near, PLACES);
        ok = false;
    }
    exit(ok)
}
