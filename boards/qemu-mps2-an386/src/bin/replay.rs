//! Any scenario made on the depot map, replayed through the whole loop (the
//! ring driver over the replay bench, prediction, verdicts, EKF): the
//! scenario is not linked into the image but read in place from the flash
//! partition at [`PARTITION_START`], where QEMU's generic loader puts it:
//!
//! ```text
//! qemu-system-arm ... -device loader,file=X.scn,addr=0x00300000 -kernel target/thumbv7em-none-eabihf/release/replay
//! ```
//!
//! Exits 0 when the pose error is within the scenario's own bounds, 1
//! otherwise: a scenario refused (damaged, made on another map or for
//! another ring), a loop that stops, or a pose error beyond the bounds.
//! `scripts/replay-checks.sh` runs it on the committed scenario and on
//! planted failures.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::map::{Aligned, MapView};
use echoloc::scenario::Scenario;
use qemu_mps2_an386::replay::{self, SCENARIO_PARTITION as PARTITION_START};
use qemu_mps2_an386::{calibrate, exit, flash_bytes, start_systick};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

#[entry]
fn main() -> ! {
    let syst = start_systick();
    hprintln!(
        "echoloc {} on mps2-an386: a scenario from {:#010x} through the whole loop",
        env!("CARGO_PKG_VERSION"),
        PARTITION_START
    );
    let per_tick = calibrate(&syst);
    if flash_bytes() > PARTITION_START {
        hprintln!("FAIL: the image overlaps the scenario partition");
        exit(false);
    }
    let Ok(map) = MapView::new(&DEPOT.0) else {
        hprintln!("FAIL: depot map refused");
        exit(false);
    };
    let Some(bytes) = replay::scenario_partition() else { exit(false) };
    let net = CredenceNet::shipped();
    let ok = match replay::replay::<{ replay::PARTICLES }>(
        bytes,
        &map,
        echoloc::map::crc32(&DEPOT.0),
        &net,
        &syst,
        per_tick,
        None,
    ) {
        Some(r) => {
            let h = Scenario::parse(bytes).map(|s| *s.header()).ok();
            replay::report(&r, h.map_or((0.0, 0.0), |h| (h.bound_position_m, h.bound_heading_deg)))
        }
        None => false,
    };
    exit(ok);
}
