//! One ranging module through embedded-hal-mock pins and a scripted clock:
//! ranges, temperatures, no echo, stuck ECHO, echo in blanking, BINH, pin
//! errors, late polls, input capture and the bounded blocking wait. Every
//! pin operation is also logged across pins and checked against the ping
//! protocol (`Protocol` in the support module).

#[path = "common/driver_support.rs"]
mod support;
#[path = "common/driver_support_self_tests.rs"]
mod support_self_tests;

use echoloc::driver::{ConfigError, Echo, Error, Fault, Module, ModuleConfig, NoPin, SpeedOfSound, Timing};
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::digital::{State, Transaction as T};
use embedded_hal_mock::eh1::MockError;
use support::{
    c_ref, init_pings, pin_error, reads, tof_ref_us, window_ref_us, writes, Fired, MockClock, Pins, RecPin, Scripts,
};

type M<'c> = Module<RecPin<'c>, RecPin<'c>, NoPin<MockError>, RecPin<'c>, &'c MockClock, 2>;

fn timing(centi_c: i16) -> Timing {
    ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(centi_c).unwrap()).timing().unwrap()
}

/// A module's pins (two address lines, BINH scripted but unused unless a
/// test wires it) on the test's clock.
struct Bench<'c> {
    pins: Pins<'c, 2>,
    clock: &'c MockClock,
}

impl<'c> Bench<'c> {
    fn new(clock: &'c MockClock, echo: &[T], init: &[T], a0: &[T], a1: &[T]) -> Self {
        let s = Scripts {
            echo: echo.to_vec(),
            init: init.to_vec(),
            binh: Vec::new(),
            addr: vec![a0.to_vec(), a1.to_vec()],
        };
        Self { pins: Pins::new(&s, clock), clock }
    }
    fn module(&self, t: Timing) -> M<'c> {
        let (echo, init, _, addr) = self.pins.clones();
        Module::new(init, echo, addr, self.clock, t)
    }
    /// Scripts used up, protocol kept, INIT low at the end; the pings fired.
    fn done(mut self) -> Vec<Fired> {
        self.pins.done()
    }
}

/// Fire `transducer` at the clock's time `at` and see the echo `tof` µs
/// later: the range must come back as `range_mm`.
fn ping_ok(m: &mut M<'_>, clock: &MockClock, transducer: u8, at: u32, tof: u32, range_mm: u32) {
    clock.set(at);
    assert_eq!(m.start(transducer), Ok(at));
    clock.set(at + tof);
    assert_eq!(m.poll(), Ok(Some(Echo::Range { range_mm, tof_us: tof })));
    assert!(m.is_idle());
}

/// Where the pings went and when, as the pins saw them.
fn fired(f: &[Fired]) -> Vec<(u8, u32)> {
    f.iter().map(|f| (f.transducer, f.at)).collect()
}

#[test]
fn normal_pings_at_several_ranges_and_temperatures() {
    let temps = [-2000i16, 0, 2000, 3500];
    let ranges = [450u32, 1234, 3000, 5400];
    let n = temps.len() * ranges.len();
    // Each ping: ECHO low before, low just before the echo, high at it.
    let echo = reads(&"LLH".repeat(n));
    // Transducer 2 = lines (low, high), written once: later pings reuse them.
    let clock = MockClock::at(1_000);
    let bench = Bench::new(&clock, &echo, &init_pings(n), &writes("L"), &writes("H"));
    for &tc in &temps {
        let mut m = bench.module(timing(tc));
        for &r in &ranges {
            let tof = tof_ref_us(f64::from(r), tc);
            let t0 = clock.now();
            assert_eq!(m.start(2), Ok(t0));
            clock.set(t0 + tof - 1);
            assert_eq!(m.poll(), Ok(None), "{tc} {r}");
            clock.set(t0 + tof);
            // The µs rounding of the echo time moves the range by < 0.09 mm,
            // so the millimetre comes back exactly.
            assert_eq!(m.poll(), Ok(Some(Echo::Range { range_mm: r, tof_us: tof })), "T={tc} cC R={r} mm");
            assert!(m.is_idle());
            clock.advance(50_000);
        }
        let _ = m.destroy();
        if tc != *temps.last().unwrap() {
            // The next temperature is a fresh driver on the same pins: it
            // does not know the lines and writes them all on its first ping.
            bench.pins.addr[0].clone().update_expectations(&writes("L"));
            bench.pins.addr[1].clone().update_expectations(&writes("H"));
        }
    }
    let f = bench.done();
    assert_eq!(f.len(), n);
    assert!(f.iter().all(|f| f.transducer == 2 && f.ended_at.is_some()));
}

