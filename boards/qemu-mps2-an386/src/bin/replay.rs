//! Any scenario, on the map it was made on, replayed through the whole loop
//! (the ring driver over the replay bench, prediction, verdicts, EKF). The
//! scenario is not linked into the image but read in place from the flash
//! partition at [`SCENARIO_PARTITION`]; the map likewise from the map
//! partition at [`MAP_PARTITION`] when one is there (as `--bin bigmap` reads
//! it), else the depot map linked into the image. QEMU's generic loader puts
//! both files in place:
//!
//! ```text
//! qemu-system-arm ... -device loader,file=X.map,addr=0x00200000 -device loader,file=X.scn,addr=0x00300000 \
//!   -kernel target/thumbv7em-none-eabihf/release/replay
//! ```
//!
//! `echoloc-lab board` does all of it for a robot's log or bag (docs/log.md).
//! Exits 0 when the pose error is within the scenario's own bounds, 1
//! otherwise: a scenario refused (damaged, made on another map or for
//! another ring), a map refused, a loop that stops, or a pose error beyond
//! the bounds. `scripts/replay-checks.sh` runs it on the committed scenario
//! and on planted failures.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::map::{Aligned, MapView};
use echoloc::scenario::Scenario;
use qemu_mps2_an386::partition::{read_map, MapPartition, MAP_PARTITION, MAP_PARTITION_LEN_WITH_SCENARIO};
use qemu_mps2_an386::replay::{self, SCENARIO_PARTITION};
use qemu_mps2_an386::{calibrate, exit, flash_bytes, start_systick};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

#[entry]
fn main() -> ! {
    let syst = start_systick();
    hprintln!(
        "echoloc {} on mps2-an386: a scenario from {:#010x} through the whole loop",
        env!("CARGO_PKG_VERSION"),
        SCENARIO_PARTITION
    );
    let per_tick = calibrate(&syst);
    if flash_bytes() > MAP_PARTITION {
        hprintln!("FAIL: the image overlaps the map and scenario partitions");
        exit(false);
    }
    let blob: &[u8] = match read_map(MAP_PARTITION_LEN_WITH_SCENARIO) {
        MapPartition::Map(b) => {
            hprintln!("map: {} bytes from the partition at {:#010x}", b.len(), MAP_PARTITION);
            b
        }
        MapPartition::Empty(_) => {
            hprintln!("map: the depot, linked into the image ({} bytes)", DEPOT.0.len());
            &DEPOT.0
        }
        MapPartition::TooLong(n) => {
            hprintln!(
                "FAIL: the map header at {:#010x} claims {} bytes, more than the {} byte partition below the scenario's",
                MAP_PARTITION,
                n,
                MAP_PARTITION_LEN_WITH_SCENARIO
            );
            exit(false);
        }
    };
    let map = match MapView::new(blob) {
        Ok(m) => m,
        Err(e) => {
            hprintln!("FAIL: the map ({} bytes) does not validate: {:?}", blob.len(), e);
            exit(false);
        }
    };
    let Some(bytes) = replay::scenario_partition() else { exit(false) };
    let net = CredenceNet::shipped();
    let ok = match replay::replay::<{ replay::PARTICLES }>(
        bytes,
        &map,
        echoloc::map::crc32(blob),
        &net,
        &syst,
        per_tick,
        None,
        1,
    ) {
        Some(r) => {
            let h = Scenario::parse(bytes).map(|s| *s.header()).ok();
            replay::report(&r, h.map_or((0.0, 0.0), |h| (h.bound_position_m, h.bound_heading_deg)))
        }
        None => false,
    };
    exit(ok);
}
