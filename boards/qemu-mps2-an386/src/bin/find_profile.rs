//! A fixed workload for an instruction profile of the localizer while it
//! searches: the main firmware's find-itself scenario (`depot-find.scn`,
//! no start pose, the same seed) through the whole loop, stopped after the
//! first four ring cycles, all of them searching. `BIN=find_profile bash
//! scripts/m4-profile.sh` runs it under QEMU's execution log and says
//! where a searching cycle's instructions go (issue #36 item 4).
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::controller::replay::check;
use echoloc::credence::net::CredenceNet;
use echoloc::localize::{Mode, Start};
use echoloc::map::{Aligned, MapView};
use echoloc::predict::Mount;
use echoloc::scenario::replay::Bench;
use echoloc::scenario::Scenario;
use qemu_mps2_an386::exit;
use qemu_mps2_an386::replay::{run_loop, setup, PARTICLES, POLL_STEP_US, TRANSDUCERS};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));
static FIND: &[u8] = include_bytes!("../../depot-find.scn");
/// The main firmware's seed for this scenario.
const SEED: u64 = 6;
/// Ring cycles profiled (the scenario's first ones search).
const CYCLES: u32 = 4;

#[entry]
fn main() -> ! {
    let Ok(map) = MapView::new(&DEPOT.0) else { exit(false) };
    let Ok(scenario) = Scenario::parse(FIND) else { exit(false) };
    let Some(setup) = setup(&map) else { exit(false) };
    let mut mounts = [Mount { x_mm: 0, y_mm: 0, heading_mdeg: 0 }; TRANSDUCERS];
    for (i, m) in mounts.iter_mut().enumerate() {
        *m = scenario.mount(i).unwrap_or(*m);
    }
    let bench = Bench::new(scenario, POLL_STEP_US);
    if check(&bench, echoloc::map::crc32(&DEPOT.0), &setup).is_err() {
        exit(false);
    }
    let net = CredenceNet::shipped();
    let mut cycles = 0u32;
    // The board's own loop (the main firmware's find-itself replay), left
    // after CYCLES cycles.
    let _ = run_loop::<PARTICLES>(&bench, &map, &mounts, &net, &setup, Some(Start::Unknown), SEED, &mut |_, ended| {
        if let Some(mode) = ended {
            cycles += 1;
            if mode != Mode::Searching {
                hprintln!("FAIL: cycle {} did not end searching", cycles);
                exit(false);
            }
            if cycles == CYCLES {
                hprintln!("{} searching cycles", CYCLES);
                exit(true);
            }
        }
    });
    exit(false);
}
