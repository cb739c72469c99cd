//! Compiles the robot's ROS map (`map/room.yaml` and its image) into the
//! firmware's map blob at build time, with the same importer `echoloc-lab
//! map import` uses: a firmware crate does exactly this and then
//! `include_bytes!`s `$OUT_DIR/room.map` (see `src/main.rs`). The map in the
//! image is then always the one in the repository, and a map the firmware
//! would refuse fails the build.

use std::path::Path;

use echoloc_lab::map::{import, ImportOptions};

fn main() {
    let yaml = Path::new("map/room.yaml");
    println!("cargo::rerun-if-changed=map/room.yaml");
    println!("cargo::rerun-if-changed=map/room.pgm");
    // A 100 mm C-space buffer, 1 m grid cells (grown if the grid needs it).
    let (blob, summary, _) = import(yaml, 100, 1000, &ImportOptions::default())
        .unwrap_or_else(|e| panic!("cannot compile {}: {e}", yaml.display()));
    let out = Path::new(&std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("room.map");
    std::fs::write(&out, &blob).unwrap_or_else(|e| panic!("{}: {e}", out.display()));
    // The import's summary beside it, for whoever wants to look.
    let _ = std::fs::write(out.with_extension("json"), summary.to_json());
}
