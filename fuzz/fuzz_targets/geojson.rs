//! The GeoJSON importer on arbitrary text: parsing, then the whole map
//! build (convex splitting, holes, buffers, grid, compiled form) on what it
//! accepts. No panic; and whatever the import accepts, the firmware's
//! validator accepts too (an import must never write a map the board
//! refuses).
#![no_main]

use echoloc::map::MapView;
use echoloc_lab::map::{build_map, geojson, AlignedBytes, Shape};
use libfuzzer_sys::fuzz_target;

/// Above this many vertices an input is parsed but not built: the build is
/// exercised on big inputs by the test command's own maps, and the fuzzer
/// should spend its time on many small ones.
const MAX_VERTICES: usize = 4_000;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(shapes) = geojson::parse(text) else { return };
    build_and_validate(&shapes);
});

fn build_and_validate(shapes: &[Shape]) {
    let vertices: usize = shapes.iter().map(Shape::vertex_count).sum();
    if vertices > MAX_VERTICES {
        return;
    }
    if let Ok((blob, _)) = build_map(shapes, 100, 1000) {
        let aligned = AlignedBytes::new(&blob);
        if let Err(e) = MapView::new(aligned.bytes()) {
            panic!("the import wrote a map the firmware refuses: {e:?}");
        }
    }
}
