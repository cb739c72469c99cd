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
use echoloc::geometry::{Point, Rect, Segment};
use echoloc::map::{MapSource, MapView, BLOB_HEADER_LEN, BLOB_MAGIC};
use echoloc::predict::{predict_ring, Pose, PredictParams, PIONEER16};
use echoloc::window::WindowParams;
use qemu_mps2_an386::{calibrate, elapsed, exit, flash_bytes, metric, start_systick, ticks};

/// Where the map partition starts: 4-byte aligned, past the 1 MiB image.
const PARTITION_START: usize = 0x0020_0000;
/// The partition's size: a map claiming more is refused before it is read.
const PARTITION_LEN: usize = 2 * 1024 * 1024;
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
    let poses = free_poses(&map);
    if poses.len() < POSES {
        hprintln!("FAIL: only {} free poses found in {} tries", poses.len(), MAX_TRIES);
        exit(false);
    }
    let mut ok = true;
    let (mut total, mut worst, mut predicted) = (0u64, 0u64, 0usize);
    for pose in poses.iter() {
        let mut out = [None; 16];
        let t0 = ticks(&syst);
        let r = predict_ring(&map, black_box(pose), &PIONEER16, &params, &net, &mut out);
        let t = (elapsed(t0, ticks(&syst)) * per_tick) as u64;
        if let Err(e) = r {
            hprintln!("FAIL: ring at {:?}: {:?}", pose, e);
            ok = false;
        }
        predicted += out.iter().flatten().count();
        total += t;
        worst = worst.max(t);
    }
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

/// The map in the partition: its header read through a pointer, its length
/// bounded by the partition, then the whole blob as a `'static` slice (not
/// yet validated). `None`, with a FAIL line, when there is no map header or
/// the header claims more than the partition holds.
fn partition_map() -> Option<&'static [u8]> {
    // SAFETY: PARTITION_START..+PARTITION_LEN lies in SSRAM1 (4 MiB at 0 on
    // mps2-an386), always mapped and readable, 4-byte aligned, and outside
    // every region the linker places anything in (FLASH is 0..1 MiB, RAM at
    // 0x2000_0000); nothing in this program writes it. Reading 16 bytes from
    // its start is therefore a read of plain, initialised memory.
    let header: [u8; BLOB_HEADER_LEN] =
        unsafe { core::ptr::read_volatile(PARTITION_START as *const [u8; BLOB_HEADER_LEN]) };
    if header[..4] != BLOB_MAGIC[..] {
        hprintln!("FAIL: no map at {:#010x} (header starts {:02x?})", PARTITION_START, &header[..4]);
        return None;
    }
    let payload_len = u32::from_le_bytes([header[8], header[9], header[10], header[11]]) as usize;
    let Some(len) = payload_len.checked_add(BLOB_HEADER_LEN).filter(|&n| n <= PARTITION_LEN) else {
        hprintln!(
            "FAIL: the map header claims {} + {} bytes, more than the {} byte partition holds: refused",
            BLOB_HEADER_LEN,
            payload_len,
            PARTITION_LEN
        );
        return None;
    };
    // SAFETY: `len` ≤ PARTITION_LEN, so the slice stays inside the partition
    // described above: mapped, aligned, initialised, and never written while
    // the program runs, hence valid as an immutable `'static` slice.
    Some(unsafe { core::slice::from_raw_parts(PARTITION_START as *const u8, len) })
}

/// Up to `POSES` poses spread through the map's free space by the main
/// firmware's fixed generator: none inside a piece, none with a piece within
/// 300 mm along either axis. Gives up after `MAX_TRIES` candidates.
fn free_poses(map: &MapView<'_>) -> heapless::Vec<Pose, POSES> {
    let mut out = heapless::Vec::new();
    let Some(b) = map.bounds() else { return out };
    let mut s = 0x2545_F491u32;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s
    };
    let mut tries = 0;
    while !out.is_full() && tries < MAX_TRIES {
        tries += 1;
        let x = b.min.x + (next() % (b.max.x - b.min.x).max(1) as u32) as i32;
        let y = b.min.y + (next() % (b.max.y - b.min.y).max(1) as u32) as i32;
        let heading = (next() % 6283) as f32 / 1000.0 - core::f32::consts::PI;
        let p = Point::new(x, y);
        let mut free = true;
        let _ = map.for_each_candidate(Rect::around(p), |piece| {
            free &= !piece.shape.tvector(p).is_inside();
        });
        for seg in [
            Segment::new(Point::new(x - 300, y), Point::new(x + 300, y)),
            Segment::new(Point::new(x, y - 300), Point::new(x, y + 300)),
        ] {
            free &= matches!(map.first_hit(seg), Ok(None));
        }
        if free {
            let _ = out.push(Pose { x_mm: x as f32, y_mm: y as f32, heading_rad: heading });
        }
    }
    out
}
