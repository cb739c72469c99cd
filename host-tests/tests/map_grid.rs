//! Queries through the grid index find exactly what a scan of every piece
//! finds (and, on the true layer, what `geo` says), on random maps.

use std::collections::BTreeSet;

use echoloc::geometry::{Point, Rect, Segment};
use echoloc::map::{Layer, Map, ObstacleKind};
use echoloc_host_tests::{convex_piece, geo_line, geo_polygon};
use geo::Intersects;
use proptest::prelude::*;

type M = Map<256, 8192, 1024, 8192>;

/// Solids, walls, t_b and cell size.
type RandomMap = (Vec<Vec<Point>>, Vec<(Point, Point)>, u32, u32);

fn random_map() -> impl Strategy<Value = RandomMap> {
    (
        prop::collection::vec(
            convex_piece(300, 12).prop_map(|p| p.into_iter().map(|v| Point::new(v.x * 10, v.y * 10)).collect()),
            1..30,
        ),
        prop::collection::vec((-5000i32..5000, -5000i32..5000, -5000i32..5000, -5000i32..5000), 0..10),
        0u32..400,
        100u32..3000,
    )
        .prop_map(|(solids, walls, tb, cell)| {
            let walls = walls
                .into_iter()
                .map(|(a, b, c, d)| (Point::new(a, b), Point::new(c, d)))
                .filter(|(a, b)| a != b)
                .collect();
            (solids, walls, tb, cell)
        })
}

fn build(solids: &[Vec<Point>], walls: &[(Point, Point)], tb: u32, cell: u32) -> Box<M> {
    let mut m: Box<M> = Box::default();
    for s in solids {
        m.add_obstacle(ObstacleKind::Solid, &[s]).unwrap();
    }
    for (a, b) in walls {
        m.add_obstacle(ObstacleKind::Wall, &[&[*a, *b]]).unwrap();
    }
    // A fine grid may not fit: coarsen as the importer does.
    let mut cell = cell;
    while m.finish(tb, cell).is_err() {
        cell *= 2;
    }
    m
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn grid_queries_equal_a_full_scan(
        (solids, walls, tb, cell) in random_map(),
        segs in prop::collection::vec((-6000i32..6000, -6000i32..6000, -6000i32..6000, -6000i32..6000), 20),
    ) {
        let m = build(&solids, &walls, tb, cell);
        for (ax, ay, bx, by) in segs {
            let seg = Segment::new(Point::new(ax, ay), Point::new(bx, by));
            for layer in [Layer::True, Layer::Buffered] {
                let mut via_grid = BTreeSet::new();
                m.for_each_hit(seg, layer, |p| { via_grid.insert(p.id); }).unwrap();
                let scan: BTreeSet<u16> = m.pieces().filter(|p| {
                    let s = if layer == Layer::True { p.shape } else { p.buffered };
                    s.hits_segment(seg.a, seg.b)
                }).map(|p| p.id).collect();
                prop_assert_eq!(&via_grid, &scan, "layer {:?}", layer);
                if layer == Layer::True {
                    // And geo agrees on the true outlines.
                    let line = geo_line(seg.a, seg.b);
                    let by_geo: BTreeSet<u16> = m.pieces().filter(|p| {
                        let v = p.shape.vertices();
                        if v.len() == 2 { geo_line(v[0], v[1]).intersects(&line) } else { geo_polygon(v).intersects(&line) }
                    }).map(|p| p.id).collect();
                    prop_assert_eq!(&via_grid, &by_geo);
                }
            }
            // The first hit is the nearest entry over all pieces.
            let first = m.first_hit(seg).unwrap();
            let best = m.pieces().filter_map(|p| p.shape.entry(seg).map(|e| (e, p.id)))
                .min_by(|x, y| x.0.cmp_exact(&y.0).then(x.1.cmp(&y.1)));
            prop_assert_eq!(first.map(|h| h.piece), best.map(|b| b.1));
        }
        // Box queries report each overlapping piece exactly once.
        let area = Rect { min: Point::new(-1500, -800), max: Point::new(2500, 1900) };
        let mut seen = Vec::new();
        m.for_each_candidate(area, |p| seen.push(p.id)).unwrap();
        let mut sorted = seen.clone();
        sorted.sort();
        sorted.dedup();
        prop_assert_eq!(sorted.len(), seen.len(), "a piece reported twice");
        let scan: Vec<u16> = m.pieces().filter(|p| p.bbox.overlaps(&area)).map(|p| p.id).collect();
        prop_assert_eq!(sorted, scan);
    }
}

