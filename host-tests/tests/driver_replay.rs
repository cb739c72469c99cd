//! Replay of real sonar data through the driver: the 5,456 readings of the
//! SCITOS G5's 24-sonar ring in `shared/data/sonar/scitos-g5-ring24.csv`
//! (UCI "Wall-Following Robot Navigation", CC BY 4.0), each range turned into
//! an ECHO edge at its round-trip time, fired through embedded-hal-mock pins
//! and the scripted clock in the ring's firing order, one CSV row per ring
//! cycle. Every range must come back to the clock's resolution, and readings
//! at the logger's 5.000 m clip (its "nothing heard") as no echo.

#[path = "common/driver_support.rs"]
mod support;

use echoloc::driver::{Eeruf, Module, ModuleConfig, Outcome, Ring, RingConfig, Schedule, SpeedOfSound};
use support::{
    assert_gaps, late_limit_ref_us, tof_ref_us, window_ref_us, EchoSpec, Expect, MockClock, Pins, Rig, Scripts,
};

const N: usize = 24;
const A: usize = 5;
/// No temperature is logged with the data: replay at 20 °C.
const TC: i16 = 2000;
const CLIP_MM: u32 = 5_000;
const RMAX_MM: u32 = 5_500;
const RING_DOWN_US: u32 = 3_000;
const BINH_US: u32 = 1_000;
const EERUF: Eeruf = Eeruf { alternating_us: 1_000, tolerance_mm: 50 };

fn load() -> Vec<[u32; N]> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/sonar/scitos-g5-ring24.csv");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), N + 1, "line {}", i + 1);
        let mut row = [0u32; N];
        for (k, v) in f[..N].iter().enumerate() {
            let m: f64 = v.trim().parse().unwrap_or_else(|e| panic!("line {}: {v}: {e}", i + 1));
            // Three decimals in metres: whole millimetres.
            row[k] = (m * 1000.0).round() as u32;
        }
        rows.push(row);
    }
    rows
}

#[derive(Debug, Default)]
struct Figures {
    readings: usize,
    echoes: usize,
    clipped: usize,
    exact: usize,
    max_err_mm: u32,
    sum_err_mm: u64,
    confirmed: usize,
    unconfirmed: usize,
    crosstalk: usize,
    no_echo: usize,
}