#[test]
fn range_matches_the_formula_everywhere() {
    // Every time of flight from blanking to 5.5 m at five temperatures:
    // integer driver vs the f64 formula, within half a millimetre.
    for tc in [-4000i16, -1000, 2000, 4000, 8500] {
        let c = SpeedOfSound::at_centi_celsius(tc).unwrap();
        let c_mm_per_us = c_ref(tc) / 1000.0;
        let mut worst = 0f64;
        for tof in (2_380u32..40_000).step_by(3) {
            let exact = f64::from(tof) * c_mm_per_us / 2.0;
            worst = worst.max((f64::from(c.range_mm(tof)) - exact).abs());
        }
        assert!(worst <= 0.5 + 1e-3, "T={tc}: worst {worst} mm");
    }
}

#[test]
fn no_echo_ends_with_the_window() {
    let t = timing(2000);
    let w = t.window_us();
    assert_eq!(w, window_ref_us(5_500, 2000));
    let clock = MockClock::at(u32::MAX - 10_000); // the window crosses the clock's wrap
    let bench = Bench::new(&clock, &reads("LLLL"), &init_pings(1), &writes("H"), &writes("H"));
    let mut m = bench.module(t);
    let t0 = m.start(3).unwrap();
    clock.set(t0.wrapping_add(w / 2));
    assert_eq!(m.poll(), Ok(None));
    clock.set(t0.wrapping_add(w - 1));
    assert_eq!(m.poll(), Ok(None));
    clock.set(t0.wrapping_add(w));
    assert_eq!(m.poll(), Ok(Some(Echo::NoEcho)));
    assert_eq!(m.poll(), Err(Error::Idle));
    let _ = m.destroy();
    let f = bench.done();
    assert_eq!(f.len(), 1);
    assert_eq!((f[0].transducer, f[0].ended_at), (3, Some(t0.wrapping_add(w))));
}

#[test]
fn blocking_measure_is_bounded_by_the_clock() {
    let t = timing(2000);
    let w = t.window_us();
    // 1 ms passes at every clock read: ceil(w / 1000) polls, then no echo.
    let polls = w.div_ceil(1_000) as usize;
    let clock = MockClock::at(0);
    let bench = Bench::new(&clock, &reads(&"L".repeat(1 + polls)), &init_pings(1), &writes("L"), &writes("L"));
    clock.auto_advance(1_000);
    let mut m = bench.module(t);
    assert_eq!(m.measure(0, &mut NoopDelay::new(), 1_000), Ok(Echo::NoEcho));
    assert_eq!(clock.reads(), 1 + polls as u64);
    let _ = m.destroy();
    bench.done();
}

#[test]
fn blocking_measure_ends_on_a_stopped_clock() {
    let t = timing(2000);
    let w = t.window_us();
    // The clock never moves: the poll budget (2·w/poll + 4) ends the wait.
    let budget = (w / 500 * 2 + 4) as usize;
    let clock = MockClock::at(77);
    let bench = Bench::new(&clock, &reads(&"L".repeat(1 + budget)), &init_pings(1), &writes("L"), &writes("L"));
    let mut m = bench.module(t);
    assert_eq!(m.measure(0, &mut NoopDelay::new(), 500), Err(Error::ClockStalled));
    assert!(m.is_idle());
    let _ = m.destroy();
    bench.done();
}

