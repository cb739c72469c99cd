//! Puts the workspace root (where `memory.x` lives) on the linker's search
//! path and links with cortex-m-rt's `link.x`.
use std::path::PathBuf;

fn main() {
    let dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    println!("cargo:rustc-link-search={}", dir.join("../..").display());
    println!("cargo:rerun-if-changed=../../memory.x");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
}
