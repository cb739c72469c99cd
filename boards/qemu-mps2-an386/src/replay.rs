//! The whole loop on the board: a scenario replayed through the real ring
//! driver (over the core's replay bench, which drives ECHO and the
//! microsecond clock from the scenario's echo times), then prediction with
//! the quantised credence, verdicts and the EKF, reading after reading
//! ([`echoloc::controller::replay`]). Prints the pose error against the
//! scenario's ground truth and the loop's cost as `metric` lines.

use cortex_m::peripheral::SYST;
use cortex_m_semihosting::hprintln;
use echoloc::controller::replay::{check, localizer, run, scenario_odometry, start, ReplaySetup, ReplaySummary};
use echoloc::credence::net::CredenceNet;
use echoloc::localize::{Mode, Start};
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{Mount, PredictParams};
use echoloc::scenario::replay::Bench;
use echoloc::scenario::Scenario;
use echoloc::window::WindowParams;

use crate::{elapsed, first_unpainted, paint_free_stack, stack_bounds, ticks};

/// Transducers the board's ring has (a Pioneer ring: 4 address lines).
pub const TRANSDUCERS: usize = 16;
/// Particles the board's localizer holds (issue #27: 1 024).
pub const PARTICLES: usize = 1024;
/// How far the bench's clock moves at a wait during a ping with no edge
/// due sooner, µs: the poll timer of a board that also wakes on the edge.
pub const POLL_STEP_US: u32 = 1_000;

/// Where a scenario not linked into the image is read from: the flash
/// partition QEMU's generic loader fills (`-device
/// loader,file=X.scn,addr=0x00300000`), past the 1 MiB image and the map
/// partition's first MiB.
pub const SCENARIO_PARTITION: usize = 0x0030_0000;
/// Its size: a scenario claiming more is refused before it is read.
pub const SCENARIO_PARTITION_LEN: usize = 1024 * 1024;

/// The scenario in the partition, its length from its header, bounded by
/// the partition (not yet validated: `Scenario::parse` does that). `None`,
/// with a FAIL line, when there is none or it claims too much.
pub fn scenario_partition() -> Option<&'static [u8]> {
    use echoloc::scenario::{FIXED_HEADER_LEN, MAGIC, RECORD_LEN};
    // SAFETY: SCENARIO_PARTITION..+SCENARIO_PARTITION_LEN lies in SSRAM1
    // (4 MiB at 0 on mps2-an386), always mapped and readable, outside every
    // region the linker places anything in (FLASH 0..1 MiB, RAM at
    // 0x2000_0000), and nothing in these programs writes it.
    let header: [u8; FIXED_HEADER_LEN] =
        unsafe { core::ptr::read_volatile(SCENARIO_PARTITION as *const [u8; FIXED_HEADER_LEN]) };
    if header[..4] != MAGIC[..] {
        hprintln!("FAIL: no scenario at {:#010x}", SCENARIO_PARTITION);
        return None;
    }
    let head = u16::from_le_bytes([header[6], header[7]]) as usize;
    let records = u32::from_le_bytes([header[16], header[17], header[18], header[19]]) as usize;
    let len = records.checked_mul(RECORD_LEN).and_then(|r| r.checked_add(head + 4));
    let Some(len) = len.filter(|&n| n <= SCENARIO_PARTITION_LEN) else {
        hprintln!(
            "FAIL: the scenario header claims more than the {} byte partition holds: refused",
            SCENARIO_PARTITION_LEN
        );
        return None;
    };
    // SAFETY: `len` ≤ SCENARIO_PARTITION_LEN: inside the partition described
    // above, never written while the program runs, so a valid `'static` slice.
    Some(unsafe { core::slice::from_raw_parts(SCENARIO_PARTITION as *const u8, len) })
}

/// The loop's settings on this board for `map` (its own face lobe, from its field).
pub fn setup(map: &MapView<'_>) -> Option<ReplaySetup<TRANSDUCERS>> {
    let window = WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::POLAROID_6500 }.with_map_lobe(map.field());
    ReplaySetup::standard(PredictParams::new(window)).ok()
}

/// What a replay on the board measured.
pub struct BoardReplay {
    /// The loop's figures.
    pub summary: ReplaySummary,
    /// Instructions per reading (driver, prediction, verdict, EKF), mean and worst.
    pub insns_per_reading: (u64, u64),
    /// Instructions of a whole ring cycle, mean and worst, over the cycles
    /// that ended tracking and over those that ended searching (the reading
    /// that closes a cycle carries its end: the particles' update).
    pub insns_per_cycle: [(u64, u64); 2],
    /// Stack the loop used, bytes.
    pub stack_bytes: usize,
}

