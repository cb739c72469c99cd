//! echoloc on an STM32F429ZI robot controller (cross-built, not run here):
//! the whole loop.
//!
//! Brings up the clocks (168 MHz from the 8 MHz HSE), TIM5 as the 1 MHz
//! clock with channel 1 capturing ECHO's edges, the sonar pins, USART3 as
//! the host link, and loads the compiled office map in place from flash
//! (a `MapView`: no copy in RAM). Then, for ever:
//!
//! 1. **The ring** fires on its own schedule (`Ring::poll` never waits); an
//!    ECHO edge stamped by TIM5's input capture finishes the ping in flight
//!    (`Ring::echo_captured`), so an echo's time does not depend on when the
//!    loop looks. Each reading waits in a short queue.
//! 2. **The link**: odometry from the robot's computer (cumulative poses,
//!    interpolated to each firing's time), and `SetPose` to (re)start the
//!    filter where the robot is.
//! 3. **The controller**, while the next ping is in flight (so that its
//!    work and the blocking UART writes never delay a firing): each queued
//!    reading whose odometry has come is predicted at the estimate, judged,
//!    and fed to the EKF (`echoloc::controller::Controller`); a `Reading`
//!    message goes back per reading and a `Cycle` message per ring cycle.
//!    A reading left without odometry while four more came is judged with
//!    no motion (counted as stale).
//!
//! The LEDs show, after each ring cycle, whether at least half of its judged
//! readings confirmed the map (green) and whether it saw an unknown obstacle
//! (red). The stack, painted at reset and placed below the statics by
//! flip-link (an overflow faults), has its high-water mark logged after the
//! setup and every 16 ring cycles. `defmt` logs over RTT: `cd boards/stm32f4-sonar && cargo run
//! --release` flashes and runs it through `probe-rs` (`.cargo/config.toml`).
#![no_std]
#![no_main]
#![deny(unsafe_code)]

use cortex_m_rt::entry;
use defmt_rtt as _;
use echoloc::controller::{Controller, OdometrySample, OdometrySync};
use echoloc::driver::{Error, Module, Ring, RingReading, Schedule};
use echoloc::link::{CycleReport, FromController, Link, ReadingReport, ToController, PROTOCOL_VERSION};
use echoloc::localize::{Localizer, LocalizerConfig, Start};
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::PIONEER16;
use echoloc::referencing::{EkfConfig, Motion};
use heapless::Deque;
use stm32f4_sonar::{
    credence, map_agrees, predict_params, stack_high_water, Clock, EchoLevel, HostPort, SonarRing, Tim5Clock,
    MODULE_TIMING, RING_TIMING, STACK_REPORT_CYCLES, TRANSDUCERS, VERDICTS,
};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Config;
use stm32f4xx_hal::serial::SerialExt;

/// The compiled office map (`echoloc-lab map import maps/office.geojson`),
/// the same one the QEMU board runs; it stays in flash and is read in place.
static BLOB: &Aligned<[u8]> = &Aligned(*include_bytes!("../office.map"));

/// Where the filter starts until the robot's computer sends `SetPose`:
/// x, y (m), φ (rad) in the office map, and the standard deviations.
const START: [f32; 3] = [4.0, 4.0, 0.0];
/// Particles of the localizer (issue #27).
const PARTICLES: usize = 1024;
/// Seed of its draws.
const LOCALIZER_SEED: u64 = 1;
const START_SIGMA: [f32; 3] = [0.1, 0.1, 0.05];

