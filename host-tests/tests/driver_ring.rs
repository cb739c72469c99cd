//! The ring through embedded-hal-mock pins and a scripted clock: the firing
//! schedule, a full cycle in order on its slot times, faults on single slots,
//! pin errors, late polls, and crosstalk rejected by EERUF's alternating
//! delays (with the counter-case that shows the delays are what does it).

#[path = "driver_support.rs"]
mod support;

use echoloc::driver::{
    ConfigError, Eeruf, Error, Fault, Module, ModuleConfig, Outcome, Ring, RingConfig, RingReading, Schedule,
    SpeedOfSound,
};
use embedded_hal_mock::eh1::digital::{Mock, State, Transaction as T};
use support::{pin_error, tof_ref_us, window_ref_us, EchoSpec, Expect, MockClock, Pins, Rig, Step};

type R<'c, const A: usize, const N: usize> = Ring<Mock, Mock, Mock, Mock, &'c MockClock, A, N>;

const TC: i16 = 2000;

fn module_cfg(max_range_mm: u32) -> ModuleConfig {
    ModuleConfig { max_range_mm, ..ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(TC).unwrap()) }
}

fn build<'c, const A: usize, const N: usize>(
    pins: &Pins<A>,
    clock: &'c MockClock,
    cfg: ModuleConfig,
    ring: RingConfig,
) -> R<'c, A, N> {
    let t = cfg.timing().unwrap();
    let (echo, init, binh, addr) = pins.clones();
    let module = Module::new(init, echo, addr, clock, t).with_binh(binh);
    Ring::new(module, Schedule::spread(), ring.timing::<N>(&t).unwrap())
}

/// The documented slot times, computed here from the configuration alone.
struct Plan {
    origin: u32,
    n: u32,
    slot: u32,
    alt: u32,
}

impl Plan {
    fn new(origin: u32, n: usize, max_range_mm: u32, ring_down_us: u32, alt: u32) -> Self {
        Self { origin, n: n as u32, slot: window_ref_us(max_range_mm, TC) + ring_down_us, alt }
    }
    fn fire(&self, cycle: u32, slot: u32) -> u32 {
        let period = self.n * (self.slot + self.alt);
        let shift = if cycle % 2 == 1 { (slot + 1) * self.alt } else { 0 };
        self.origin.wrapping_add(cycle * period + slot * self.slot + shift)
    }
}

fn run<const A: usize, const N: usize>(ring: &mut R<'_, A, N>, clock: &MockClock, steps: &[Step]) -> Vec<RingReading> {
    let mut out = Vec::new();
    for s in steps {
        clock.set(s.at);
        let r = ring.poll().unwrap_or_else(|e| panic!("pin error at {}: {e:?}", s.at));
        match s.expect {
            Expect::Nothing => assert_eq!(r, None, "nothing expected at {}", s.at),
            Expect::Reading => out.push(r.unwrap_or_else(|| panic!("a reading expected at {}", s.at))),
        }
    }
    out
}

fn ring_distance(a: u8, b: u8, n: usize) -> usize {
    let d = (a as isize - b as isize).unsigned_abs() % n;
    d.min(n - d)
}

#[test]
fn schedule_keeps_neighbours_apart() {
    let s16 = Schedule::<16>::spread();
    assert_eq!(s16.order(), &[0, 3, 6, 9, 12, 15, 2, 5, 8, 11, 14, 1, 4, 7, 10, 13]);
    fn check<const N: usize>(s: &Schedule<N>, min_next: usize) {
        let o = s.order();
        let mut seen = [false; N];
        for j in 0..N {
            seen[o[j] as usize] = true;
            // The ping before is at least `min_next` positions away, and no
            // neighbour fires within four slots (across cycles too).
            assert!(ring_distance(o[j], o[(j + 1) % N], N) >= min_next);
            for m in 1..=4 {
                assert!(ring_distance(o[j], o[(j + m) % N], N) >= 2, "N={N} slot {j} +{m}");
            }
        }
        assert!(seen.iter().all(|&x| x));
    }
    check(&s16, 3);
    check(&Schedule::<24>::spread(), 5);
}

