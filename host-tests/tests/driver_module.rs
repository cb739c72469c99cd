//! One ranging module through embedded-hal-mock pins and a scripted clock:
//! ranges, temperatures, no echo, stuck ECHO, echo in blanking, BINH, pin
//! errors, input capture and the bounded blocking wait.

#[path = "driver_support.rs"]
mod support;

use echoloc::driver::{ConfigError, Echo, Error, Fault, Module, ModuleConfig, NoPin, SpeedOfSound, Timing};
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::digital::{Mock, State, Transaction as T};
use embedded_hal_mock::eh1::MockError;
use support::{c_ref, pin_error, tof_ref_us, window_ref_us, MockClock};

type M<'c> = Module<Mock, Mock, NoPin<MockError>, Mock, &'c MockClock, 2>;

fn timing(centi_c: i16) -> Timing {
    ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(centi_c).unwrap()).timing().unwrap()
}

struct Bench {
    echo: Mock,
    init: Mock,
    addr: [Mock; 2],
}

impl Bench {
    fn new(echo: &[T], init: &[T], a0: &[T], a1: &[T]) -> Self {
        Self { echo: Mock::new(echo), init: Mock::new(init), addr: [Mock::new(a0), Mock::new(a1)] }
    }
    fn module<'c>(&self, clock: &'c MockClock, t: Timing) -> M<'c> {
        Module::new(self.init.clone(), self.echo.clone(), [self.addr[0].clone(), self.addr[1].clone()], clock, t)
    }
    fn done(mut self) {
        self.echo.done();
        self.init.done();
        self.addr[0].done();
        self.addr[1].done();
    }
}

#[test]
fn normal_pings_at_several_ranges_and_temperatures() {
    let temps = [-2000i16, 0, 2000, 3500];
    let ranges = [450u32, 1234, 3000, 5400];
    let n = temps.len() * ranges.len();
    // Each ping: ECHO low before, low just before the echo, high at it.
    let echo: Vec<T> = (0..n).flat_map(|_| [T::get(State::Low), T::get(State::Low), T::get(State::High)]).collect();
    let init: Vec<T> = (0..n).flat_map(|_| [T::set(State::High), T::set(State::Low)]).collect();
    // Transducer 2 = lines (low, high), written once: later pings reuse them.
    let bench = Bench::new(&echo, &init, &[T::set(State::Low)], &[T::set(State::High)]);
    let clock = MockClock::at(1_000);
    for &tc in &temps {
        let mut m = bench.module(&clock, timing(tc));
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
            bench.addr[0].clone().update_expectations(&[T::set(State::Low)]);
            bench.addr[1].clone().update_expectations(&[T::set(State::High)]);
        }
    }
    bench.done();
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
    let echo = [T::get(State::Low), T::get(State::Low), T::get(State::Low), T::get(State::Low)];
    let init = [T::set(State::High), T::set(State::Low)];
    let bench = Bench::new(&echo, &init, &[T::set(State::High)], &[T::set(State::High)]);
    let clock = MockClock::at(u32::MAX - 10_000); // the window crosses the clock's wrap
    let mut m = bench.module(&clock, t);
    let t0 = m.start(3).unwrap();
    clock.set(t0.wrapping_add(w / 2));
    assert_eq!(m.poll(), Ok(None));
    clock.set(t0.wrapping_add(w - 1));
    assert_eq!(m.poll(), Ok(None));
    clock.set(t0.wrapping_add(w));
    assert_eq!(m.poll(), Ok(Some(Echo::NoEcho)));
    assert_eq!(m.poll(), Err(Error::Idle));
    let _ = m.destroy();
    bench.done();
}