#[test]
fn stuck_high_echo_refuses_the_ping_then_recovers() {
    // No INIT write (and no address write) for the refused ping.
    let clock = MockClock::at(0);
    let bench = Bench::new(&clock, &reads("HLH"), &init_pings(1), &writes("H"), &writes("L"));
    let mut m = bench.module(timing(2000));
    assert_eq!(m.start(1), Err(Error::Fault(Fault::EchoStuckHigh)));
    assert!(m.is_idle());
    assert_eq!(m.poll(), Err(Error::Idle));
    ping_ok(&mut m, &clock, 1, 10_000, 5_827, 1000);
    let _ = m.destroy();
    assert_eq!(fired(&bench.done()), [(1, 10_000)]);
}

#[test]
fn echo_inside_blanking_is_a_fault_and_the_module_stops() {
    let clock = MockClock::at(0);
    let bench = Bench::new(&clock, &reads("LHLH"), &init_pings(2), &writes("L"), &writes("L"));
    let t = timing(2000);
    let mut m = bench.module(t);
    m.start(0).unwrap();
    clock.set(1_500);
    assert_eq!(m.poll(), Err(Error::Fault(Fault::EchoInBlanking { tof_us: 1_500 })));
    assert!(m.is_idle());
    // Exactly at the end of blanking the echo counts (0.408 m at 20 °C).
    ping_ok(&mut m, &clock, 0, 100_000, t.blanking_us(), 408);
    assert_eq!(t.min_range_mm(), 408);
    let _ = m.destroy();
    assert_eq!(fired(&bench.done()), [(0, 0), (0, 100_000)]);
}

#[test]
fn binh_shortens_blanking_and_is_dropped_after() {
    let cfg = ModuleConfig {
        binh_after_us: Some(800),
        ..ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(2000).unwrap())
    };
    let t = cfg.timing().unwrap();
    assert_eq!(t.min_range_mm(), 137);
    // Ping 1: echo at 700 µs, before BINH: in blanking. Ping 2: low at 900
    // (BINH rises), echo at 1 200 µs: 206 mm.
    let clock = MockClock::at(0);
    let mut bench = Bench::new(&clock, &reads("LHLLH"), &init_pings(2), &writes("L"), &writes("L"));
    bench.pins.binh.update_expectations(&writes("HL"));
    let (_, _, binh, _) = bench.pins.clones();
    let mut m = bench.module(t).with_binh(binh);
    m.start(0).unwrap();
    clock.set(700);
    assert_eq!(m.poll(), Err(Error::Fault(Fault::EchoInBlanking { tof_us: 700 })));
    clock.set(50_000);
    m.start(0).unwrap();
    // A late poll raises BINH at 900 µs, not 800: blanking ends at 900.
    clock.set(50_900);
    assert_eq!(m.poll(), Ok(None));
    clock.set(51_200);
    assert_eq!(m.poll(), Ok(Some(Echo::Range { range_mm: 206, tof_us: 1_200 })));
    let _ = m.destroy();
    let f = bench.done();
    assert_eq!(fired(&f), [(0, 0), (0, 50_000)]);
    // BINH after INIT, at the poll that raised it; INIT and BINH dropped at the echo.
    assert_eq!((f[0].binh_at, f[1].binh_at, f[1].ended_at), (None, Some(50_900), Some(51_200)));
}

