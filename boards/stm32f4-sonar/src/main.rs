//! echoloc on an STM32F429ZI robot controller (cross-built, not run here).
//!
//! Brings up the clocks (168 MHz from the 8 MHz HSE), the 1 MHz TIM5 clock
//! and the sonar pins (see the library's docs for the wiring), loads the
//! compiled office map in place from flash (a `MapView`: no copy in RAM),
//! and runs the ring for ever:
//! the ring fires on its own schedule (`Ring::poll` never waits), each
//! transducer's reading is compared with what the map predicts for it from
//! the current pose estimate, and each transducer is predicted in the
//! ring-down gap just before it fires, so one ring cycle predicts the whole
//! ring for the pose of that moment. After each cycle the status LEDs show
//! whether the map agreed and whether an unknown obstacle was seen.
//!
//! The pose estimate stays where it starts: correcting it from the verdicts
//! (the pose filter) is a later step.
#![no_std]
#![no_main]
#![deny(unsafe_code)]

use cortex_m_rt::entry;
use echoloc::driver::{Error, Module, Ring, Schedule};
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::Pose;
use echoloc::referencing::VerdictCounts;
use stm32f4_sonar::{
    credence, expect, judge, map_agrees, predict_params, Expected, SonarRing, Tim5Clock, MODULE_TIMING, RING_TIMING,
    TRANSDUCERS,
};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Config;

/// The compiled office map (`echoloc-lab map import maps/office.geojson`),
/// the same one the QEMU board runs; it stays in flash and is read in place.
static BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!("../../qemu-mps2-an386/office.map"));

/// Where the robot starts in the office map (mm, rad): the pose estimate
/// until a pose filter moves it.
const START: Pose = Pose { x_mm: 4000.0, y_mm: 4000.0, heading_rad: 0.0 };

#[entry]
fn main() -> ! {
    let Some(dp) = pac::Peripherals::take() else {
        panic!("device peripherals already taken");
    };
    // NUCLEO-F429ZI: HSE is the ST-LINK's 8 MHz output (bypass). APB1 at
    // 42 MHz puts the APB1 timers at 84 MHz: a whole number of MHz, as the
    // 1 MHz prescaler needs.
    let mut rcc =
        dp.RCC.freeze(Config::hse(8.MHz()).bypass_hse_oscillator().sysclk(168.MHz()).pclk1(42.MHz()).pclk2(84.MHz()));
    let clock = Tim5Clock::start(dp.TIM5, &mut rcc);

    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioe = dp.GPIOE.split(&mut rcc);
    let mut ok_led = gpiob.pb0.into_push_pull_output();
    let mut obstacle_led = gpiob.pb14.into_push_pull_output();
    let init = gpioe.pe6.into_push_pull_output();
    let binh = gpioe.pe7.into_push_pull_output();
    let echo = gpioa.pa0.into_floating_input();
    let addr = [
        gpioe.pe2.into_push_pull_output().erase_number(),
        gpioe.pe3.into_push_pull_output().erase_number(),
        gpioe.pe4.into_push_pull_output().erase_number(),
        gpioe.pe5.into_push_pull_output().erase_number(),
    ];
    let module = Module::new(init, echo, addr, &clock, MODULE_TIMING).with_binh(binh);
    let mut ring: SonarRing<'_> = Ring::new(module, Schedule::spread(), RING_TIMING);

    let Ok(map) = MapView::new(&BLOB.0) else {
        panic!("the office map blob was refused");
    };
    let params = predict_params(map.buffer_mm());
    let net = credence();
    let pose = START;

    // What each transducer should read from the pose estimate.
    let mut expected = [Expected::Unknown; TRANSDUCERS];
    // What transducer `t` should read, into its slot of `expected`.
    let refresh = |expected: &mut [Expected; TRANSDUCERS], t: u8| {
        expected[usize::from(t)] = expect(&map, &pose, t, &params, &net).unwrap_or(Expected::Unknown);
    };
    let mut tally = VerdictCounts::default();
    if let Some(t) = ring.schedule().transducer(0) {
        refresh(&mut expected, t);
    }
    loop {
        let reading = match ring.poll() {
            Ok(Some(r)) => r,
            Ok(None) => continue,
            // Pins here cannot fail (`Infallible`), and the ring is only
            // polled; anything else is a driver bug: start the schedule again.
            Err(Error::Pin(never)) => match never {},
            Err(_) => {
                let _ = ring.reset();
                tally = VerdictCounts::default();
                if let Some(t) = ring.schedule().transducer(0) {
                    refresh(&mut expected, t);
                }
                continue;
            }
        };
        let verdict = judge(&reading.outcome, &expected[usize::from(reading.transducer)]);
        tally.add(verdict);

        // The ring is now in its ring-down gap: predict the transducer that
        // fires next, from the pose estimate as it is now.
        let next_slot = usize::from(reading.slot) + 1;
        if let Some(n) = ring.schedule().transducer(next_slot % TRANSDUCERS) {
            refresh(&mut expected, n);
        }

        if next_slot == TRANSDUCERS {
            // A whole cycle: show it, start counting the next.
            if map_agrees(&tally) {
                ok_led.set_high();
            } else {
                ok_led.set_low();
            }
            if tally.unknown_obstacle > 0 {
                obstacle_led.set_high();
            } else {
                obstacle_led.set_low();
            }
            tally = VerdictCounts::default();
        }
    }
}
