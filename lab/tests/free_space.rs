//! Free space inside the building (issue #37, item 5): on the two-room
//! GeoJSON map, the localizer started from no pose (`Start::Unknown`, the
//! particles drawn from the field's free nodes) puts no particle outside
//! the building. The oracle is the building drawn by hand from
//! `data/two-rooms.geojson` (axis-aligned rectangles), not the importer's
//! enclosure; the same map compiled with the old free space (the obstacles'
//! bounding box) does put particles outside, so the test can fail.

mod common;

use echoloc::localize::{Localizer, LocalizerConfig, Start};
use echoloc::map::MapView;
use echoloc::referencing::{EkfConfig, VerdictConfig};
use echoloc_lab::map::{build_map_with, import, read_source, AlignedBytes, FieldOptions, ImportOptions};

/// (free nodes, free nodes outside the building, particles outside the
/// building over `seeds`) of a compiled map.
fn count(blob: &[u8], seeds: std::ops::RangeInclusive<u64>) -> (u32, u32, usize) {
    let a = AlignedBytes::new(blob);
    let view = MapView::new(a.bytes()).unwrap();
    let field = view.field();
    let mut outside_nodes = 0;
    for n in 0..field.nodes() {
        if field.is_free(n) {
            let (x, y) = field.position_mm(n).unwrap();
            if !common::in_two_rooms(f64::from(x) / 1e3, f64::from(y) / 1e3) {
                outside_nodes += 1;
            }
        }
    }
    let mut outside_particles = 0;
    for seed in seeds {
        let mut loc: Box<Localizer<1024>> =
            Box::new(Localizer::new(LocalizerConfig::DEFAULT, EkfConfig::DEFAULT, VerdictConfig::POLAROID, seed));
        loc.start(Start::Unknown, field).unwrap();
        let poses = loc.particles().poses();
        assert_eq!(poses.len(), 1024);
        outside_particles += poses.iter().filter(|p| !common::in_two_rooms(f64::from(p[0]), f64::from(p[1]))).count();
    }
    (field.free_nodes(), outside_nodes, outside_particles)
}

#[test]
fn no_particle_is_drawn_outside_the_two_room_building() {
    let path = common::root().join("lab/tests/data/two-rooms.geojson");
    let opt = ImportOptions::default();
    let (new, summary, _) = import(&path, 100, 1000, &opt).unwrap();
    // The old free space: the same shapes and field, no building.
    let src = read_source(&path, &opt).unwrap();
    let (old, _) = build_map_with(&src.shapes, 100, 1000, Some((&FieldOptions::default(), None))).unwrap();
    assert_eq!(summary.extra["free_space"]["from"], "enclosed by the walls", "{:?}", summary.extra);
    let (free, nodes_out, particles_out) = count(&new, 1..=5);
    let (old_free, old_nodes_out, old_particles_out) = count(&old, 1..=5);
    eprintln!(
        "two rooms: free nodes {old_free} → {free}; outside the building {old_nodes_out} → {nodes_out}; \
         particles outside over seeds 1–5 (1 024 each) {old_particles_out} → {particles_out}"
    );
    // The old free space reached outside (the oracle can see it) ...
    assert!(old_nodes_out > 0 && old_particles_out > 0);
    // ... and every node it dropped was outside: inside, nothing changed.
    assert_eq!(old_free - free, old_nodes_out);
    // Now: nothing outside.
    assert_eq!((nodes_out, particles_out), (0, 0));
}
