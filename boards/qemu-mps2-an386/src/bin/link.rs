//! The whole loop with the host link (issue #12 item 2): the echoes come
//! from a scenario in the flash partition at 0x0030_0000 through the ring
//! driver, as in `--bin replay`, but the odometry comes from the robot's
//! computer over UART0 (framed [`ToController::Odometry`] messages), and for
//! every reading the controller sends back its outcome, prediction, κ,
//! verdict, pose, covariance and the localizer's mode ([`FromController::Reading`]),
//! a [`FromController::Cycle`] per ring cycle, and at the end the link's
//! [`FromController::Status`] (frames taken and dropped, by cause).
//!
//! Run by `echoloc-lab link --qemu target/thumbv7em-none-eabihf/release/link
//! --scenario X.scn`, which starts QEMU with UART0 on a Unix socket and the
//! scenario in the partition, streams the odometry and prints what comes
//! back as JSON lines. Exits 0 when the pose error (against the scenario's
//! truth, printed on the semihosting console) is within its bounds, or,
//! when the host restarted the localizer (`SetPose`, `Search`: taken after
//! the reading during which they came), when the loop ran to the end.
#![no_std]
#![no_main]

use core::cell::RefCell;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::controller::replay::{check, localizer, run, start, ReplayError};
use echoloc::controller::{OdometryError, OdometrySample, OdometrySync};
use echoloc::credence::net::CredenceNet;
use echoloc::link::{CycleReport, FromController, Link, ReadingReport, ToController, PROTOCOL_VERSION};
use echoloc::localize::localizer::Start;
use echoloc::map::{Aligned, MapView};
use echoloc::predict::Mount;
use echoloc::scenario::replay::Bench;
use echoloc::scenario::Scenario;
use qemu_mps2_an386::replay::{self, Fixed6, PARTICLES, POLL_STEP_US, TRANSDUCERS};
use qemu_mps2_an386::uart::Uart0;
use qemu_mps2_an386::{calibrate, exit, start_systick};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

/// Polls of the UART while waiting for odometry up to a reading, before
/// the controller gives up on a silent host: about 10⁹ instructions, a
/// few seconds under QEMU, far more than a live host ever needs.
const MAX_WAIT_POLLS: u32 = 20_000_000;

