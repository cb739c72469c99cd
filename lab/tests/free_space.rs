//! Free space inside the building (issue #37, item 5; issue #47): on the
//! two-room GeoJSON map and on a floor plan drawn with its doorways and
//! entrance open (`data/doorways.geojson`), the localizer started from no
//! pose (`Start::Unknown`, the particles drawn from the field's free nodes)
//! puts no particle outside the building, and every room is inside. The
//! oracle is each building drawn by hand (axis-aligned rectangles), not the
//! importer's enclosure; the same maps compiled with the old free space (the
//! obstacles' bounding box) or the walls alone (`--door-mm 0`) do put
//! particles outside or lose the rooms, so the tests can fail.

mod common;

use echoloc::localize::{Localizer, LocalizerConfig, Start};
use echoloc::map::MapView;
use echoloc::referencing::{EkfConfig, VerdictConfig};
use echoloc_lab::map::free_space::FreeSpace;
use echoloc_lab::map::{build_map_with, import, read_source, AlignedBytes, FieldOptions, ImportOptions};

/// (free nodes, free nodes outside the building, particles outside the
/// building over `seeds`) of a compiled map of the two rooms.
fn count(blob: &[u8], seeds: std::ops::RangeInclusive<u64>) -> (u32, u32, usize) {
    count_in(blob, seeds, common::in_two_rooms)
}