#[test]
fn pin_error_from_set_high_leaves_a_clean_idle() {
    let err = pin_error();
    let mut init = vec![
        // ping 1: INIT fails to rise; the driver drops it at once
        T::set(State::High).with_error(err.clone()),
        T::set(State::Low),
        // ping 2: fails to rise and fails to drop: dropped first thing next time
        T::set(State::High).with_error(err.clone()),
        T::set(State::Low).with_error(err.clone()),
        T::set(State::Low),
    ];
    init.extend(init_pings(1));
    // The address lines were written on ping 1 and are not written again.
    let clock = MockClock::at(0);
    let bench = Bench::new(&clock, &reads("LLLH"), &init, &writes("H"), &writes("H"));
    let mut m = bench.module(timing(2000));
    assert_eq!(m.start(3), Err(Error::Pin(err.clone())));
    assert!(m.is_idle());
    assert_eq!(m.start(3), Err(Error::Pin(err)));
    assert!(m.is_idle());
    ping_ok(&mut m, &clock, 3, 40_000, 11_654, 2000);
    let _ = m.destroy();
    // The failed rises are not pings.
    assert_eq!(fired(&bench.done()), [(3, 40_000)]);
}

#[test]
fn pin_errors_while_listening_and_on_address_lines() {
    let err = pin_error();
    let echo = [T::get(State::Low), T::get(State::Low).with_error(err.clone()), T::get(State::Low), T::get(State::Low)];
    // Ping 2 selects 1: line 0 fails, so ping 3 writes both lines again.
    let a0 = [T::set(State::Low), T::set(State::High).with_error(err.clone()), T::set(State::High)];
    let clock = MockClock::at(0);
    let bench = Bench::new(&clock, &echo, &writes("HLH"), &a0, &writes("LL"));
    let mut m = bench.module(timing(2000));
    m.start(0).unwrap();
    clock.set(3_000);
    assert_eq!(m.poll(), Err(Error::Pin(err.clone())));
    assert!(m.is_idle());
    assert_eq!(m.start(1), Err(Error::Pin(err)));
    assert!(m.is_idle());
    m.start(1).unwrap();
    assert_eq!(m.start(1), Err(Error::Busy));
    assert_eq!(m.select(2), Err(Error::Busy));
    // Destroyed with the last ping in flight: INIT is left as it is.
    let _ = m.destroy();
    let mut pins = bench.pins;
    assert_eq!(fired(&pins.done_in_flight()), [(0, 0), (1, 3_000)]);
}

#[test]
fn select_after_a_failed_drop_lowers_init_before_the_lines_move() {
    let err = pin_error();
    // The echo ends the ping but INIT fails to fall; select(1) must drop
    // INIT before it touches the multiplexer (the protocol check sees it).
    let init = [T::set(State::High), T::set(State::Low).with_error(err.clone()), T::set(State::Low)];
    let clock = MockClock::at(0);
    let bench = Bench::new(&clock, &reads("LH"), &init, &writes("LH"), &writes("L"));
    let mut m = bench.module(timing(2000));
    m.start(0).unwrap();
    clock.set(5_827);
    assert_eq!(m.poll(), Err(Error::Pin(err)));
    assert!(m.is_idle());
    assert_eq!(m.select(9), Err(Error::NoSuchTransducer(9)));
    m.select(1).unwrap();
    let _ = m.destroy();
    let f = bench.done();
    assert_eq!(fired(&f), [(0, 0)]);
    assert_eq!(f[0].ended_at, Some(5_827));
}

#[test]
fn a_late_poll_that_finds_echo_high_is_untimed_not_no_echo() {
    let t = timing(2000);
    let w = t.window_us();
    let clock = MockClock::at(0);
    // Ping 1: first look 500 µs after the window, ECHO high. Ping 2: same,
    // ECHO low. Ping 3: ECHO high exactly at the end of the window.
    let bench = Bench::new(&clock, &reads("LHLLLH"), &init_pings(3), &writes("L"), &writes("L"));
    let mut m = bench.module(t);
    m.start(0).unwrap();
    clock.set(w + 500);
    // Something came back, but when is unknown: not a range, and not the
    // "no echo" that self-referencing would read as an obstacle removed.
    assert_eq!(m.poll(), Ok(Some(Echo::Untimed { seen_after_us: w + 500 })));
    assert!(m.is_idle());
    clock.set(100_000);
    m.start(0).unwrap();
    clock.set(100_000 + w + 500);
    assert_eq!(m.poll(), Ok(Some(Echo::NoEcho)));
    ping_ok(&mut m, &clock, 0, 200_000, w, 5_500);
    let _ = m.destroy();
    let f = bench.done();
    assert_eq!(f.iter().map(|f| f.ended_at.unwrap() - f.at).collect::<Vec<_>>(), [w + 500, w + 500, w]);
}

