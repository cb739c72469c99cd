//! Links the firmware with this package's STM32F429ZI `memory.x`, never the
//! workspace root's (the QEMU board's), in a form `flip-link` can flip.
//!
//! cortex-m-rt's `link.x` says `INCLUDE memory.x`, and rust-lld resolves that
//! name in its working directory before any `-L` path; cargo runs rustc (and
//! so the linker) in the workspace root, where the QEMU board's `memory.x`
//! lives. Adding this directory to the search path, as the QEMU board adds
//! the root, is therefore not enough: the root's file would still win (it
//! did: the vector table landed at 0x0000_0000). So this script writes
//! `stm32f4-sonar.x` into `OUT_DIR`: cortex-m-rt's `link.x.in` (a pinned copy,
//! see `link.x.in`) with that one line replaced by the contents of this
//! package's `memory.x`, followed by what cortex-m-rt's own build script
//! appends (the PAC's `device.x`, the vector-table size check) and a check
//! that FLASH and RAM are the STM32F429ZI's.
//!
//! The binary links with `-Tstm32f4-sonar.x` by name, `OUT_DIR` on the search
//! path (no file of that name is in the workspace root), and `memory.x` is
//! inlined rather than included: `flip-link` (the linker for this board, see
//! `scripts/thumb-link.sh`) finds the `RAM` line in the script it is given,
//! writes a copy with RAM moved to the top into a folder of its own and links
//! again from there, where that copy wins by name. The stack then lies below
//! `.data`/`.bss`, and an overflow runs off the bottom of RAM into a fault
//! instead of into the statics.
use std::fmt::Write as _;
use std::path::PathBuf;

/// armv7em: at most 240 device interrupts (as cortex-m-rt's build script).
const MAX_INTERRUPTS: u32 = 240;

fn main() {
    let dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let memory = dir.join("memory.x");
    let template = std::fs::read_to_string(dir.join("link.x.in")).expect("link.x.in is in the package");
    let memory_x = std::fs::read_to_string(&memory).expect("memory.x is in the package");

    let mut script = String::new();
    let mut replaced = 0;
    for line in template.lines() {
        if line.trim() == "INCLUDE memory.x" {
            // Inlined, not included by path: flip-link must see (and rewrite) the RAM line.
            writeln!(script, "/* {} */", memory.display()).expect("writing to a String");
            writeln!(script, "{memory_x}").expect("writing to a String");
            replaced += 1;
        } else {
            writeln!(script, "{line}").expect("writing to a String");
        }
    }
    assert_eq!(replaced, 1, "link.x.in must include memory.x exactly once");
    write!(
        script,
        r#"
/* Provides weak aliases (cf. PROVIDED) for device specific interrupt handlers */
/* This will usually be provided by a device crate generated using svd2rust (see `device.x`) */
INCLUDE device.x

ASSERT(SIZEOF(.vector_table) <= 0x{size:x}, "
There can't be more than {MAX_INTERRUPTS} interrupt handlers. This may be a bug in
your device crate, or you may have registered more than {MAX_INTERRUPTS} interrupt
handlers.");

/* The memory must be this package's (STM32F429ZI), not the QEMU board's. */
ASSERT(ORIGIN(FLASH) == 0x08000000 && LENGTH(FLASH) == 2048K, "stm32f4-sonar: FLASH is not the STM32F429ZI's: wrong memory.x");
/* flip-link's second link moves ORIGIN(RAM) up (keeping its end) and puts the stack below it. */
ASSERT(ORIGIN(RAM) >= 0x20000000 && ORIGIN(RAM) + LENGTH(RAM) == 0x20000000 + 192K, "stm32f4-sonar: RAM is not the STM32F429ZI's: wrong memory.x");
"#,
        size = MAX_INTERRUPTS * 4 + 0x40,
    )
    .expect("writing to a String");
    let linker_script = out.join("stm32f4-sonar.x");
    std::fs::write(&linker_script, script).expect("OUT_DIR is writable");

    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tstm32f4-sonar.x");
    // defmt's symbol table for the host-side decoder.
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=link.x.in");
    println!("cargo:rerun-if-changed=build.rs");
}
