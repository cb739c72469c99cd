//! Self-tests of `driver_support.rs`, included by `driver_module.rs` only so
//! that they run once.

use echoloc::driver::Clock;
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal_mock::eh1::digital::{State, Transaction as T};

use super::support::{
    c_ref, init_pings, reads, tof_ref_us, writes, Act, Event, Line, MockClock, Pins, Protocol, Rig, Scripts,
};

#[test]
fn mock_clock_scripts_steps_ticks_and_wraps() {
    let c = MockClock::at(u32::MAX - 4);
    assert_eq!(c.now_us(), u32::MAX - 4);
    c.advance(10);
    assert_eq!(c.now_us(), 5);
    c.auto_advance(3);
    assert_eq!((c.now_us(), c.now_us(), c.now()), (5, 8, 11));
    c.resolution(4);
    c.auto_advance(0);
    assert_eq!(c.now_us(), 8);
    assert_eq!(c.reads(), 5);
}

#[test]
fn reference_speed_of_sound() {
    assert!((c_ref(2000) - 343.21).abs() < 0.01);
    // 1 m at 20 °C is 5 827 µs there and back.
    assert_eq!(tof_ref_us(1000.0, 2000), 5827);
}

#[test]
fn rig_writes_only_changed_address_lines() {
    let mut rig = Rig::new(3, 10_000, None);
    rig.select(5);
    rig.select(4);
    rig.select(4);
    assert_eq!(rig.scripts.addr[0], vec![T::set(State::High), T::set(State::Low)]);
    assert_eq!(rig.scripts.addr[1], vec![T::set(State::Low)]);
    assert_eq!(rig.scripts.addr[2], vec![T::set(State::High)]);
}

#[test]
fn script_shorthands() {
    assert_eq!(reads("LH"), vec![T::get(State::Low), T::get(State::High)]);
    assert_eq!(writes("H"), vec![T::set(State::High)]);
    assert_eq!(init_pings(2), writes("HLHL"));
}

#[test]
fn recording_pins_log_across_pins_in_order_with_the_time() {
    let clock = MockClock::at(7);
    let s = Scripts { echo: reads("L"), init: init_pings(1), binh: writes("HL"), addr: vec![writes("H")] };
    let mut pins = Pins::<1>::new(&s, &clock);
    let (mut echo, mut init, mut binh, [mut a0]) = pins.clones();
    assert_eq!(echo.is_high(), Ok(false));
    a0.set_high().unwrap();
    init.set_high().unwrap();
    clock.advance(900);
    binh.set_high().unwrap();
    clock.advance(100);
    init.set_low().unwrap();
    binh.set_low().unwrap();
    let ev = |line, act, at| Event { line, act, at, ok: true };
    let want = [
        ev(Line::Echo, Act::Read(false), 7),
        ev(Line::Addr(0), Act::SetHigh, 7),
        ev(Line::Init, Act::SetHigh, 7),
        ev(Line::Binh, Act::SetHigh, 907),
        ev(Line::Init, Act::SetLow, 1_007),
        ev(Line::Binh, Act::SetLow, 1_007),
    ];
    assert_eq!(pins.log.take(), want);
    // The protocol checker accepts it and sees one ping of transducer 1.
    let mut p = Protocol::new(1);
    p.feed(&want);
    p.assert_idle();
    let fired = p.take_fired();
    assert_eq!(fired.len(), 1);
    assert_eq!((fired[0].transducer, fired[0].at, fired[0].binh_at, fired[0].ended_at), (1, 7, Some(907), Some(1_007)));
    drop((echo, init, binh, a0));
    pins.done_in_flight();
}

/// Feed `events` to a fresh checker; the panic message if it objects.
fn objection(events: &[(Line, Act)]) -> Option<String> {
    let events: Vec<Event> =
        events.iter().enumerate().map(|(i, &(line, act))| Event { line, act, at: i as u32, ok: true }).collect();
    std::panic::catch_unwind(|| Protocol::new(1).feed(&events))
        .err()
        .map(|e| e.downcast_ref::<String>().cloned().unwrap_or_default())
}

#[test]
fn protocol_checker_catches_wrong_orders() {
    use Act::{Read, SetHigh as Hi, SetLow as Lo};
    use Line::{Addr, Binh, Echo, Init};
    let good = [(Echo, Read(false)), (Addr(0), Lo), (Init, Hi), (Binh, Hi), (Init, Lo), (Binh, Lo)];
    assert_eq!(objection(&good), None);
    let cases: [(&[(Line, Act)], &str); 5] = [
        // Address line written after INIT rose.
        (&[(Echo, Read(false)), (Addr(0), Lo), (Init, Hi), (Addr(0), Hi)], "address line written while INIT"),
        // INIT rose before the multiplexer was ever set.
        (&[(Echo, Read(false)), (Init, Hi)], "address line 0 unknown"),
        // No stuck-line check before the ping.
        (&[(Addr(0), Lo), (Init, Hi)], "without ECHO read low"),
        // BINH before INIT.
        (&[(Echo, Read(false)), (Addr(0), Lo), (Binh, Hi)], "BINH raised while INIT is not high"),
        // BINH dropped before INIT.
        (&[(Echo, Read(false)), (Addr(0), Lo), (Init, Hi), (Binh, Hi), (Binh, Lo)], "BINH dropped before INIT"),
    ];
    for (events, why) in cases {
        let msg = objection(events).unwrap_or_else(|| panic!("accepted: {events:?}"));
        assert!(msg.contains(why), "{msg}");
    }
}
