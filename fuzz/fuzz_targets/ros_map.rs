//! The ROS map_server importer on arbitrary input: the bytes before the
//! first 0x00 are the YAML text, the rest the image (PGM or PNG). Parsing,
//! decoding, classification, contour tracing, simplification and the whole
//! map build on what is accepted. No panic; and whatever the import
//! accepts, the firmware's validator accepts too.
#![no_main]

use std::path::Path;

use echoloc::map::MapView;
use echoloc_lab::map::{build_map, grid_shapes, ros, AlignedBytes, ImportOptions, Shape, Unknown};
use libfuzzer_sys::fuzz_target;

/// Images above this many cells are decoded but not traced (the real maps
/// run in the test command; the fuzzer should spend its time on many small
/// inputs).
const MAX_CELLS: usize = 1 << 16;
const MAX_VERTICES: usize = 4_000;

fuzz_target!(|data: &[u8]| {
    let (yaml, image) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let Ok(text) = std::str::from_utf8(yaml) else { return };
    let path = Path::new("/fuzz/map.yaml");
    let Ok(y) = ros::parse_yaml(path, text) else { return };
    let Ok(img) = ros::decode_image(image) else { return };
    assert_eq!(img.value.len(), img.width * img.height, "decoded values disagree with the size");
    if let Some(a) = &img.alpha {
        assert_eq!(a.len(), img.value.len(), "decoded alpha disagrees with the size");
    }
    if img.width * img.height > MAX_CELLS {
        return;
    }
    // Both ways of reading unknown cells, as `--unknown` chooses.
    for unknown in [Unknown::Free, Unknown::Occupied] {
        let grid = ros::grid_of(y.clone(), &img);
        let opt = ImportOptions { unknown, ..ImportOptions::default() };
        let Ok((shapes, _)) = grid_shapes(path, &grid, &opt) else { continue };
        let vertices: usize = shapes.iter().map(Shape::vertex_count).sum();
        if vertices > MAX_VERTICES {
            continue;
        }
        if let Ok((blob, _)) = build_map(&shapes, 100, 1000) {
            let aligned = AlignedBytes::new(&blob);
            if let Err(e) = MapView::new(aligned.bytes()) {
                panic!("the import wrote a map the firmware refuses: {e:?}");
            }
        }
    }
});