#[test]
fn full_cycle_in_scheduled_order_on_slot_times() {
    const N: usize = 16;
    let (rmax, ring_down, alt) = (5_500, 5_000, 1_000);
    let world: Vec<Option<u32>> = (0..N as u32).map(|i| (i % 6 != 5).then_some(600 + 250 * i)).collect();
    let sched = Schedule::<N>::spread();
    let order = *sched.order();
    let plan = Plan::new(3_000, N, rmax, ring_down, alt);
    let mut rig = Rig::new(4, window_ref_us(rmax, TC), None);
    for k in 0..2 {
        for j in 0..N {
            let t = order[j];
            let echo = world[t as usize].map_or(EchoSpec::Never, |r| EchoSpec::At(tof_ref_us(f64::from(r), TC)));
            rig.ring_ping(plan.fire(k, j as u32), t, echo, Some(order[(j + 1) % N]));
        }
    }
    let (scripts, steps) = rig.take();
    let mut pins = Pins::<4>::new(&scripts);
    let clock = MockClock::at(0);
    let cfg = RingConfig { ring_down_us: ring_down, eeruf: Some(Eeruf { alternating_us: alt, tolerance_mm: 50 }) };
    let mut ring = build::<4, N>(&pins, &clock, module_cfg(rmax), cfg);
    assert_eq!(ring.timing().slot_us(), plan.slot);
    assert_eq!(ring.next_fire_us(), None);
    let readings = run(&mut ring, &clock, &steps);
    assert_eq!(readings.len(), 2 * N);
    for (i, r) in readings.iter().enumerate() {
        let (k, j) = ((i / N) as u32, i % N);
        let t = order[j];
        assert_eq!((r.transducer, r.slot as usize, r.cycle), (t, j, k));
        assert_eq!(r.fired_at_us, plan.fire(k, j as u32), "slot {j} of cycle {k}");
        let want = match (world[t as usize], k) {
            (None, _) => Outcome::NoEcho,
            (Some(mm), 0) => Outcome::Unconfirmed { range_mm: mm, tof_us: tof_ref_us(f64::from(mm), TC) },
            (Some(mm), _) => Outcome::Range { range_mm: mm, tof_us: tof_ref_us(f64::from(mm), TC) },
        };
        assert_eq!(r.outcome, want, "transducer {t} cycle {k}");
    }
    drop(ring);
    pins.done();
}

#[test]
fn faults_on_single_slots_keep_the_schedule() {
    const N: usize = 4;
    let (rmax, ring_down, alt) = (3_000, 2_000, 1_000);
    let plan = Plan::new(0, N, rmax, ring_down, alt);
    let order = *Schedule::<N>::spread().order();
    assert_eq!(order, [0, 1, 2, 3]);
    let tof = tof_ref_us(1_000.0, TC);
    let mut rig = Rig::new(2, window_ref_us(rmax, TC), None);
    let cycle0 = [EchoSpec::At(tof), EchoSpec::StuckHigh, EchoSpec::At(1_000), EchoSpec::Never];
    for (j, e) in cycle0.into_iter().enumerate() {
        rig.ring_ping(plan.fire(0, j as u32), order[j], e, Some(order[(j + 1) % N]));
    }
    for j in 0..N {
        rig.ring_ping(plan.fire(1, j as u32), order[j], EchoSpec::At(tof), Some(order[(j + 1) % N]));
    }
    let (scripts, steps) = rig.take();
    let mut pins = Pins::<2>::new(&scripts);
    let clock = MockClock::at(0);
    let cfg = RingConfig { ring_down_us: ring_down, eeruf: Some(Eeruf { alternating_us: alt, tolerance_mm: 50 }) };
    let mut ring = build::<2, N>(&pins, &clock, module_cfg(rmax), cfg);
    let readings = run(&mut ring, &clock, &steps);
    let got: Vec<Outcome> = readings.iter().map(|r| r.outcome).collect();
    let un = Outcome::Unconfirmed { range_mm: 1_000, tof_us: tof };
    let ok = Outcome::Range { range_mm: 1_000, tof_us: tof };
    assert_eq!(
        got,
        vec![
            un,
            Outcome::Fault(Fault::EchoStuckHigh),
            Outcome::Fault(Fault::EchoInBlanking { tof_us: 1_000 }),
            Outcome::NoEcho,
            // Only transducer 0 has a reading from the cycle before to agree with.
            ok,
            un,
            un,
            un,
        ]
    );
    for (i, r) in readings.iter().enumerate() {
        assert_eq!(r.fired_at_us, plan.fire((i / N) as u32, (i % N) as u32));
    }
    drop(ring);
    pins.done();
}