/// Replay every row through a 24-transducer ring whose clock reads in
/// multiples of `tick` µs; returns the figures.
fn replay(tick: u32) -> Figures {
    let rows = load();
    assert_eq!(rows.len(), 5_456);
    let sound = SpeedOfSound::at_centi_celsius(TC).unwrap();
    let cfg = ModuleConfig { binh_after_us: Some(BINH_US), ..ModuleConfig::polaroid_6500(sound) };
    assert_eq!(cfg.max_range_mm, RMAX_MM);
    let timing = cfg.timing().unwrap();
    let window = window_ref_us(RMAX_MM, TC);
    assert_eq!(timing.window_us(), window);
    let rt = RingConfig { ring_down_us: RING_DOWN_US, eeruf: Some(EERUF) }.timing::<N>(&timing).unwrap();
    let sched = Schedule::<N>::spread();
    let order = *sched.order();

    // Start 30 s before the 32-bit µs clock wraps; the replay lasts about
    // 79 minutes of ring time, so it wraps twice.
    let origin = (u32::MAX - 30_000_000) / 64 * 64;
    let clock = MockClock::at(origin);
    clock.resolution(tick);
    let mut pins = Pins::<A>::new(&Scripts { addr: vec![Vec::new(); A], ..Scripts::default() }, &clock);
    let (echo, init, binh, addr) = pins.clones();
    let module = Module::new(init, echo, addr, &clock, timing).with_binh(binh);
    let mut ring = Ring::new(module, sched, rt);

    // The documented slot times, from the configuration alone.
    let late_limit = late_limit_ref_us(EERUF.alternating_us, EERUF.tolerance_mm, TC);
    assert_eq!(rt.late_limit_us(), late_limit);
    let slot = u64::from(window + RING_DOWN_US + late_limit);
    let alt = u64::from(EERUF.alternating_us);
    let period = N as u64 * (slot + alt);
    let due = |k: u64, j: u64| -> u32 {
        let shift = if k % 2 == 1 { (j + 1) * alt } else { 0 };
        (u64::from(origin) + k * period + j * slot + shift) as u32
    };

    let c_mm_per_us = support::c_ref(TC) / 1000.0;
    let bound_mm = (f64::from(tick) * c_mm_per_us / 2.0 + 0.5).ceil() as u32;
    let mut rig = Rig::new(A, window, Some(BINH_US)).with_tick(tick);
    let mut fig = Figures::default();
    for (k, row) in rows.iter().enumerate() {
        let mut fires = [0u32; N];
        for j in 0..N {
            let t = order[j];
            let mm = row[t as usize];
            let echo = if mm == CLIP_MM { EchoSpec::Never } else { EchoSpec::At(tof_ref_us(f64::from(mm), TC)) };
            // The firing poll comes at the first clock reading at or after
            // the slot's time.
            let f = rig.ceil_tick(due(k as u64, j as u64));
            fires[j] = f;
            rig.ring_ping(f, t, echo, Some(order[(j + 1) % N]));
        }
        let (scripts, steps) = rig.take();
        // Panics unless the previous row used up its scripts exactly.
        pins.reload(&scripts);
        let mut got = Vec::with_capacity(N);
        for s in &steps {
            clock.set(s.at);
            let r = ring.poll().unwrap_or_else(|e| panic!("row {k}: pin error {e:?}"));
            match s.expect {
                Expect::Nothing => assert_eq!(r, None, "row {k} at {}", s.at),
                Expect::Reading => got.push(r.unwrap_or_else(|| panic!("row {k}: no reading at {}", s.at))),
            }
        }
        assert_eq!(got.len(), N, "row {k}");
        // The pins, in order across all of them: the protocol kept, the
        // pings where the readings say, the ring-down gap after each window.
        let fired = pins.check();
        assert_eq!(fired.iter().map(|f| f.at).collect::<Vec<_>>(), fires, "row {k}");
        assert_gaps(&fired, window, RING_DOWN_US);
        for (j, r) in got.iter().enumerate() {
            let t = order[j];
            let mm = row[t as usize];
            assert_eq!((r.transducer, r.slot as usize, r.cycle), (t, j, k as u32), "row {k}");
            assert_eq!(r.fired_at_us, fires[j], "row {k} slot {j}");
            // Late only by the clock's resolution, well within the limit.
            assert!(r.late_us < tick && r.late_us <= late_limit, "row {k} slot {j}: {} µs late", r.late_us);
            fig.readings += 1;
            match r.outcome {
                Outcome::Range { .. } => fig.confirmed += 1,
                Outcome::Unconfirmed { .. } => fig.unconfirmed += 1,
                Outcome::Crosstalk { .. } => fig.crosstalk += 1,
                Outcome::NoEcho => fig.no_echo += 1,
                Outcome::Untimed { .. } => panic!("row {k} S{}: untimed {:?}", t + 1, r.outcome),
                Outcome::Fault(f) => panic!("row {k} S{}: fault {f:?}", t + 1),
            }
            if mm == CLIP_MM {
                fig.clipped += 1;
                assert_eq!(r.outcome, Outcome::NoEcho, "row {k} S{}: clipped reading", t + 1);
                continue;
            }
            let back = r.outcome.echo_mm().unwrap_or_else(|| panic!("row {k} S{} {mm} mm: {:?}", t + 1, r.outcome));
            let err = back.abs_diff(mm);
            assert!(err <= bound_mm, "row {k} S{}: {mm} mm came back as {back} (tick {tick} µs)", t + 1);
            fig.echoes += 1;
            fig.exact += usize::from(err == 0);
            fig.max_err_mm = fig.max_err_mm.max(err);
            fig.sum_err_mm += u64::from(err);
        }
    }
    drop(ring);
    pins.done();
    assert!(clock.now() < origin, "the replay must cross the clock's wrap");
    fig
}

#[test]
fn replay_scitos_ring_at_1us_gets_every_millimetre_back() {
    let fig = replay(1);
    println!("1 µs clock: {fig:?}");
    assert_eq!(fig.readings, 5_456 * N);
    assert_eq!(fig.clipped, 18_081);
    assert_eq!(fig.no_echo, fig.clipped);
    // At 1 µs the edge moves the range by < 0.09 mm: every millimetre exact.
    assert_eq!(fig.exact, fig.echoes);
    assert_eq!(fig.echoes + fig.clipped, fig.readings);
}

#[test]
fn replay_scitos_ring_at_64us_stays_within_the_clock_resolution() {
    // A 15.625 kHz timer: 64 µs ≈ 11 mm of range per count.
    let fig = replay(64);
    println!("64 µs clock: {fig:?}, mean error {:.2} mm", fig.sum_err_mm as f64 / fig.echoes as f64);
    assert_eq!(fig.no_echo, fig.clipped);
    assert!(fig.max_err_mm <= 12);
    // Floored counts lose on average half a count, ≈ 5.5 mm.
    let mean = fig.sum_err_mm as f64 / fig.echoes as f64;
    assert!((4.0..7.0).contains(&mean), "mean {mean}");
}
