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
use echoloc::scenario::{Scenario, FIXED_HEADER_LEN, MAGIC};
use qemu_mps2_an386::{calibrate, exit, flash_bytes, replay, start_systick};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

/// Where the scenario partition starts: past the 1 MiB image and the map partition's first MiB.
const PARTITION_START: usize = 0x0030_0000;
/// Its size: a scenario claiming more is refused before it is read.
const PARTITION_LEN: usize = 1024 * 1024;

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
    let Some(bytes) = partition() else { exit(false) };
    let net = CredenceNet::shipped();
    let ok = match replay::replay(bytes, &map, echoloc::map::crc32(&DEPOT.0), &net, &syst, per_tick) {
        Some(r) => {
            let h = Scenario::parse(bytes).map(|s| *s.header()).ok();
            replay::report(&r, h.map_or((0.0, 0.0), |h| (h.bound_position_m, h.bound_heading_deg)))
        }
        None => false,
    };
    exit(ok);
}

/// The scenario in the partition, its length from its header, bounded by
/// the partition (not yet validated: `Scenario::parse` does that).
fn partition() -> Option<&'static [u8]> {
    // SAFETY: PARTITION_START..+PARTITION_LEN lies in SSRAM1 (4 MiB at 0 on
    // mps2-an386), always mapped and readable, outside every region the
    // linker places anything in (FLASH 0..1 MiB, RAM at 0x2000_0000), and
    // nothing in this program writes it.
    let header: [u8; FIXED_HEADER_LEN] =
        unsafe { core::ptr::read_volatile(PARTITION_START as *const [u8; FIXED_HEADER_LEN]) };
    if header[..4] != MAGIC[..] {
        hprintln!("FAIL: no scenario at {:#010x}", PARTITION_START);
        return None;
    }
    let head = u16::from_le_bytes([header[6], header[7]]) as usize;
    let records = u32::from_le_bytes([header[16], header[17], header[18], header[19]]) as usize;
    let len = records.checked_mul(echoloc::scenario::RECORD_LEN).and_then(|r| r.checked_add(head + 4));
    let Some(len) = len.filter(|&n| n <= PARTITION_LEN) else {
        hprintln!("FAIL: the scenario header claims more than the {} byte partition holds: refused", PARTITION_LEN);
        return None;
    };
    // SAFETY: `len` ≤ PARTITION_LEN: inside the partition described above,
    // never written while the program runs, so valid as a `'static` slice.
    Some(unsafe { core::slice::from_raw_parts(PARTITION_START as *const u8, len) })
}
