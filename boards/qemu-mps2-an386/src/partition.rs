//! A compiled map read in place from a flash partition instead of linked
//! into the image: a robot's map changes more often than its firmware
//! (DESIGN §10). QEMU's generic loader puts the map file there:
//!
//! ```text
//! qemu-system-arm ... -device loader,file=X.map,addr=0x00200000 -kernel …
//! ```
//!
//! The partition starts at [`MAP_PARTITION`] in SSRAM1, which QEMU's
//! mps2-an386 maps at address 0 with 4 MiB; the image lives in the first
//! 1 MiB (`memory.x`: FLASH 0x0..1024K), so nothing linked overlaps it (the
//! binaries check that at run time too). `--bin bigmap` has it to itself
//! ([`MAP_PARTITION_LEN`], 2 MiB); `--bin replay` shares the upper MiB with
//! the scenario partition ([`crate::replay::SCENARIO_PARTITION`]), so a map
//! there may take [`MAP_PARTITION_LEN_WITH_SCENARIO`]. A real board would put
//! the map in a flash partition of its own the same way and read it with
//! this code: header through a pointer, length bounded by the partition,
//! then `MapView::new` validates every byte before anything trusts it.

use echoloc::map::{BLOB_HEADER_LEN, BLOB_MAGIC};

/// Where the map partition starts: 4-byte aligned, past the 1 MiB image.
pub const MAP_PARTITION: usize = 0x0020_0000;
/// Its size when nothing else shares it.
pub const MAP_PARTITION_LEN: usize = 2 * 1024 * 1024;
/// Its size below the scenario partition.
pub const MAP_PARTITION_LEN_WITH_SCENARIO: usize = crate::replay::SCENARIO_PARTITION - MAP_PARTITION;

/// What the partition holds.
pub enum MapPartition {
    /// A map header and a length that fits: the whole blob, not yet validated.
    Map(&'static [u8]),
    /// No map header (the first four bytes).
    Empty([u8; 4]),
    /// A header claiming this many payload bytes, more than the partition holds.
    TooLong(usize),
}

/// Reads the partition's header and bounds the map by `len` bytes (at most
/// [`MAP_PARTITION_LEN`]).
pub fn read_map(len: usize) -> MapPartition {
    let len_max = len.min(MAP_PARTITION_LEN);
    // SAFETY: MAP_PARTITION..+MAP_PARTITION_LEN lies in SSRAM1 (4 MiB at 0 on
    // mps2-an386), always mapped and readable, 4-byte aligned, and outside
    // every region the linker places anything in (FLASH is 0..1 MiB, RAM at
    // 0x2000_0000); nothing in these programs writes it. Reading 16 bytes from
    // its start is therefore a read of plain, initialised memory.
    let header: [u8; BLOB_HEADER_LEN] =
        unsafe { core::ptr::read_volatile(MAP_PARTITION as *const [u8; BLOB_HEADER_LEN]) };
    if header[..4] != BLOB_MAGIC[..] {
        return MapPartition::Empty([header[0], header[1], header[2], header[3]]);
    }
    let payload_len = u32::from_le_bytes([header[8], header[9], header[10], header[11]]) as usize;
    let Some(n) = payload_len.checked_add(BLOB_HEADER_LEN).filter(|&n| n <= len_max) else {
        return MapPartition::TooLong(payload_len);
    };
    // SAFETY: `n` ≤ len_max ≤ MAP_PARTITION_LEN, so the slice stays inside the
    // partition described above: mapped, aligned, initialised, and never
    // written while the program runs, hence valid as an immutable `'static`
    // slice.
    MapPartition::Map(unsafe { core::slice::from_raw_parts(MAP_PARTITION as *const u8, n) })
}
