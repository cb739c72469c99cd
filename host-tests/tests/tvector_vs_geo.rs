//! The t-vector collision test against `geo`'s `Intersects`, on random convex
//! pieces and segments with many touching and collinear cases.

use echoloc::geometry::{Convex, Point, Segment};
use echoloc_host_tests::{convex_piece, geo_line, geo_polygon, segment_near};
use geo::Intersects;
use proptest::prelude::*;

fn cases() -> ProptestConfig {
    ProptestConfig { cases: 4000, ..ProptestConfig::default() }
}

proptest! {
    #![proptest_config(cases())]

    #[test]
    fn solid_piece_agrees_with_geo((piece, a, b) in convex_piece(2000, 24).prop_flat_map(|p| segment_near(p, 3000))) {
        let c = Convex::new(&piece).unwrap();
        let ours = c.hits_segment(a, b);
        let poly = geo_polygon(&piece);
        let theirs = if a == b { poly.intersects(&echoloc_host_tests::coord(a)) } else { poly.intersects(&geo_line(a, b)) };
        prop_assert_eq!(ours, theirs, "piece {:?} segment {:?}→{:?}", piece, a, b);
        // The exact entry parameter exists exactly when the segment hits.
        let entry = c.entry(Segment::new(a, b));
        prop_assert_eq!(entry.is_some(), ours);
        if let Some(e) = entry {
            prop_assert!(e.den > 0 && 0 <= e.num && e.num <= e.den);
            // The rounded entry point lies within a millimetre of the piece.
            let q = e.point_on(Segment::new(a, b));
            let d = geo::Euclidean.distance_helper(&poly, q);
            prop_assert!(d <= 1.0, "entry point {:?} is {} mm from the piece", q, d);
        }
    }

    #[test]
    fn wall_agrees_with_geo(
        (ax, ay, bx, by) in (-50i32..50, -50i32..50, -50i32..50, -50i32..50),
        (p, q, r, s) in (-60i32..60, -60i32..60, -60i32..60, -60i32..60),
        k in 0..3u8,
    ) {
        let (a, b) = (Point::new(ax, ay), Point::new(bx, by));
        prop_assume!(a != b);
        // k = 1 forces the segment onto the wall's line (collinear cases).
        let (c, d) = match k {
            1 => (Point::new(ax + (bx - ax) * (p % 4), ay + (by - ay) * (p % 4)),
                  Point::new(ax + (bx - ax) * (q % 4), ay + (by - ay) * (q % 4))),
            _ => (Point::new(p, q), Point::new(r, s)),
        };
        let w = [a, b];
        let wall = Convex::new(&w).unwrap();
        let ours = wall.hits_segment(c, d);
        let theirs = if c == d { geo_line(a, b).intersects(&echoloc_host_tests::coord(c)) } else { geo_line(a, b).intersects(&geo_line(c, d)) };
        prop_assert_eq!(ours, theirs, "wall {:?} segment {:?}→{:?}", w, c, d);
        prop_assert_eq!(wall.entry(Segment::new(c, d)).is_some(), ours);
    }

    #[test]
    fn front_surfaces_face_the_point(piece in convex_piece(2000, 24), x in -4000i32..4000, y in -4000i32..4000) {
        // Edge i is a front surface from p exactly when p is strictly on its
        // outer side: checked here with geo's orientation kernel.
        use geo::kernels::{Kernel, Orientation};
        let c = Convex::new(&piece).unwrap();
        let p = Point::new(x, y);
        let fronts = c.front_surfaces(c.tvector(p));
        for i in 0..c.edge_count() {
            let (u, v) = c.edge(i);
            let o = <f64 as geo::GeoNum>::Ker::orient2d(echoloc_host_tests::coord(u), echoloc_host_tests::coord(v), echoloc_host_tests::coord(p));
            prop_assert_eq!(fronts >> i & 1 == 1, o == Orientation::Clockwise);
        }
    }
}

/// `geo`'s Euclidean distance from a polygon to a point, under a short name.
trait DistanceHelper {
    fn distance_helper(&self, poly: &geo::Polygon<f64>, p: Point) -> f64;
}

impl DistanceHelper for geo::Euclidean {
    fn distance_helper(&self, poly: &geo::Polygon<f64>, p: Point) -> f64 {
        use geo::Distance;
        geo::Euclidean.distance(&geo::Point::from(echoloc_host_tests::coord(p)), poly)
    }
}
