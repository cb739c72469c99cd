//! Big maps on the board (issue #11 item 5): a compiled map that is not
//! linked into the image but read in place from a separate flash partition,
//! validated, then timed with Pioneer rings as the main firmware times the
//! depot. `scripts/big-maps.sh` imports the depot tiled 1×1, 3×2 and 4×4
//! (about 430, 2 500 and 7 000 convex pieces) and runs this binary on each,
//! with the map file put into the emulated flash at [`PARTITION_START`] by
//! QEMU's generic loader:
//!
//! ```text
//! qemu-system-arm ... -device loader,file=X.map,addr=0x00200000 -kernel target/thumbv7em-none-eabihf/release/bigmap
//! ```
//!
//! The partition is `0x0020_0000..0x0040_0000` (2 MiB) of SSRAM1, which QEMU's
//! mps2-an386 maps at address 0 with 4 MiB; the firmware image lives in the
//! first 1 MiB (`memory.x`: FLASH 0x0..1024K), so nothing it links overlaps
//! the partition, and this binary checks that at run time too. A real board
//! would put the map in a flash partition of its own the same way (a linker
//! region, or a fixed sector range written by the flashing tool) and read it
//! with exactly this code: header through a pointer, length bounded by the
//! partition, then [`MapView::new`] validates every byte before anything
//! trusts it.
//!
//! Prints `metric map_validate_insns`, `map_bytes`, `pieces`,
//! `insns_per_ring`, `insns_per_ring_max` and `insns_per_window` (32 rings at
//! free poses spread through the map). Exits 0 on success, 1 on any failure:
//! no map, a length claim beyond the partition, a map that does not
//! validate, a failed prediction, too few echoes to time (HardFault and panic
//! exit 1 too).
//!
//! `cargo build -p qemu-mps2-an386 --bin bigmap --target thumbv7em-none-eabihf --release`
//! (running it needs the loader flag above: see `scripts/big-maps.sh`).
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::map::{MapSource, MapView, BLOB_HEADER_LEN};
use echoloc::predict::PredictParams;
use echoloc::window::WindowParams;
use qemu_mps2_an386::partition::{self, MapPartition};
use qemu_mps2_an386::{
    calibrate, elapsed, exit, flash_bytes, free_poses, metric, start_systick, ticks, time_rings, RingTimes,
};

/// Where the map partition starts ([`partition::MAP_PARTITION`]).
const PARTITION_START: usize = partition::MAP_PARTITION;
/// The partition's size: a map claiming more is refused before it is read.
const PARTITION_LEN: usize = partition::MAP_PARTITION_LEN;
/// Rings timed, at free poses spread through the map.
const POSES: usize = 32;
/// Candidate positions the pose generator may try before giving up.
const MAX_TRIES: u32 = 200_000;

#[entry]
fn main() -> ! {
    let syst = start_systick();
    hprintln!(
        "echoloc {} on mps2-an386: a big map from the flash partition at {:#010x}",
        env!("CARGO_PKG_VERSION"),
        PARTITION_START
    );
    let per_tick = calibrate(&syst);
    if flash_bytes() > PARTITION_START {
        hprintln!("FAIL: the image ({} bytes) overlaps the map partition", flash_bytes());
        exit(false);
    }
    let Some(blob) = partition_map() else { exit(false) };

    let t0 = ticks(&syst);
    let map = MapView::new(black_box(blob));
    let validate = elapsed(t0, ticks(&syst)) * per_tick;
    let map = match map {
        Ok(v) => v,
        Err(e) => {
            hprintln!("FAIL: the map ({} bytes) does not validate: {:?}", blob.len(), e);
            exit(false);
        }
    };
    let (cell, cols, rows) = map.grid_dims();
    hprintln!(
        "map: {} bytes read in place, {} obstacles, {} convex pieces, {} edges, t_b {} mm, grid {}x{} of {} mm, {} refs; validated",
        blob.len(),
        map.obstacle_count(),
        map.piece_count(),
        map.true_vertex_count(),
        map.buffer_mm(),
        cols,
        rows,
        cell,
        map.grid_refs()
    );
    if let Some(b) = map.bounds() {
        hprintln!("bounds: ({}, {}) .. ({}, {}) mm", b.min.x, b.min.y, b.max.x, b.max.y);
    }
    metric("map_validate_insns", validate as u64);
    metric("map_bytes", blob.len() as u64);
    metric("pieces", map.piece_count() as u64);

    let net = CredenceNet::shipped();
    let params = PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE });
    let poses = free_poses::<POSES>(&map, MAX_TRIES);
    if poses.len() < POSES {
        hprintln!("FAIL: only {} free poses found in {} tries", poses.len(), MAX_TRIES);
        exit(false);
    }
    let RingTimes { total, worst, predicted, ok: rings_ok } = time_rings(&map, &poses, &params, &net, &syst, per_tick);
    let mut ok = rings_ok;
    let rings = poses.len() as u64;
    hprintln!("{} rings at free poses, {} of {} windows predicted an echo", rings, predicted, rings * 16);
    if predicted < POSES * 4 {
        hprintln!("FAIL: too few predictions for the timing to mean anything");
        ok = false;
    }
    metric("insns_per_ring", total / rings);
    metric("insns_per_ring_max", worst);
    metric("insns_per_window", total / (rings * 16));
    exit(ok);
}

/// The map in the partition ([`partition::read_map`]); `None`, with a FAIL
/// line, when there is no map header or the header claims more than the
/// partition holds.
fn partition_map() -> Option<&'static [u8]> {
    match partition::read_map(PARTITION_LEN) {
        MapPartition::Map(b) => Some(b),
        MapPartition::Empty(h) => {
            hprintln!("FAIL: no map at {:#010x} (header starts {:02x?})", PARTITION_START, h);
            None
        }
        MapPartition::TooLong(payload_len) => {
            hprintln!(
                "FAIL: the map header claims {} + {} bytes, more than the {} byte partition holds: refused",
                BLOB_HEADER_LEN,
                payload_len,
                PARTITION_LEN
            );
            None
        }
    }
}
