//! The ring through embedded-hal-mock pins and a scripted clock: the firing
//! schedule, a full cycle in order on its slot times, faults on single slots,
//! pin errors, late polls (the ring-down gap kept, EERUF held back), and
//! crosstalk rejected by EERUF's alternating delays (with the counter-case
//! that shows the delays are what does it). Every pin operation is logged
//! across pins and checked against the ping protocol, and the pings the pins
//! saw must be the readings' pings with the ring-down gap after each window.

#[path = "common/driver_support.rs"]
mod support;

use echoloc::driver::{
    ConfigError, Eeruf, Error, Fault, Module, ModuleConfig, Outcome, Ring, RingConfig, RingReading, Schedule,
    SpeedOfSound,
};
use embedded_hal_mock::eh1::digital::{State, Transaction as T};
use support::{
    assert_gaps, init_pings, late_limit_ref_us, pin_error, reads, tof_ref_us, window_ref_us, writes, EchoSpec, Expect,
    Fired, MockClock, Pins, RecPin, Rig, Scripts, Step,
};

type R<'c, const A: usize, const N: usize> = Ring<RecPin<'c>, RecPin<'c>, RecPin<'c>, RecPin<'c>, &'c MockClock, A, N>;

const TC: i16 = 2000;

fn module_cfg(max_range_mm: u32) -> ModuleConfig {
    ModuleConfig { max_range_mm, ..ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(TC).unwrap()) }
}

fn build<'c, const A: usize, const N: usize>(
    pins: &Pins<'c, A>,
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
#[derive(Clone, Copy)]
struct Plan {
    origin: u32,
    n: u32,
    slot: u32,
    alt: u32,
    late_limit: u32,
}

impl Plan {
    /// `eeruf`: step and tolerance.
    fn new(origin: u32, n: usize, max_range_mm: u32, ring_down_us: u32, eeruf: Option<(u32, u32)>) -> Self {
        let (alt, late_limit) = eeruf.map_or((0, 0), |(alt, tol)| (alt, late_limit_ref_us(alt, tol, TC)));
        Self { origin, n: n as u32, slot: window_ref_us(max_range_mm, TC) + ring_down_us + late_limit, alt, late_limit }
    }
    fn offset(&self, cycle: u32, slot: u32) -> u32 {
        let period = self.n * (self.slot + self.alt);
        let shift = if cycle % 2 == 1 { (slot + 1) * self.alt } else { 0 };
        cycle * period + slot * self.slot + shift
    }
    fn fire(&self, cycle: u32, slot: u32) -> u32 {
        self.origin.wrapping_add(self.offset(cycle, slot))
    }
    /// The slot fires `late` µs after its time: the documented rule moves
    /// the schedule onto the firing when that is beyond the late limit.
    /// Returns the firing time.
    fn fire_late(&mut self, cycle: u32, slot: u32, late: u32) -> u32 {
        let f = self.fire(cycle, slot) + late;
        if late > self.late_limit {
            self.origin = f - self.offset(cycle, slot);
        }
        f
    }
}

/// The pings the pins saw are the readings' pings (a faulted slot fires
/// nothing), on the readings' times, each followed by the ring-down gap.
fn check_fired(fired: &[Fired], readings: &[RingReading], window: u32, ring_down: u32) {
    let pinged: Vec<(u8, u32)> = readings
        .iter()
        .filter(|r| !matches!(r.outcome, Outcome::Fault(Fault::EchoStuckHigh)))
        .map(|r| (r.transducer, r.fired_at_us))
        .collect();
    assert_eq!(fired.iter().map(|f| (f.transducer, f.at)).collect::<Vec<_>>(), pinged);
    assert_gaps(fired, window, ring_down);
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
    let plan = Plan::new(3_000, N, rmax, ring_down, Some((alt, 50)));
    let mut rig = Rig::new(4, window_ref_us(rmax, TC), None);
    for k in 0..2 {
        for j in 0..N {
            let t = order[j];
            let echo = world[t as usize].map_or(EchoSpec::Never, |r| EchoSpec::At(tof_ref_us(f64::from(r), TC)));
            rig.ring_ping(plan.fire(k, j as u32), t, echo, Some(order[(j + 1) % N]));
        }
    }
    let (scripts, steps) = rig.take();
    let clock = MockClock::at(0);
    let mut pins = Pins::<4>::new(&scripts, &clock);
    let cfg = RingConfig { ring_down_us: ring_down, eeruf: Some(Eeruf { alternating_us: alt, tolerance_mm: 50 }) };
    let mut ring = build::<4, N>(&pins, &clock, module_cfg(rmax), cfg);
    assert_eq!(ring.timing().late_limit_us(), plan.late_limit);
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
        assert_eq!(r.late_us, 0);
    }
    drop(ring);
    check_fired(&pins.done(), &readings, window_ref_us(rmax, TC), ring_down);
}

#[test]
fn faults_on_single_slots_keep_the_schedule() {
    const N: usize = 4;
    let (rmax, ring_down, alt) = (3_000, 2_000, 1_000);
    let plan = Plan::new(0, N, rmax, ring_down, Some((alt, 50)));
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
    let clock = MockClock::at(0);
    let mut pins = Pins::<2>::new(&scripts, &clock);
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
    check_fired(&pins.done(), &readings, window_ref_us(rmax, TC), ring_down);
}

