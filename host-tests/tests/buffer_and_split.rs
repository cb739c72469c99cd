//! C-space buffers contain every point within `t_b` of their piece (checked
//! with `geo`'s distances), and convex splitting covers a simple polygon
//! exactly (areas add up; `geo` decides which sample points are inside).

use echoloc::buffer::grow;
use echoloc::geometry::{orient, split_convex, Convex, Point, MAX_PIECE_VERTICES};
use echoloc_host_tests::{convex_piece, coord, geo_line, geo_polygon, star_polygon};
use geo::{Contains, Distance, Euclidean, Intersects};
use proptest::prelude::*;

fn cases(n: u32) -> ProptestConfig {
    ProptestConfig { cases: n, ..ProptestConfig::default() }
}

proptest! {
    #![proptest_config(cases(1500))]

    #[test]
    fn buffer_contains_every_point_within_tb(
        piece in convex_piece(1500, 24),
        tb in 0u32..800,
        samples in prop::collection::vec((-2500i32..2500, -2500i32..2500), 60),
    ) {
        let c = Convex::new(&piece).unwrap();
        let g = grow(c, tb).unwrap();
        let gc = Convex::new(&g).expect("a buffered piece is a valid convex piece");
        let poly = geo_polygon(&piece);
        let centre = piece[0];
        for (x, y) in samples {
            let p = Point::new(centre.x + x, centre.y + y);
            let d = Euclidean.distance(&geo::Point::from(coord(p)), &poly);
            if d <= tb as f64 {
                prop_assert!(gc.tvector(p).is_inside(), "{:?} at {} mm of the piece, outside its {} mm buffer", p, d, tb);
            }
            // Conservative, not wasteful: nothing beyond the octagon's corner
            // distance (t_b / cos 22.5°) plus a millimetre of rounding.
            if d > tb as f64 * 1.0824 + 1.5 {
                prop_assert!(!gc.tvector(p).is_inside(), "{:?} at {} mm is inside the {} mm buffer", p, d, tb);
            }
        }
        // The tight spots: points at distance just under t_b from a vertex,
        // all round (the octagon's diagonal edges are closest there).
        for (k, &v) in piece.iter().enumerate() {
            for j in 0..48 {
                let a = (j as f64 + k as f64 / 7.0) / 48.0 * std::f64::consts::TAU;
                let p = Point::new(v.x + (tb as f64 * a.cos()) as i32, v.y + (tb as f64 * a.sin()) as i32);
                let d = Euclidean.distance(&geo::Point::from(coord(p)), &poly);
                if d <= tb as f64 {
                    prop_assert!(gc.tvector(p).is_inside(), "{:?} at {} mm of the piece, outside its {} mm buffer", p, d, tb);
                }
            }
        }
        // Every vertex of the piece is inside its buffer.
        prop_assert!(piece.iter().all(|&v| gc.tvector(v).is_inside()));
    }

    #[test]
    fn wall_buffer_contains_points_within_tb(
        (ax, ay, bx, by) in (-1000i32..1000, -1000i32..1000, -1000i32..1000, -1000i32..1000),
        tb in 1u32..500,
        samples in prop::collection::vec((-1600i32..1600, -1600i32..1600), 60),
    ) {
        let (a, b) = (Point::new(ax, ay), Point::new(bx, by));
        prop_assume!(a != b);
        let w = [a, b];
        let g = grow(Convex::new(&w).unwrap(), tb).unwrap();
        let gc = Convex::new(&g).unwrap();
        let line = geo_line(a, b);
        for (x, y) in samples {
            let p = Point::new(x, y);
            let d = Euclidean.distance(&geo::Point::from(coord(p)), &line);
            if d <= tb as f64 {
                prop_assert!(gc.tvector(p).is_inside(), "{:?} at {} mm of the wall", p, d);
            }
        }
    }
}

/// Splits `poly`, checking each piece, and returns the pieces.
fn split(poly: &[Point]) -> Vec<Vec<Point>> {
    let mut pieces = Vec::new();
    split_convex::<256, ()>(poly, MAX_PIECE_VERTICES, |p| {
        pieces.push(p.to_vec());
        Ok(())
    })
    .expect("a simple polygon splits");
    pieces
}

fn area2(p: &[Point]) -> i128 {
    (1..p.len() - 1).map(|i| orient(p[0], p[i], p[i + 1]) as i128).sum()
}

proptest! {
    #![proptest_config(cases(800))]

    #[test]
    fn split_covers_exactly(poly in star_polygon(3000), samples in prop::collection::vec((-3100i32..3100, -3100i32..3100), 80)) {
        let pieces = split(&poly);
        for p in &pieces {
            prop_assert!(Convex::new(p).is_ok(), "piece {:?} is not strictly convex", p);
            prop_assert!(p.len() <= MAX_PIECE_VERTICES);
            prop_assert!(p.len() >= 3);
        }
        // Areas add up exactly...
        let total: i128 = pieces.iter().map(|p| area2(p)).sum();
        prop_assert_eq!(total, area2(&poly).abs());
        // ...and at sample points the pieces agree with the polygon: inside
        // the polygon ⇒ in some piece; inside a piece ⇒ in the polygon; and
        // no point is strictly inside two pieces.
        let whole = geo_polygon(&poly);
        let geo_pieces: Vec<_> = pieces.iter().map(|p| geo_polygon(p)).collect();
        for (x, y) in samples {
            let q = geo::Point::new(x as f64, y as f64);
            let in_poly = whole.contains(&q);
            let covering = geo_pieces.iter().filter(|g| g.intersects(&q)).count();
            let strictly = geo_pieces.iter().filter(|g| g.contains(&q)).count();
            if in_poly {
                prop_assert!(covering >= 1, "({}, {}) inside the polygon but in no piece", x, y);
            }
            if strictly > 0 {
                prop_assert!(whole.intersects(&q), "({}, {}) in a piece but outside the polygon", x, y);
            }
            prop_assert!(strictly <= 1, "({}, {}) strictly inside {} pieces", x, y, strictly);
        }
        // Every piece's vertices are the polygon's own vertices.
        for p in &pieces {
            prop_assert!(p.iter().all(|v| poly.contains(v)));
        }
    }
}

#[test]
fn split_handles_a_rectilinear_room_outline() {
    // A U-shaped room outline on a 50 mm lattice, as an occupancy-grid
    // contour would give: many collinear vertices and reflex corners.
    let mut ring = Vec::new();
    for x in (0..=4000).step_by(50) {
        ring.push(Point::new(x, 0));
    }
    for y in (50..=3000).step_by(50) {
        ring.push(Point::new(4000, y));
    }
    ring.extend([Point::new(3000, 3000), Point::new(3000, 1000), Point::new(1000, 1000), Point::new(1000, 3000)]);
    ring.push(Point::new(0, 3000));
    let pieces = split(&ring);
    assert_eq!(pieces.iter().map(|p| area2(p)).sum::<i128>(), area2(&ring));
    assert!(pieces.len() <= 4, "{} pieces for a U: expected a handful", pieces.len());
}