#[test]
fn blocking_measure_is_bounded_by_the_clock() {
    let t = timing(2000);
    let w = t.window_us();
    // 1 ms passes at every clock read: ceil(w / 1000) polls, then no echo.
    let polls = w.div_ceil(1_000) as usize;
    let mut echo = vec![T::get(State::Low)];
    echo.extend(std::iter::repeat_n(T::get(State::Low), polls));
    let bench =
        Bench::new(&echo, &[T::set(State::High), T::set(State::Low)], &[T::set(State::Low)], &[T::set(State::Low)]);
    let clock = MockClock::at(0);
    clock.auto_advance(1_000);
    let mut m = bench.module(&clock, t);
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
    let mut echo = vec![T::get(State::Low)];
    echo.extend(std::iter::repeat_n(T::get(State::Low), budget));
    let bench =
        Bench::new(&echo, &[T::set(State::High), T::set(State::Low)], &[T::set(State::Low)], &[T::set(State::Low)]);
    let clock = MockClock::at(77);
    let mut m = bench.module(&clock, t);
    assert_eq!(m.measure(0, &mut NoopDelay::new(), 500), Err(Error::ClockStalled));
    assert!(m.is_idle());
    let _ = m.destroy();
    bench.done();
}

#[test]
fn stuck_high_echo_refuses_the_ping_then_recovers() {
    let echo = [T::get(State::High), T::get(State::Low), T::get(State::High)];
    // No INIT write for the refused ping.
    let init = [T::set(State::High), T::set(State::Low)];
    let bench = Bench::new(&echo, &init, &[T::set(State::High)], &[T::set(State::Low)]);
    let clock = MockClock::at(0);
    let mut m = bench.module(&clock, timing(2000));
    assert_eq!(m.start(1), Err(Error::Fault(Fault::EchoStuckHigh)));
    assert!(m.is_idle());
    assert_eq!(m.poll(), Err(Error::Idle));
    clock.set(10_000);
    m.start(1).unwrap();
    clock.set(10_000 + 5_827);
    assert_eq!(m.poll(), Ok(Some(Echo::Range { range_mm: 1000, tof_us: 5_827 })));
    let _ = m.destroy();
    bench.done();
}

#[test]
fn echo_inside_blanking_is_a_fault_and_the_module_stops() {
    let echo = [T::get(State::Low), T::get(State::High), T::get(State::Low), T::get(State::High)];
    let init = [T::set(State::High), T::set(State::Low), T::set(State::High), T::set(State::Low)];
    let bench = Bench::new(&echo, &init, &[T::set(State::Low)], &[T::set(State::Low)]);
    let clock = MockClock::at(0);
    let t = timing(2000);
    let mut m = bench.module(&clock, t);
    m.start(0).unwrap();
    clock.set(1_500);
    assert_eq!(m.poll(), Err(Error::Fault(Fault::EchoInBlanking { tof_us: 1_500 })));
    assert!(m.is_idle());
    // Exactly at the end of blanking the echo counts (0.408 m at 20 °C).
    clock.set(100_000);
    m.start(0).unwrap();
    clock.set(100_000 + t.blanking_us());
    assert_eq!(m.poll(), Ok(Some(Echo::Range { range_mm: 408, tof_us: t.blanking_us() })));
    assert_eq!(t.min_range_mm(), 408);
    let _ = m.destroy();
    bench.done();
}

#[test]
fn binh_shortens_blanking_and_is_dropped_after() {
    let cfg = ModuleConfig {
        binh_after_us: Some(800),
        ..ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(2000).unwrap())
    };
    let t = cfg.timing().unwrap();
    assert_eq!(t.min_range_mm(), 137);
    let echo = [
        // ping 1: echo at 700 µs, before BINH: in blanking
        T::get(State::Low),
        T::get(State::High),
        // ping 2: low at 900 (BINH rises), echo at 1 200 µs: 206 mm
        T::get(State::Low),
        T::get(State::Low),
        T::get(State::High),
    ];
    let init = [T::set(State::High), T::set(State::Low), T::set(State::High), T::set(State::Low)];
    let bench = Bench::new(&echo, &init, &[T::set(State::Low)], &[T::set(State::Low)]);
    let mut binh = Mock::new(&[T::set(State::High), T::set(State::Low)]);
    let clock = MockClock::at(0);
    let mut m = bench.module(&clock, t).with_binh(binh.clone());
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
    binh.done();
    bench.done();
}