#[entry]
fn main() -> ! {
    let syst = start_systick();
    hprintln!(
        "echoloc {} on mps2-an386: the whole loop, odometry over the host link on UART0",
        env!("CARGO_PKG_VERSION")
    );
    let _ = calibrate(&syst);
    let Ok(map) = MapView::new(&DEPOT.0) else {
        hprintln!("FAIL: depot map refused");
        exit(false);
    };
    let Some(bytes) = replay::scenario_partition() else { exit(false) };
    let scenario = match Scenario::parse(bytes) {
        Ok(s) => s,
        Err(e) => {
            hprintln!("FAIL: scenario refused: {}", e);
            exit(false);
        }
    };
    let Some(setup) = replay::setup(&map) else { exit(false) };
    let mut mounts = [Mount { x_mm: 0, y_mm: 0, heading_mdeg: 0 }; TRANSDUCERS];
    for (i, m) in mounts.iter_mut().enumerate() {
        *m = scenario.mount(i).unwrap_or(*m);
    }
    let map_crc = echoloc::map::crc32(&DEPOT.0);
    let bench = Bench::new(scenario, POLL_STEP_US);
    if let Err(e) = check(&bench, map_crc, &setup) {
        hprintln!("FAIL: scenario refused: {}", e);
        exit(false);
    }
    let Some(uart) = Uart0::take() else { exit(false) };
    let link = RefCell::new(Link::new(uart));
    let hello =
        FromController::Hello { protocol: PROTOCOL_VERSION, transducers: TRANSDUCERS as u8, map_crc, time_us: 0 };
    let _ = link.borrow_mut().send(&hello);

    let odometry = RefCell::new(OdometrySync::<16>::new());
    let refused = core::cell::Cell::new(0u32);
    // A SetPose or Search from the host, and how many were taken.
    let restart = core::cell::Cell::new(None::<Start>);
    let restarts = core::cell::Cell::new(0u32);
    let net = CredenceNet::shipped();
    let mut loc = localizer::<PARTICLES, TRANSDUCERS>(&setup, 1);
    if let Err(e) = start(&mut loc, &bench, map.field(), None) {
        hprintln!("FAIL: {}", e);
        exit(false);
    }
    let result = run::<_, _, 4, TRANSDUCERS, PARTICLES>(
        &bench,
        &map,
        map.field(),
        &mounts,
        &net,
        &setup,
        &mut loc,
        |reading, _| {
            // Odometry up to the firing: read the link until a sample at or
            // after it has come (never more: the rest waits in QEMU's socket).
            let t = reading.fired_at_us;
            let mut odo = odometry.borrow_mut();
            for _ in 0..MAX_WAIT_POLLS {
                if odo.covers(t) {
                    return odo.increment_to(t).map_err(ReplayError::Odometry);
                }
                match link.borrow_mut().poll(64) {
                    Ok(Some(ToController::Odometry { time_us, x, y, theta })) => {
                        if odo.push(OdometrySample { time_us, pose: [x, y, theta] }).is_err() {
                            refused.set(refused.get() + 1);
                        }
                    }
                    Ok(Some(ToController::End)) => return Err(ReplayError::Odometry(OdometryError::NotYet)),
                    // Taken after this reading, where the controller can restart.
                    Ok(Some(ToController::SetPose { pose, sigma })) => restart.set(Some(Start::Known { pose, sigma })),
                    Ok(Some(ToController::Search { around })) => {
                        restart.set(Some(around.map_or(Start::Unknown, |(pose, sigma)| Start::Around { pose, sigma })))
                    }
                    Ok(None) | Err(_) => {}
                }
            }
            Err(ReplayError::Odometry(OdometryError::NotYet))
        },
        |c, r, _, step| {
            if let Some(how) = restart.take() {
                if c.restart(how).is_err() {
                    refused.set(refused.get() + 1);
                } else {
                    restarts.set(restarts.get() + 1);
                }
            }
            let mut l = link.borrow_mut();
            if let Some(end) = &step.cycle_end {
                let _ = l.send(&FromController::Cycle(CycleReport::from(end)));
            }
            let _ = l.send(&FromController::Reading(ReadingReport::new(r, step, c.state(), c.covariance(), c.mode())));
        },
    );
    let mut l = link.borrow_mut();
    let readings = result.as_ref().map_or(0, |s| s.counts.readings);
    let status = FromController::Status { rx: l.rx_counts(), odometry_refused: refused.get(), readings, stale: 0 };
    let _ = l.send(&status);
    let rx = l.rx_counts();
    hprintln!(
        "link: {} frames taken, {} dropped (overflow {}, cobs {}, short {}, crc {}, version {}, decode {}); {} odometry samples refused",
        rx.ok, rx.dropped(), rx.overflow, rx.cobs, rx.short, rx.crc, rx.version, rx.decode, refused.get()
    );
    let (used, size) = qemu_mps2_an386::stack_high_water();
    hprintln!("stack high-water mark: {} of {} bytes (the whole loop with the link)", used, size);
    let ok = match result {
        Ok(s) => {
            let h = scenario.header();
            hprintln!(
                "pose error against the ground truth over the link: RMSE {} m and {} deg over {} readings",
                Fixed6(s.score.position_rmse_m),
                Fixed6(s.score.heading_rmse_deg),
                s.score.readings
            );
            if restarts.get() > 0 {
                // The host moved the estimate: the scenario's bounds are not this run's.
                hprintln!("link: {} restarts from the host; the pose bounds not judged", restarts.get());
                true
            } else {
                if !s.passed {
                    hprintln!(
                        "FAIL: beyond the scenario's bounds ({} m, {} deg)",
                        Fixed6(h.bound_position_m),
                        Fixed6(h.bound_heading_deg)
                    );
                }
                s.passed
            }
        }
        Err(e) => {
            hprintln!("FAIL: the loop stopped: {}", e);
            false
        }
    };
    exit(ok);
}