/// Replays `bytes` (a scenario made on the map whose blob has CRC
/// `map_crc`), printing what it finds. `None`, with a FAIL line, when the
/// scenario is refused or the loop stops on an error.
#[allow(clippy::too_many_arguments)]
pub fn replay<const P: usize>(
    bytes: &[u8],
    map: &MapView<'_>,
    map_crc: u32,
    net: &CredenceNet<'_>,
    syst: &Option<SYST>,
    per_tick: u32,
    how: Option<Start>,
    seed: u64,
) -> Option<BoardReplay> {
    let scenario = match Scenario::parse(bytes) {
        Ok(s) => s,
        Err(e) => {
            hprintln!("FAIL: scenario refused: {}", e);
            return None;
        }
    };
    let Some(setup) = setup(map) else {
        hprintln!("FAIL: the board's ring configuration");
        return None;
    };
    let mut mounts = [Mount { x_mm: 0, y_mm: 0, heading_mdeg: 0 }; TRANSDUCERS];
    for (i, m) in mounts.iter_mut().enumerate() {
        *m = scenario.mount(i).unwrap_or(*m);
    }
    let bench = Bench::new(scenario, POLL_STEP_US);
    if let Err(e) = check(&bench, map_crc, &setup) {
        hprintln!("FAIL: scenario refused: {}", e);
        return None;
    }
    let h = scenario.header();
    let f = Fixed6;
    hprintln!(
        "scenario: {} records, {} transducers, {} bytes; start ({}, {}) m, {} rad; bounds {} m, {} deg RMSE",
        scenario.len(),
        scenario.transducers(),
        bytes.len(),
        f(h.start[0]),
        f(h.start[1]),
        f(h.start[2]),
        f(h.bound_position_m),
        f(h.bound_heading_deg)
    );
    let (_, bottom) = stack_bounds();
    let sp = paint_free_stack(bottom);
    let (mut total, mut worst) = (0u64, 0u64);
    // Per mode: cycles, their instructions, the worst one; and the cycle in progress.
    let mut cycles = [(0u64, 0u64, 0u64); 2];
    let mut in_cycle = 0u64;
    let mut t0 = ticks(syst);
    let result = run_loop::<P>(&bench, map, &mounts, net, &setup, how, seed, &mut |_, ended| {
        let t = ticks(syst);
        let n = u64::from(elapsed(t0, t)) * u64::from(per_tick);
        total += n;
        worst = worst.max(n);
        // The reading that closed a cycle paid for its end: the cycle so
        // far, plus this reading, is that cycle's cost.
        if let Some(mode) = ended {
            // Tracking and searching cycles apart (a lost cycle, where the
            // particles wake and are drawn, is neither).
            let k = match mode {
                Mode::Tracking => Some(0),
                Mode::Searching => Some(1),
                Mode::Lost => None,
            };
            if let Some(c) = k.and_then(|k| cycles.get_mut(k)) {
                let cost = in_cycle + n;
                *c = (c.0 + 1, c.1 + cost, c.2.max(cost));
            }
            in_cycle = 0;
        } else {
            in_cycle += n;
        }
        // The callback's own cost is left out of the next reading.
        t0 = ticks(syst);
    });
    let stack_bytes = sp - first_unpainted(bottom, sp);
    let summary = match result {
        Ok(s) => s,
        Err(e) => {
            hprintln!("FAIL: the loop stopped: {}", e);
            return None;
        }
    };
    let n = u64::from(summary.score.readings.max(1));
    let per = |c: (u64, u64, u64)| (c.1 / c.0.max(1), c.2);
    Some(BoardReplay {
        summary,
        insns_per_reading: (total / n, worst),
        insns_per_cycle: [per(cycles[0]), per(cycles[1])],
        stack_bytes,
    })
}

/// The loop itself, never inlined, so that its frames lie below the
/// caller's painted stack pointer.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
pub fn run_loop<const P: usize>(
    bench: &Bench<'_>,
    map: &MapView<'_>,
    mounts: &[Mount],
    net: &CredenceNet<'_>,
    setup: &ReplaySetup<TRANSDUCERS>,
    how: Option<Start>,
    seed: u64,
    tick: &mut dyn FnMut(u32, Option<Mode>),
) -> Result<ReplaySummary, echoloc::controller::replay::ReplayError> {
    // The localizer's one copy, built in place in this frame.
    let mut loc = localizer::<P, TRANSDUCERS>(setup, seed);
    start(&mut loc, bench, map.field(), how)?;
    run::<_, _, 4, TRANSDUCERS, P>(
        bench,
        map,
        map.field(),
        mounts,
        net,
        setup,
        &mut loc,
        scenario_odometry,
        |c, _, _, s| tick(c.counts().readings, s.cycle_end.map(|e| e.localizer.mode)),
    )
}