#[test]
fn pin_error_from_set_high_retries_the_slot_and_late_polls_reanchor() {
    const N: usize = 2;
    let (rmax, ring_down) = (3_000, 2_000);
    let window = window_ref_us(rmax, TC);
    // Without EERUF the late limit is 0: the slot is window + ring-down.
    let slot = window + ring_down;
    let tof = tof_ref_us(1_500.0, TC);
    let err = pin_error();
    // Fire 0, its echo, fire 1 (fails), fire 1 again, fire 0 late; the
    // echoes of the last two come by input capture, not by reading ECHO.
    let mut init = init_pings(1);
    init.extend([T::set(State::High).with_error(err.clone()), T::set(State::Low)]);
    init.extend(init_pings(2));
    // Line 0 selects 0, then 1 during the first gap, then 0, then 1 again.
    let s = Scripts { echo: reads("LHLLL"), init, binh: Vec::new(), addr: vec![writes("LHLH")] };
    let clock = MockClock::at(100);
    let mut pins = Pins::<1>::new(&s, &clock);
    let mut ring = build::<1, N>(&pins, &clock, module_cfg(rmax), RingConfig { ring_down_us: ring_down, eeruf: None });
    assert_eq!(ring.timing().late_limit_us(), 0);
    assert_eq!(ring.timing().slot_us(), slot);
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
    assert_eq!((r.transducer, r.fired_at_us, r.late_us), (1, 100 + slot + 10, 10));
    assert_eq!(r.outcome, Outcome::Range { range_mm: 1_500, tof_us: tof });
    // Without EERUF nothing needs the pattern: the schedule follows the
    // late firing, and the next ping is a whole slot after it.
    assert_eq!(ring.next_fire_us(), Some(100 + 2 * slot + 10));
    // Polled three slots late: the schedule moves on instead of bursting.
    let late = 100 + 5 * slot;
    clock.set(late);
    assert_eq!(ring.poll(), Ok(None));
    assert_eq!(ring.next_fire_us(), Some(late));
    let r = ring.echo_captured(late + tof).unwrap();
    assert_eq!((r.cycle, r.late_us), (1, 3 * slot - 10));
    assert_eq!(ring.next_fire_us(), Some(late + slot));
    drop(ring);
    let fired = pins.done();
    assert_eq!(fired.iter().map(|f| (f.transducer, f.at)).collect::<Vec<_>>(), [(0, 100), (1, 110 + slot), (0, late)]);
    assert_gaps(&fired, window, ring_down);
}

/// A reflection of one transducer's ping that reaches another.
struct Ghost {
    from: u8,
    to: u8,
    after_us: u32,
}

const RMAX: u32 = 3_000;
const RING_DOWN: u32 = 2_000;

/// Simulate `cycles` cycles of an `N`-transducer ring with `A` address lines
/// in a world where transducer `t` sees its own wall at `own[t]` mm and the
/// `ghosts` arrive inside other transducers' windows; `late` lists the
/// slots `(cycle, slot, µs)` first polled that late. The ghosts are placed
/// by the actual firing times, which follow the documented rule for late
/// slots. Returns, per reading, whether its echo was a ghost, and the
/// readings; checks the pins' protocol, pings and gaps on the way.
fn simulate<const A: usize, const N: usize>(
    own: [Option<u32>; N],
    ghosts: &[Ghost],
    eeruf: Option<Eeruf>,
    late: &[(u32, u32, u32)],
    cycles: u32,
) -> Vec<(bool, RingReading)> {
    let order = *Schedule::<N>::spread().order();
    let window = window_ref_us(RMAX, TC);
    let blanking = echoloc::driver::POLAROID_BLANKING_US;
    let mut plan = Plan::new(50_000, N, RMAX, RING_DOWN, eeruf.map(|e| (e.alternating_us, e.tolerance_mm)));
    let mut fired: Vec<(u32, u8)> = Vec::new();
    let mut from_ghost = Vec::new();
    let mut rig = Rig::new(A, window, None);
    for k in 0..cycles {
        for j in 0..N {
            let t = order[j];
            let l = late.iter().find(|x| (x.0, x.1) == (k, j as u32)).map_or(0, |x| x.2);
            let f = plan.fire_late(k, j as u32, l);
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
            if l > 0 {
                rig.late_ring_ping(f, t, echo, Some(order[(j + 1) % N]));
            } else {
                rig.ring_ping(f, t, echo, Some(order[(j + 1) % N]));
            }
            fired.push((f, t));
        }
    }
    let (scripts, steps) = rig.take();
    let clock = MockClock::at(0);
    let mut pins = Pins::<A>::new(&scripts, &clock);
    let mut ring = build::<A, N>(&pins, &clock, module_cfg(RMAX), RingConfig { ring_down_us: RING_DOWN, eeruf });
    assert_eq!(ring.timing().slot_us(), plan.slot);
    let readings = run(&mut ring, &clock, &steps);
    drop(ring);
    check_fired(&pins.done(), &readings, window, RING_DOWN);
    from_ghost.into_iter().zip(readings).collect()
}