#[test]
fn pin_error_from_set_high_retries_the_slot_and_late_polls_reanchor() {
    const N: usize = 2;
    let rmax = 3_000;
    let slot = window_ref_us(rmax, TC) + 2_000;
    let tof = tof_ref_us(1_500.0, TC);
    let err = pin_error();
    // Fire 0, its echo, fire 1 (fails), fire 1 again, fire 0 late; the
    // echoes of the last two come by input capture, not by reading ECHO.
    let echo = [T::get(State::Low), T::get(State::High), T::get(State::Low), T::get(State::Low), T::get(State::Low)];
    let init = [
        T::set(State::High),
        T::set(State::Low),
        T::set(State::High).with_error(err.clone()),
        T::set(State::Low),
        T::set(State::High),
        T::set(State::Low),
        T::set(State::High),
        T::set(State::Low),
    ];
    // Line 0 selects 0, then 1 during the first gap, then 0, then 1 again.
    let a0 = [T::set(State::Low), T::set(State::High), T::set(State::Low), T::set(State::High)];
    let mut pins =
        Pins::<1> { echo: Mock::new(&echo), init: Mock::new(&init), binh: Mock::new(&[]), addr: [Mock::new(&a0)] };
    let clock = MockClock::at(100);
    let mut ring = build::<1, N>(&pins, &clock, module_cfg(rmax), RingConfig { ring_down_us: 2_000, eeruf: None });
    assert_eq!(ring.poll(), Ok(None)); // fires transducer 0 at 100
    clock.set(100 + tof);
    let r = ring.poll().unwrap().unwrap();
    assert_eq!((r.transducer, r.outcome), (0, Outcome::Range { range_mm: 1_500, tof_us: tof }));
    assert_eq!(ring.next_fire_us(), Some(100 + slot));
    clock.set(100 + slot);
    assert_eq!(ring.poll(), Err(Error::Pin(err)));
    // The same slot is still due and fires at the next poll.
    clock.set(100 + slot + 10);
    assert_eq!(ring.poll(), Ok(None));
    // Captured edge instead of polling.
    let r = ring.echo_captured(100 + slot + 10 + tof).unwrap();
    assert_eq!((r.transducer, r.fired_at_us), (1, 100 + slot + 10));
    assert_eq!(r.outcome, Outcome::Range { range_mm: 1_500, tof_us: tof });
    // The slot pattern stays anchored to the schedule, not the late firing.
    assert_eq!(ring.next_fire_us(), Some(100 + 2 * slot));
    // Polled three slots late: the schedule moves on instead of bursting.
    let late = 100 + 5 * slot;
    clock.set(late);
    assert_eq!(ring.poll(), Ok(None));
    assert_eq!(ring.next_fire_us(), Some(late));
    assert_eq!(ring.echo_captured(late + tof).unwrap().cycle, 1);
    assert_eq!(ring.next_fire_us(), Some(late + slot));
    drop(ring);
    pins.done();
}

/// A reflection of one transducer's ping that reaches another.
struct Ghost {
    from: u8,
    to: u8,
    after_us: u32,
}

/// Simulate 4 cycles of an 8-transducer ring in which two ghosts arrive
/// inside other transducers' windows. Returns, per reading, whether its echo
/// was a ghost, and the readings.
fn crosstalk_run(eeruf: Option<Eeruf>) -> Vec<(bool, RingReading)> {
    const N: usize = 8;
    let (rmax, ring_down) = (3_000, 2_000);
    let alt = eeruf.map_or(0, |e| e.alternating_us);
    let own: [Option<u32>; N] =
        [Some(2_000), Some(2_500), Some(2_500), Some(1_500), Some(2_500), Some(2_500), None, Some(2_500)];
    let ghosts = [Ghost { from: 3, to: 6, after_us: 24_000 }, Ghost { from: 5, to: 0, after_us: 25_000 }];
    let order = *Schedule::<N>::spread().order();
    let window = window_ref_us(rmax, TC);
    let blanking = echoloc::driver::POLAROID_BLANKING_US;
    let plan = Plan::new(50_000, N, rmax, ring_down, alt);
    let mut fired: Vec<(u32, u8)> = Vec::new();
    let mut from_ghost = Vec::new();
    let mut rig = Rig::new(3, window, None);
    for k in 0..4 {
        for j in 0..N {
            let t = order[j];
            let f = plan.fire(k, j as u32);
            let mut best: Option<(u32, bool)> = own[t as usize].map(|mm| (tof_ref_us(f64::from(mm), TC), false));
            for g in ghosts.iter().filter(|g| g.to == t) {
                for &(at, src) in &fired {
                    let arrive = at + g.after_us;
                    // The module hears it only after its own blanking.
                    if src == g.from && arrive >= f + blanking && arrive <= f + window {
                        let x = arrive - f;
                        if best.is_none_or(|(b, _)| x < b) {
                            best = Some((x, true));
                        }
                    }
                }
            }
            from_ghost.push(best.is_some_and(|(_, g)| g));
            let echo = best.map_or(EchoSpec::Never, |(x, _)| EchoSpec::At(x));
            rig.ring_ping(f, t, echo, Some(order[(j + 1) % N]));
            fired.push((f, t));
        }
    }
    let (scripts, steps) = rig.take();
    let mut pins = Pins::<3>::new(&scripts);
    let clock = MockClock::at(0);
    let mut ring = build::<3, N>(&pins, &clock, module_cfg(rmax), RingConfig { ring_down_us: ring_down, eeruf });
    let readings = run(&mut ring, &clock, &steps);
    drop(ring);
    pins.done();
    from_ghost.into_iter().zip(readings).collect()
}

