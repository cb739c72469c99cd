//! Links the firmware with this package's STM32F429ZI `memory.x`, never the
//! workspace root's (the QEMU board's).
//!
//! cortex-m-rt's `link.x` says `INCLUDE memory.x`, and rust-lld resolves that
//! name in its working directory before any `-L` path; cargo runs rustc (and
//! so the linker) in the workspace root, where the QEMU board's `memory.x`
//! lives. Adding this directory to the search path, as the QEMU board adds
//! the root, is therefore not enough: the root's file would still win (it
//! did: the vector table landed at 0x0000_0000). So this script writes
//! `stm32f4-sonar.x` into `OUT_DIR`: cortex-m-rt's `link.x.in` (a pinned copy,
//! see `link.x.in`) with that one line replaced by an `INCLUDE` of this
//! package's `memory.x` by absolute path, followed by what cortex-m-rt's own
//! build script appends (the PAC's `device.x`, the vector-table size check)
//! and a check that FLASH and RAM are the STM32F429ZI's. The binary links
//! with `-T` on that file's absolute path.
use std::fmt::Write as _;
use std::path::PathBuf;

/// armv7em: at most 240 device interrupts (as cortex-m-rt's build script).
const MAX_INTERRUPTS: u32 = 240;

fn main() {
    let dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let memory = dir.join("memory.x");
    let template = std::fs::read_to_string(dir.join("link.x.in")).expect("link.x.in is in the package");

    let mut script = String::new();
    let mut replaced = 0;
    for line in template.lines() {
        if line.trim() == "INCLUDE memory.x" {
            writeln!(script, "INCLUDE \"{}\"", memory.display()).expect("writing to a String");
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
ASSERT(ORIGIN(RAM) == 0x20000000 && LENGTH(RAM) == 192K, "stm32f4-sonar: RAM is not the STM32F429ZI's: wrong memory.x");
"#,
        size = MAX_INTERRUPTS * 4 + 0x40,
    )
    .expect("writing to a String");
    let linker_script = out.join("stm32f4-sonar.x");
    std::fs::write(&linker_script, script).expect("OUT_DIR is writable");

    println!("cargo:rustc-link-arg-bins=-T{}", linker_script.display());
    // defmt's symbol table for the host-side decoder.
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=link.x.in");
    println!("cargo:rerun-if-changed=build.rs");
}