/// 4 cycles of an 8-transducer ring in which two ghosts arrive inside other
/// transducers' windows.
fn crosstalk_run(eeruf: Option<Eeruf>) -> Vec<(bool, RingReading)> {
    let own = [Some(2_000), Some(2_500), Some(2_500), Some(1_500), Some(2_500), Some(2_500), None, Some(2_500)];
    let ghosts = [Ghost { from: 3, to: 6, after_us: 24_000 }, Ghost { from: 5, to: 0, after_us: 25_000 }];
    simulate::<3, 8>(own, &ghosts, eeruf, &[], 4)
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
    // The late limit (352 µs) is part of every slot.
    assert_eq!(rt.late_limit_us(), late_limit_ref_us(1_000, 50, TC));
    assert_eq!(rt.late_limit_us(), 352);
    assert_eq!(rt.period_us(), 24 * (t.window_us() + 3_000 + 352 + 1_000));
    // The shortest step that moves a range past 50 mm: 295 µs (50.6 mm).
    let edge =
        |alternating_us| RingConfig { ring_down_us: 3_000, eeruf: Some(Eeruf { alternating_us, tolerance_mm: 50 }) };
    assert_eq!(edge(295).timing::<24>(&t).map(|r| r.late_limit_us()), Ok(0));
    assert_eq!(edge(294).timing::<24>(&t), Err(ConfigError::AlternatingDelay));
}

const EERUF: Eeruf = Eeruf { alternating_us: 1_000, tolerance_mm: 50 };

#[test]
fn a_late_poll_keeps_the_ring_down_gap_and_holds_eeruf_back() {
    // Four transducers, each with a wall at 1 m. In cycle 1, slot 2 is first
    // polled 5 ms late: more than the ring-down gap (2 ms), less than a slot
    // (19.8 ms). In cycle 3, slot 0 is polled 300 µs late, within the limit.
    const N: usize = 4;
    let own = [Some(1_000); N];
    let late = [(1, 2, 5_000), (3, 0, 300)];
    let run = simulate::<2, N>(own, &[], Some(EERUF), &late, 5);
    let window = window_ref_us(RMAX, TC);
    let slot = window + RING_DOWN + late_limit_ref_us(1_000, 50, TC);
    let at = |k: usize, j: usize| run[k * N + j].1;
    // The late ping says how late it was, and the next one comes a whole
    // slot (+ the odd cycle's step) after it: the full gap after its window
    // (check_fired in simulate asserts every gap from the pins' log).
    assert_eq!(at(1, 2).late_us, 5_000);
    assert_eq!(at(1, 3).fired_at_us - at(1, 2).fired_at_us, slot + EERUF.alternating_us);
    assert_eq!(at(1, 3).late_us, 0);
    // Within the limit the pattern holds: the next slot is on its old time.
    assert_eq!(at(3, 0).late_us, 300);
    assert_eq!(at(3, 1).fired_at_us - at(3, 0).fired_at_us, slot + EERUF.alternating_us - 300);
    // EERUF: the re-anchored slot and the N - 1 after it neither confirm nor
    // are kept; their successors have nothing to compare with; after that,
    // confirmations resume. The 300 µs late slot changes nothing.
    let kinds: Vec<char> = run
        .iter()
        .map(|(_, r)| match r.outcome {
            Outcome::Range { range_mm: 1_000, .. } => 'R',
            Outcome::Unconfirmed { range_mm: 1_000, .. } => 'u',
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(kinds.iter().collect::<String>(), "uuuu RRuu uuuu uuRR RRRR".replace(' ', ""));
}

#[test]
fn a_late_poll_cannot_make_a_ghost_look_steady() {
    // Transducer 0's ping reaches transducer 1 one slot and 5 ms later. On
    // time, the ghost moves by the step (172 mm) from cycle to cycle. In
    // cycle 1 (odd, so transducer 1 fires one step later than in even
    // cycles relative to 0) slot 0 is polled one step late: kept on the old
    // pattern, slot 1 would hear the ghost exactly where it was in cycle 0,
    // and EERUF would confirm it. The late limit re-anchors instead.
    let window = window_ref_us(RMAX, TC);
    let slot = window + RING_DOWN + late_limit_ref_us(1_000, 50, TC);
    let ghosts = [Ghost { from: 0, to: 1, after_us: slot + 5_000 }];
    let run = simulate::<1, 2>([Some(2_000), None], &ghosts, Some(EERUF), &[(1, 0, 1_000)], 3);
    let ghost: Vec<&RingReading> = run.iter().filter(|(g, _)| *g).map(|(_, r)| r).collect();
    assert_eq!(ghost.len(), 3, "{run:?}");
    assert!(ghost.iter().all(|r| r.transducer == 1 && r.outcome.accepted_mm().is_none()), "{ghost:?}");
    // The ghost still moved, because the schedule moved with the late slot.
    assert_ne!(ghost[0].outcome.echo_mm(), ghost[1].outcome.echo_mm());
}