#[test]
fn queries_before_finish_are_refused_and_rebuilds_work() {
    let mut m: Box<M> = Box::default();
    let sq = [Point::new(0, 0), Point::new(100, 0), Point::new(100, 100), Point::new(0, 100)];
    m.add_obstacle(ObstacleKind::Solid, &[&sq]).unwrap();
    let seg = Segment::new(Point::new(-50, 50), Point::new(50, 50));
    assert_eq!(m.first_hit(seg), Err(echoloc::map::MapError::NotFinished));
    m.finish(10, 50).unwrap();
    assert!(m.first_hit(seg).unwrap().is_some());
    // Adding returns the map to building; finishing again rebuilds.
    m.add_obstacle(ObstacleKind::Wall, &[&[Point::new(-20, 0), Point::new(-20, 100)]]).unwrap();
    assert!(!m.is_finished());
    m.finish(10, 50).unwrap();
    assert_eq!(m.first_hit(seg).unwrap().unwrap().obstacle, 1);
    assert_eq!(m.vertex_count(), 4 + 2 + m.pieces().map(|p| p.buffered.len()).sum::<usize>());
}

#[test]
fn a_failed_add_changes_nothing() {
    let mut m: Map<2, 16, 16, 16> = Map::new();
    let sq = [Point::new(0, 0), Point::new(100, 0), Point::new(100, 100), Point::new(0, 100)];
    let bad = [Point::new(0, 0), Point::new(100, 100), Point::new(100, 0), Point::new(0, 100)];
    m.add_obstacle(ObstacleKind::Solid, &[&sq]).unwrap();
    assert!(m.add_obstacle(ObstacleKind::Solid, &[&sq, &bad]).is_err());
    assert!(m.add_obstacle(ObstacleKind::Solid, &[&sq, &sq]).is_err(), "capacity: 2 pieces");
    assert_eq!((m.obstacles().len(), m.piece_count(), m.vertex_count()), (1, 1, 4));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// `Piece::front_edges` against `geo`: from a point outside a piece, the
    /// edges with the point on their outer side (geo's orientation kernel),
    /// lowest index first, but never a seam between two pieces of one
    /// obstacle; from a point inside or on the piece, none.
    #[test]
    fn front_edges_face_the_point_and_skip_seams(
        (w1, w2, h) in (1i32..400, 1i32..400, 1i32..400),
        (x, y) in (-600i32..1000, -600i32..1000),
    ) {
        use geo::kernels::{Kernel, Orientation};
        use geo::Intersects;
        // Two rectangles side by side: the shared edge x = w1 is a seam of each.
        let left = [Point::new(0, 0), Point::new(w1, 0), Point::new(w1, h), Point::new(0, h)];
        let right = [Point::new(w1, 0), Point::new(w1 + w2, 0), Point::new(w1 + w2, h), Point::new(w1, h)];
        let mut m: Box<M> = Box::default();
        m.add_obstacle(ObstacleKind::Solid, &[&left, &right]).unwrap();
        m.finish(0, 500).unwrap();
        let o = Point::new(x, y);
        let mut pieces = 0;
        for piece in m.pieces() {
            pieces += 1;
            let ours: Vec<(u8, Point, Point)> = piece.front_edges(o).collect();
            let outline: Vec<Point> = piece.shape.vertices().to_vec();
            let inside = geo_polygon(&outline).intersects(&echoloc_host_tests::coord(o));
            let mut theirs = Vec::new();
            if !inside {
                for i in 0..piece.shape.edge_count() {
                    let (u, v) = piece.shape.edge(i);
                    let seam = u.x == w1 && v.x == w1;
                    let side = <f64 as geo::GeoNum>::Ker::orient2d(
                        echoloc_host_tests::coord(u),
                        echoloc_host_tests::coord(v),
                        echoloc_host_tests::coord(o),
                    );
                    if side == Orientation::Clockwise && !seam {
                        theirs.push((i as u8, u, v));
                    }
                }
            }
            prop_assert_eq!(&ours, &theirs, "piece {:?} from {:?}", outline, o);
        }
        prop_assert_eq!(pieces, 2);
    }
}