#[test]
fn pin_error_from_set_high_leaves_a_clean_idle() {
    let err = pin_error();
    let echo = [T::get(State::Low), T::get(State::Low), T::get(State::Low), T::get(State::High)];
    let init = [
        // ping 1: INIT fails to rise; the driver drops it at once
        T::set(State::High).with_error(err.clone()),
        T::set(State::Low),
        // ping 2: fails to rise and fails to drop: dropped first thing next time
        T::set(State::High).with_error(err.clone()),
        T::set(State::Low).with_error(err.clone()),
        T::set(State::Low),
        T::set(State::High),
        T::set(State::Low),
    ];
    // The address lines were written on ping 1 and are not written again.
    let bench = Bench::new(&echo, &init, &[T::set(State::High)], &[T::set(State::High)]);
    let clock = MockClock::at(0);
    let mut m = bench.module(&clock, timing(2000));
    assert_eq!(m.start(3), Err(Error::Pin(err.clone())));
    assert!(m.is_idle());
    assert_eq!(m.start(3), Err(Error::Pin(err)));
    assert!(m.is_idle());
    clock.set(40_000);
    m.start(3).unwrap();
    clock.set(40_000 + 11_654);
    assert_eq!(m.poll(), Ok(Some(Echo::Range { range_mm: 2000, tof_us: 11_654 })));
    let _ = m.destroy();
    bench.done();
}

#[test]
fn pin_errors_while_listening_and_on_address_lines() {
    let err = pin_error();
    let echo = [T::get(State::Low), T::get(State::Low).with_error(err.clone()), T::get(State::Low), T::get(State::Low)];
    let init = [T::set(State::High), T::set(State::Low), T::set(State::High)];
    // Ping 2 selects 1: line 0 fails, so ping 3 writes both lines again.
    let a0 = [T::set(State::Low), T::set(State::High).with_error(err.clone()), T::set(State::High)];
    let a1 = [T::set(State::Low), T::set(State::Low)];
    let bench = Bench::new(&echo, &init, &a0, &a1);
    let clock = MockClock::at(0);
    let mut m = bench.module(&clock, timing(2000));
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
    bench.done();
}

#[test]
fn input_capture_finishes_a_ping() {
    let echo = [T::get(State::Low), T::get(State::Low), T::get(State::Low)];
    let init = [
        T::set(State::High),
        T::set(State::Low),
        T::set(State::High),
        T::set(State::Low),
        T::set(State::High),
        T::set(State::Low),
    ];
    let bench = Bench::new(&echo, &init, &[T::set(State::Low)], &[T::set(State::Low)]);
    let clock = MockClock::at(5);
    let mut m = bench.module(&clock, timing(2000));
    let t0 = m.start(0).unwrap();
    assert_eq!(m.echo_captured(t0 + 17_481), Ok(Echo::Range { range_mm: 3000, tof_us: 17_481 }));
    assert_eq!(m.echo_captured(t0), Err(Error::Idle));
    let t1 = m.start(0).unwrap();
    // A stamp from before the ping is a fault, not a 71-minute echo.
    assert_eq!(m.echo_captured(t1.wrapping_sub(3)), Err(Error::Fault(Fault::EchoInBlanking { tof_us: 0 })));
    let t2 = m.start(0).unwrap();
    let w = m.timing().window_us();
    assert_eq!(m.echo_captured(t2 + w + 1), Ok(Echo::NoEcho));
    let _ = m.destroy();
    bench.done();
}

#[test]
fn bad_transducer_and_bad_configs_are_refused() {
    let bench = Bench::new(&[], &[], &[], &[]);
    let clock = MockClock::at(0);
    let mut m = bench.module(&clock, timing(2000));
    assert_eq!(M::TRANSDUCERS, 4);
    assert_eq!(m.start(4), Err(Error::NoSuchTransducer(4)));
    assert_eq!(m.cancel(), Ok(()));
    let _ = m.destroy();
    bench.done();

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