/// (free nodes, free nodes outside `inside`, particles outside `inside`
/// over `seeds`) of a compiled map.
fn count_in(blob: &[u8], seeds: std::ops::RangeInclusive<u64>, inside: fn(f64, f64) -> bool) -> (u32, u32, usize) {
    let a = AlignedBytes::new(blob);
    let view = MapView::new(a.bytes()).unwrap();
    let field = view.field();
    let mut outside_nodes = 0;
    for n in 0..field.nodes() {
        if field.is_free(n) {
            let (x, y) = field.position_mm(n).unwrap();
            if !inside(f64::from(x) / 1e3, f64::from(y) / 1e3) {
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
        outside_particles += poses.iter().filter(|p| !inside(f64::from(p[0]), f64::from(p[1]))).count();
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

#[test]
fn doors_change_nothing_on_the_two_rooms() {
    // Its only gaps are the yards' 2 m mouths, wider than a door: the blob
    // with doors closed (the default) is the blob of the walls alone.
    let path = common::root().join("lab/tests/data/two-rooms.geojson");
    let (with_doors, summary, _) = import(&path, 100, 1000, &ImportOptions::default()).unwrap();
    let (walls_alone, _, _) = import(&path, 100, 1000, &ImportOptions { door_mm: 0, ..Default::default() }).unwrap();
    assert!(with_doors == walls_alone, "the blobs differ");
    assert_eq!(summary.extra["free_space"]["door_mm"], 1200);
    assert!(summary.extra["free_space"].get("warning").is_none(), "{:?}", summary.extra);
}

/// The building of `data/doorways.geojson`, by hand: 20 m × 12 m, its
/// entrance a 1.2 m gap in the south wall (x 9.4–10.6), a corridor
/// (y 5–7) with doors of 0.8–1.2 m into three rooms south and four north.
const DOORWAYS_ROOMS: [(f64, f64, f64, f64); 8] = [
    (0.0, 6.0, 0.0, 5.0),
    (6.0, 14.0, 0.0, 5.0),
    (14.0, 20.0, 0.0, 5.0),
    (0.0, 20.0, 5.0, 7.0),
    (0.0, 5.0, 7.0, 12.0),
    (5.0, 10.0, 7.0, 12.0),
    (10.0, 15.0, 7.0, 12.0),
    (15.0, 20.0, 7.0, 12.0),
];

/// Its three pieces of furniture.
const DOORWAYS_BOXES: [(f64, f64, f64, f64); 3] =
    [(0.5, 2.5, 0.5, 1.3), (16.0, 18.0, 9.0, 10.0), (11.0, 12.0, 2.0, 3.0)];

fn in_doorways(x: f64, y: f64) -> bool {
    let within = |r: &(f64, f64, f64, f64)| x > r.0 && x < r.1 && y > r.2 && y < r.3;
    x > 0.0 && x < 20.0 && y > 0.0 && y < 12.0 && !DOORWAYS_BOXES.iter().any(within)
}

#[test]
fn a_floor_plan_with_open_doorways_is_inside_and_nothing_outside() {
    let path = common::root().join("lab/tests/data/doorways.geojson");
    let src = read_source(&path, &ImportOptions::default()).unwrap();
    let Some(free) = &src.free_polygons else { panic!("a GeoJSON source") };
    let space = FreeSpace::of(&src.shapes, free, 1200);
    let FreeSpace::Enclosed(e) = &space else { panic!("{space:?}") };
    assert_eq!(e.door_mm(), 1200);
    // Against the building by hand, on a 37 mm raster (not the lattice's)
    // from 4 m outside it: inside the outer walls and no furniture, less
    // the walls (points within 2 mm) and the entrance's own line (points
    // within 0.1 m of it are where the doorway is split between inside and
    // outside, the module's step 4).
    let walls = [0.0, 5.0, 6.0, 7.0, 10.0, 12.0, 14.0, 15.0, 20.0];
    let (mut checked, mut inside) = (0, 0);
    for i in 0..=760 {
        for j in 0..=540 {
            let (x, y) = (-4.0 + 0.037 * f64::from(i), -4.0 + 0.037 * f64::from(j));
            let on_wall = walls.iter().any(|&w| (x - w).abs() < 0.002 || (y - w).abs() < 0.002);
            let at_entrance = y.abs() < 0.1 && x > 9.3 && x < 10.7;
            if on_wall || at_entrance {
                continue;
            }
            let want = in_doorways(x, y);
            assert_eq!(space.contains(x * 1e3, y * 1e3), want, "({x:.3}, {y:.3})");
            checked += 1;
            inside += usize::from(want);
        }
    }
    assert!(checked > 400_000 && inside > 150_000, "{checked} {inside}");
    // Every room holds free nodes (3 m² and more) and no node is outside.
    let (blob, summary, _) = import(&path, 100, 1000, &ImportOptions::default()).unwrap();
    assert!(summary.extra["free_space"].get("warning").is_none(), "{:?}", summary.extra);
    let a = AlignedBytes::new(&blob);
    let view = MapView::new(a.bytes()).unwrap();
    let field = view.field();
    for r in DOORWAYS_ROOMS {
        let n = (0..field.nodes())
            .filter(|&n| field.is_free(n))
            .filter_map(|n| field.position_mm(n))
            .filter(|&(x, y)| {
                let (x, y) = (f64::from(x) / 1e3, f64::from(y) / 1e3);
                x > r.0 && x < r.1 && y > r.2 && y < r.3
            })
            .count();
        assert!(n >= 48, "{r:?}: {n} free nodes");
    }
    let (free, nodes_out, particles_out) = count_in(&blob, 1..=5, in_doorways);
    // The walls alone enclose nothing here: the bounding box, as before #37.
    let (old, old_summary, _) = import(&path, 100, 1000, &ImportOptions { door_mm: 0, ..Default::default() }).unwrap();
    assert_eq!(old_summary.extra["free_space"]["from"], "bounding box");
    let (old_free, old_nodes_out, old_particles_out) = count_in(&old, 1..=5, in_doorways);
    eprintln!(
        "doorways: free nodes {old_free} (walls alone: the bounding box) → {free}; outside the building \
         {old_nodes_out} → {nodes_out}; particles outside over seeds 1–5 (1 024 each) {old_particles_out} → {particles_out}"
    );
    assert!(old_nodes_out > 1000 && old_particles_out > 1000);
    assert_eq!((nodes_out, particles_out), (0, 0));
    // Inside, the doors lost nothing: every node the box had inside is free.
    assert_eq!(old_free - old_nodes_out, free);
}