/// `v` with six decimals, formatted with integers only: core's float
/// formatting would add about 10 KiB of flash for a few lines of output,
/// and `f64` a soft double library (the M4F's FPU is single precision).
/// The whole part and the fraction apart (`v - trunc(v)` is exact), so
/// that the fraction's millionths round as they would in `f64` for any
/// value an `f32` pose or score holds.
pub struct Fixed6(pub f32);

impl core::fmt::Display for Fixed6 {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if !self.0.is_finite() {
            return f.write_str("nan");
        }
        let a = self.0.abs();
        let whole = libm::truncf(a);
        let mut micro = libm::roundf((a - whole) * 1e6) as u64;
        let mut whole = whole as u64;
        if micro == 1_000_000 {
            (whole, micro) = (whole + 1, 0);
        }
        let sign = if self.0 < 0.0 && (whole, micro) != (0, 0) { "-" } else { "" };
        write!(f, "{}{}.{:06}", sign, whole, micro)
    }
}

/// Prints a replay's findings and metrics; true when it met the scenario's bounds.
pub fn report(r: &BoardReplay, bounds: (f32, f32)) -> bool {
    let s = &r.summary;
    let c = &s.counts;
    let (bp, bh) = (Fixed6(bounds.0), Fixed6(bounds.1));
    hprintln!(
        "loop: {} readings in {} cycles: {} echoes ({} not confirmed by EERUF), {} no echo, {} invalid; EKF accepted {}, gated {}; lost {} times, {} cycles",
        c.readings, c.cycles, c.echoes, c.unconfirmed, c.no_echo, c.invalid, s.accepted, s.gated, s.lost.0, s.lost.1
    );
    let x = s.state.map(Fixed6);
    hprintln!(
        "pose error against the ground truth: RMSE {} m and {} deg, max {} m, final {} m and {} deg; final estimate ({}, {}) m, {} rad",
        Fixed6(s.score.position_rmse_m),
        Fixed6(s.score.heading_rmse_deg),
        Fixed6(s.score.max_position_m),
        Fixed6(s.score.final_position_m),
        Fixed6(s.score.final_heading_deg),
        x[0],
        x[1],
        x[2]
    );
    hprintln!("metric pose_rmse_m {}", Fixed6(s.score.position_rmse_m));
    hprintln!("metric heading_rmse_deg {}", Fixed6(s.score.heading_rmse_deg));
    crate::metric("loop_insns_per_reading", r.insns_per_reading.0);
    crate::metric("loop_insns_per_reading_max", r.insns_per_reading.1);
    crate::metric("loop_stack_bytes", r.stack_bytes as u64);
    if s.passed {
        hprintln!("loop: within the scenario's bounds ({} m, {} deg RMSE)", bp, bh);
    } else {
        hprintln!(
            "FAIL: pose error beyond the scenario's bounds: {} m (bound {} m), {} deg (bound {} deg)",
            Fixed6(s.score.position_rmse_m),
            bp,
            Fixed6(s.score.heading_rmse_deg),
            bh
        );
    }
    s.passed
}

/// Prints what the localizer did on a run it had to find itself in, and its
/// metrics; true when it ends tracking within 0.3 m and 10° of the truth,
/// having handed off to the EKF at least twice and woken at least once (it
/// found itself, was carried, noticed, and found itself again).
pub fn report_find(r: &BoardReplay) -> bool {
    let s = &r.summary;
    let l = &s.localizer;
    hprintln!(
        "find: {} cycles searching, {} tracking, {} lost; {} hand-offs, {} wake-ups, {} searches ended by the EKF; final mode {}",
        l.searching,
        l.tracking,
        l.lost,
        l.handoffs,
        l.wakes,
        l.calmed,
        s.mode.name()
    );
    hprintln!("find: final error {} m and {} deg", Fixed6(s.score.final_position_m), Fixed6(s.score.final_heading_deg));
    crate::metric("loc_search_insns_per_cycle", r.insns_per_cycle[1].0);
    crate::metric("loc_search_insns_per_cycle_max", r.insns_per_cycle[1].1);
    crate::metric("find_stack_bytes", r.stack_bytes as u64);
    let ok = s.mode == Mode::Tracking
        && s.score.final_position_m <= 0.3
        && s.score.final_heading_deg <= 10.0
        && l.handoffs >= 2
        && l.wakes >= 1;
    if ok {
        hprintln!("find: found itself, was carried, noticed, and found itself again");
    } else {
        hprintln!("FAIL: the localizer did not find itself again (see the lines above)");
    }
    ok
}