/// Readings waiting for their odometry.
const QUEUE: usize = 4;

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
    let gpiod = dp.GPIOD.split(&mut rcc);
    let gpioe = dp.GPIOE.split(&mut rcc);
    let mut ok_led = gpiob.pb0.into_push_pull_output();
    let mut obstacle_led = gpiob.pb14.into_push_pull_output();
    let init = gpioe.pe6.into_push_pull_output();
    let binh = gpioe.pe7.into_push_pull_output();
    let echo = EchoLevel::new(gpioa.pa0.into_alternate::<2>());
    let addr = [
        gpioe.pe2.into_push_pull_output().erase_number(),
        gpioe.pe3.into_push_pull_output().erase_number(),
        gpioe.pe4.into_push_pull_output().erase_number(),
        gpioe.pe5.into_push_pull_output().erase_number(),
    ];
    let module = Module::new(init, echo, addr, &clock, MODULE_TIMING).with_binh(binh);
    let mut ring: SonarRing<'_> = Ring::new(module, Schedule::spread(), RING_TIMING);

    let Ok(serial) = dp.USART3.serial((gpiod.pd8, gpiod.pd9), 115_200.bps(), &mut rcc) else {
        panic!("USART3 at 115200 baud is refused");
    };
    let mut link = Link::new(HostPort::new(serial));

    let Ok(map) = MapView::new(&BLOB.0) else {
        panic!("the office map blob was refused");
    };
    let params = predict_params(&map);
    let net = credence();
    // The localizer's one copy (21 KiB at 1 024 particles), in this frame for
    // the program's life; the controller borrows it.
    let mut localizer: Localizer<PARTICLES> =
        Localizer::new(LocalizerConfig::DEFAULT, EkfConfig::DEFAULT, VERDICTS, LOCALIZER_SEED);
    if localizer.start(Start::Known { pose: START, sigma: START_SIGMA }, map.field()).is_err() {
        panic!("the start pose is refused");
    }
    let mut controller = Controller::new(&map, map.field(), &PIONEER16, params, &net, &mut localizer);
    let mut odometry = OdometrySync::<16>::new();
    let mut queue: Deque<RingReading, QUEUE> = Deque::new();
    let (mut refused, mut stale) = (0u32, 0u32);
    let map_crc = echoloc::map::crc32(&BLOB.0);
    defmt::info!("echoloc controller: {} pieces, map CRC {=u32:#010x}", map.piece_count(), map_crc);
    let hello = FromController::Hello {
        protocol: PROTOCOL_VERSION,
        transducers: TRANSDUCERS as u8,
        map_crc,
        time_us: clock.now_us(),
    };
    if let Err(e) = link.send(&hello) {
        defmt::warn!("link: {}", e);
    }
    let (used, size) = stack_high_water();
    defmt::info!("stack: {=usize} of {=usize} bytes used by the setup (painted at reset)", used, size);

    loop {
        // 1. The ring: a stamped edge first, then the schedule.
        let reading = match clock.take_capture() {
            // An edge outside a ping (a stale stamp) is no reading: `Idle`.
            Some(stamp) => ring.echo_captured(stamp).ok(),
            None => match ring.poll() {
                Ok(r) => r,
                Err(Error::Pin(never)) => match never {},
                Err(e) => {
                    defmt::warn!("ring: {}, restarting the schedule", e);
                    let _ = ring.reset();
                    None
                }
            },
        };
        if let Some(r) = reading {
            if queue.is_full() {
                // Four more readings and still no odometry for this one:
                // judge it without motion rather than lose it.
                if let Some(old) = queue.pop_front() {
                    stale += 1;
                    step(
                        &mut controller,
                        &mut link,
                        &Motion { dx: 0.0, dy: 0.0, dphi: 0.0 },
                        &old,
                        (&mut ok_led, &mut obstacle_led),
                    );
                }
            }
            let _ = queue.push_back(r);
        }

        // 2. The link: at most one message per pass.
        match link.poll(16) {
            Ok(Some(ToController::Odometry { time_us, x, y, theta })) => {
                if odometry.push(OdometrySample { time_us, pose: [x, y, theta] }).is_err() {
                    refused += 1;
                }
            }
            Ok(Some(ToController::SetPose { pose, sigma })) => {
                if controller.restart(Start::Known { pose, sigma }).is_err() {
                    refused += 1;
                }
            }
            Ok(Some(ToController::Search { around })) => {
                let how = around.map_or(Start::Unknown, |(pose, sigma)| Start::Around { pose, sigma });
                if controller.restart(how).is_err() {
                    refused += 1;
                }
            }
            Ok(Some(ToController::End)) => {
                let status = FromController::Status {
                    rx: link.rx_counts(),
                    odometry_refused: refused,
                    readings: controller.counts().readings,
                    stale,
                };
                let _ = link.send(&status);
            }
            Ok(None) => {}
            Err(e) => defmt::warn!("link: {}", e),
        }

        // 3. The controller, only while a ping is in flight (its slot's time
        // has come), so nothing here delays a firing.
        let in_flight = ring.next_fire_us().is_some_and(|due| (clock.now_us().wrapping_sub(due) as i32) >= 0);
        if in_flight {
            if let Some(r) = queue.front().copied() {
                if odometry.covers(r.fired_at_us) {
                    let _ = queue.pop_front();
                    let u = odometry.increment_to(r.fired_at_us).unwrap_or(Motion { dx: 0.0, dy: 0.0, dphi: 0.0 });
                    step(&mut controller, &mut link, &u, &r, (&mut ok_led, &mut obstacle_led));
                }
            }
        }
    }
}

/// One reading through the controller; its report (and the cycle's, when
/// it closed one) to the host; the LEDs per cycle; the stack's high-water
/// mark every [`STACK_REPORT_CYCLES`] cycles. Never inlined: the root of the
/// ring cycle's static stack bound (`scripts/stack-bound.sh`).
#[inline(never)]
fn step<M, K, P, const N: usize>(
    controller: &mut Controller<'_, M, K, N>,
    link: &mut Link<P>,
    u: &Motion,
    r: &RingReading,
    leds: (&mut impl embedded_hal::digital::OutputPin, &mut impl embedded_hal::digital::OutputPin),
) where
    M: MapSource + ?Sized,
    K: echoloc::credence::Credence + ?Sized,
    P: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write,
{
    match controller.step(u, r) {
        Ok(s) => {
            if let Some(end) = &s.cycle_end {
                let (ok_led, obstacle_led) = leds;
                let _ = if map_agrees(&end.verdicts) { ok_led.set_high() } else { ok_led.set_low() };
                let _ =
                    if end.verdicts.unknown_obstacle > 0 { obstacle_led.set_high() } else { obstacle_led.set_low() };
                let _ = link.send(&FromController::Cycle(CycleReport::from(end)));
                let cycles = controller.counts().cycles;
                if cycles % STACK_REPORT_CYCLES == 0 {
                    let (used, size) = stack_high_water();
                    defmt::info!(
                        "stack: high-water mark {=usize} of {=usize} bytes after {=u32} ring cycles",
                        used,
                        size,
                        cycles
                    );
                }
            }
            let x = controller.state();
            defmt::debug!("t{} {}: pose ({}, {}, {})", r.transducer, s.report.verdict, x[0], x[1], x[2]);
            let report = ReadingReport::new(r, &s, x, controller.covariance(), controller.mode());
            let _ = link.send(&FromController::Reading(report));
        }
        Err(e) => defmt::warn!("controller: {}", e),
    }
}