#[test]
fn crosstalk_is_rejected_by_alternating_delays() {
    let eeruf = Eeruf { alternating_us: 1_000, tolerance_mm: 50 };
    let run = crosstalk_run(Some(eeruf));
    let ghosts = run.iter().filter(|(g, _)| *g).count();
    assert!(ghosts >= 5, "the scenario must produce ghosts, got {ghosts}");
    for (ghost, r) in &run {
        if *ghost {
            // A ghost is never accepted: first seen it is unconfirmed, and
            // after that it has moved by the alternating delay (≈172 mm).
            assert_eq!(r.outcome.accepted_mm(), None, "ghost accepted: {r:?}");
        }
    }
    // The ghost on transducer 6 moves by one step of delay per cycle.
    let six: Vec<u32> =
        run.iter().filter(|(_, r)| r.transducer == 6).filter_map(|(_, r)| r.outcome.echo_mm()).collect();
    assert_eq!(six.len(), 4);
    println!("ghost on transducer 6 with EERUF, mm per cycle: {six:?}");
    for w in six.windows(2) {
        assert!(w[0].abs_diff(w[1]) > eeruf.tolerance_mm, "{six:?}");
        assert!(w[0].abs_diff(w[1]) <= 172, "{six:?}");
    }
    assert!(run
        .iter()
        .filter(|(_, r)| r.transducer == 6)
        .skip(1)
        .all(|(_, r)| matches!(r.outcome, Outcome::Crosstalk { .. })));
    // True echoes without a ghost next to them are confirmed from cycle 1 on.
    let confirmed: Vec<&RingReading> =
        run.iter().map(|(_, r)| r).filter(|r| r.outcome.accepted_mm().is_some()).collect();
    assert_eq!(confirmed.len(), 3 * 6 + 1, "6 clean transducers × 3 cycles, and transducer 0 in cycle 1");
    let truth = [2_000, 2_500, 2_500, 1_500, 2_500, 2_500, 0, 2_500];
    assert!(confirmed.iter().all(|r| r.outcome.accepted_mm() == Some(truth[r.transducer as usize])));
}

#[test]
fn without_alternating_delays_the_ghost_looks_steady() {
    // Same world, no EERUF: the ghost on transducer 6 comes back at the same
    // range every cycle, so comparing consecutive readings alone could never
    // reject it: the alternating delays are what exposes it.
    let run = crosstalk_run(None);
    let six: Vec<u32> =
        run.iter().filter(|(_, r)| r.transducer == 6).filter_map(|(_, r)| r.outcome.accepted_mm()).collect();
    assert_eq!(six.len(), 4);
    println!("ghost on transducer 6 without EERUF, mm per cycle: {six:?}");
    assert!(six.iter().all(|&mm| mm == six[0]), "{six:?}");
    assert!(run.iter().filter(|(g, _)| *g).all(|(_, r)| r.outcome.accepted_mm().is_some()));
}

#[test]
fn ring_configs_are_checked() {
    let t = module_cfg(5_500).timing().unwrap();
    let short = RingConfig { ring_down_us: 1_000, eeruf: Some(Eeruf { alternating_us: 200, tolerance_mm: 50 }) };
    assert_eq!(short.timing::<16>(&t), Err(ConfigError::AlternatingDelay));
    let zero = RingConfig { ring_down_us: 1_000, eeruf: Some(Eeruf { alternating_us: 0, tolerance_mm: 0 }) };
    assert_eq!(zero.timing::<16>(&t), Err(ConfigError::AlternatingDelay));
    assert_eq!(RingConfig { ring_down_us: 1_000_001, eeruf: None }.timing::<16>(&t), Err(ConfigError::RingDown));
    assert_eq!(RingConfig { ring_down_us: 1_000_000, eeruf: None }.timing::<4096>(&t), Err(ConfigError::CycleTooLong));
    let ok = RingConfig { ring_down_us: 3_000, eeruf: Some(Eeruf { alternating_us: 1_000, tolerance_mm: 50 }) };
    let rt = ok.timing::<24>(&t).unwrap();
    assert_eq!(rt.period_us(), 24 * (t.window_us() + 3_000 + 1_000));
}