#[test]
fn input_capture_finishes_a_ping() {
    let clock = MockClock::at(5);
    let bench = Bench::new(&clock, &reads("LLL"), &init_pings(3), &writes("L"), &writes("L"));
    let mut m = bench.module(timing(2000));
    let t0 = m.start(0).unwrap();
    assert_eq!(m.echo_captured(t0 + 17_481), Ok(Echo::Range { range_mm: 3000, tof_us: 17_481 }));
    assert_eq!(m.echo_captured(t0), Err(Error::Idle));
    let t1 = m.start(0).unwrap();
    // A stamp from before the ping is a fault, not a 71-minute echo.
    assert_eq!(m.echo_captured(t1.wrapping_sub(3)), Err(Error::Fault(Fault::EchoInBlanking { tof_us: 0 })));
    let t2 = m.start(0).unwrap();
    let w = m.timing().window_us();
    // A stamp says exactly when: after the window is beyond R_max, no echo.
    assert_eq!(m.echo_captured(t2 + w + 1), Ok(Echo::NoEcho));
    let _ = m.destroy();
    assert_eq!(bench.done().len(), 3);
}

#[test]
fn bad_transducer_and_bad_configs_are_refused() {
    let clock = MockClock::at(0);
    let bench = Bench::new(&clock, &[], &[], &[], &[]);
    let mut m = bench.module(timing(2000));
    assert_eq!(M::TRANSDUCERS, 4);
    assert_eq!(m.start(4), Err(Error::NoSuchTransducer(4)));
    assert_eq!(m.cancel(), Ok(()));
    let _ = m.destroy();
    assert!(bench.done().is_empty());

    let c = SpeedOfSound::at_centi_celsius(2000).unwrap();
    let base = ModuleConfig::polaroid_6500(c);
    assert_eq!(ModuleConfig { max_range_mm: 0, ..base }.timing(), Err(ConfigError::MaxRange));
    assert_eq!(ModuleConfig { max_range_mm: 11_001, ..base }.timing(), Err(ConfigError::MaxRange));
    assert_eq!(ModuleConfig { max_range_mm: 400, ..base }.timing(), Err(ConfigError::Blanking));
    assert_eq!(ModuleConfig { binh_after_us: Some(100), ..base }.timing(), Err(ConfigError::Binh));
    assert_eq!(ModuleConfig { binh_after_us: Some(2_380), ..base }.timing(), Err(ConfigError::Binh));
    assert_eq!(SpeedOfSound::at_centi_celsius(9000), Err(ConfigError::Temperature));
    assert_eq!(SpeedOfSound::from_um_per_s(200_000_000), Err(ConfigError::SpeedOfSound));
}

#[test]
fn errors_are_core_errors_with_messages() {
    fn describe(e: &dyn core::error::Error) -> (String, Option<String>) {
        (e.to_string(), e.source().map(|s| s.to_string()))
    }
    let stuck: Error<MockError> = Error::Fault(Fault::EchoStuckHigh);
    assert_eq!(
        describe(&stuck),
        ("sonar fault: ECHO high before the ping".into(), Some("ECHO high before the ping".into()))
    );
    let pin: Error<MockError> = Error::Pin(pin_error());
    assert!(describe(&pin).0.starts_with("pin error: "), "{pin}");
    assert_eq!(describe(&pin).1, None);
    assert_eq!(describe(&ConfigError::Binh).0, "BINH time outside the transmit burst .. blanking end");
}
