//! Convex splitting of polygons with holes, checked against `geo`: the
//! pieces' areas add up exactly to outer minus holes, sample points agree with
//! `geo`'s polygon-with-holes containment, no point is strictly inside two
//! pieces; invalid hole layouts (as `geo` judges them) are errors, never
//! panics, and valid ones always split.

use echoloc::geometry::{orient, split_convex_with_holes, Convex, HolesError, Point, MAX_PIECE_VERTICES};
use echoloc_host_tests::{coord, geo_polygon, is_simple, star_polygon};
use geo::{Contains, Intersects, LineString, Polygon};
use proptest::prelude::*;

fn cases(n: u32) -> ProptestConfig {
    ProptestConfig { cases: n, ..ProptestConfig::default() }
}

fn area2(p: &[Point]) -> i128 {
    (1..p.len() - 1).map(|i| orient(p[0], p[i], p[i + 1]) as i128).sum()
}

/// The ring as a closed line string (first point repeated at the end), so
/// that its closing edge counts in `intersects`.
fn ring_ls(r: &[Point]) -> LineString<f64> {
    let mut ls = LineString::from(r.iter().map(|&p| coord(p)).collect::<Vec<_>>());
    ls.close();
    ls
}

/// Whether `geo` calls this a valid polygon with holes in our sense: every
/// hole strictly inside the outer ring, no two rings touching, no hole
/// inside another.
fn geo_valid(outer: &[Point], holes: &[Vec<Point>]) -> bool {
    let o = geo_polygon(outer);
    let ob = ring_ls(outer);
    for (i, h) in holes.iter().enumerate() {
        let hp = geo_polygon(h);
        if !o.contains(&hp) || ring_ls(h).intersects(&ob) {
            return false;
        }
        if holes[..i].iter().any(|g| geo_polygon(g).intersects(&hp)) {
            return false;
        }
    }
    true
}

/// A star-shaped outer ring of radius up to 3000 and up to six star-shaped
/// holes, each placed on the segment from the centre (in the outer ring's
/// kernel) towards a random outer vertex and scaled to that vertex's
/// distance, so that most fit; on a coarse lattice half of the time, so that
/// equal x coordinates and collinear bridges come up.
fn layout() -> impl Strategy<Value = (Vec<Point>, Vec<Vec<Point>>)> {
    (
        star_polygon(3000),
        prop::collection::vec((star_polygon(700), any::<prop::sample::Index>(), 10i64..80, any::<bool>()), 0..7),
    )
        .prop_map(|(outer, raw)| {
            let holes = raw
                .into_iter()
                .map(|(h, k, t, coarse)| {
                    let v = outer[k.index(outer.len())];
                    let (mut cx, mut cy) = (v.x as i64 * t / 100, v.y as i64 * t / 100);
                    if coarse {
                        cx = cx / 100 * 100;
                        cy = cy / 100 * 100;
                    }
                    let r = ((v.x as f64).hypot(v.y as f64) as i64).max(100);
                    h.into_iter()
                        .map(|p| Point::new((cx + p.x as i64 * r / 3500) as i32, (cy + p.y as i64 * r / 3500) as i32))
                        .collect::<Vec<_>>()
                })
                .filter(|h| is_simple(h))
                .collect();
            (outer, holes)
        })
}

fn split(outer: &[Point], holes: &[Vec<Point>]) -> Result<Vec<Vec<Point>>, HolesError<()>> {
    let hs: Vec<&[Point]> = holes.iter().map(|h| h.as_slice()).collect();
    let mut pieces = Vec::new();
    split_convex_with_holes::<1024, ()>(outer, &hs, MAX_PIECE_VERTICES, |p| {
        pieces.push(p.to_vec());
        Ok(())
    })?;
    Ok(pieces)
}

/// Closed / strict containment in a counter-clockwise convex piece, exact.
fn in_piece(p: &[Point], q: Point, strict: bool) -> bool {
    (0..p.len()).all(|i| {
        let o = orient(p[i], p[(i + 1) % p.len()], q);
        if strict {
            o > 0
        } else {
            o >= 0
        }
    })
}

proptest! {
    #![proptest_config(cases(1500))]

    #[test]
    fn holes_split_covers_exactly_or_is_refused(
        (outer, holes) in layout(),
        samples in prop::collection::vec((-3100i32..3100, -3100i32..3100), 120),
    ) {
        // Keep only the holes that fit (so that most cases are valid)…
        let mut fitting: Vec<Vec<Point>> = Vec::new();
        for h in &holes {
            let mut with = fitting.clone();
            with.push(h.clone());
            if geo_valid(&outer, &with) {
                fitting = with;
            }
        }
        // …but first: the raw layout is an error exactly when geo says invalid.
        let raw = split(&outer, &holes);
        prop_assert_eq!(raw.is_ok(), geo_valid(&outer, &holes), "raw layout: {:?}", raw.as_ref().err());

        let pieces = split(&outer, &fitting).map_err(|e| TestCaseError::fail(format!("{e:?}")))?;
        for p in &pieces {
            prop_assert!(Convex::new(p).is_ok(), "piece {:?} is not strictly convex", p);
            prop_assert!(p.len() >= 3 && p.len() <= MAX_PIECE_VERTICES);
        }
        let total: i128 = pieces.iter().map(|p| area2(p)).sum();
        let expect = area2(&outer).abs() - fitting.iter().map(|h| area2(h).abs()).sum::<i128>();
        prop_assert_eq!(total, expect);

        let whole = Polygon::new(ring_ls(&outer), fitting.iter().map(|h| ring_ls(h)).collect());
        // Random points, and the tricky ones: every vertex and edge midpoint.
        let mut pts: Vec<Point> = samples.into_iter().map(|(x, y)| Point::new(x, y)).collect();
        for r in std::iter::once(&outer).chain(fitting.iter()).chain(pieces.iter()) {
            for i in 0..r.len() {
                let (a, b) = (r[i], r[(i + 1) % r.len()]);
                pts.push(a);
                pts.push(Point::new(a.x / 2 + b.x / 2, a.y / 2 + b.y / 2));
            }
        }
        for q in pts {
            let g = geo::Point::from(coord(q));
            let covering = pieces.iter().filter(|p| in_piece(p, q, false)).count();
            let strictly = pieces.iter().filter(|p| in_piece(p, q, true)).count();
            if whole.contains(&g) {
                prop_assert!(covering >= 1, "{:?} inside the polygon but in no piece", q);
            }
            if strictly > 0 {
                prop_assert!(whole.intersects(&g), "{:?} in a piece but outside the polygon (or in a hole)", q);
            }
            prop_assert!(strictly <= 1, "{:?} strictly inside {} pieces", q, strictly);
        }
    }
}

/// A rectilinear ring with many holes on a 50 mm lattice, as a depot's wall
/// contour gives: bridges share x coordinates and run along grid lines.
#[test]
fn many_lattice_holes() {
    let outer: Vec<Point> =
        [(0, 0), (5000, 0), (5000, 3000), (0, 3000)].iter().map(|&(x, y)| Point::new(x, y)).collect();
    let mut holes = Vec::new();
    for i in 0..8 {
        for j in 0..4 {
            let (x, y) = (200 + i * 600, 200 + j * 700);
            holes.push(vec![
                Point::new(x, y),
                Point::new(x + 400, y),
                Point::new(x + 400, y + 250),
                Point::new(x + 200, y + 250),
                Point::new(x + 200, y + 500),
                Point::new(x, y + 500),
            ]);
        }
    }
    let pieces = split(&outer, &holes).unwrap();
    let total: i128 = pieces.iter().map(|p| area2(p)).sum();
    let expect = area2(&outer) - holes.iter().map(|h| area2(h)).sum::<i128>();
    assert_eq!(total, expect);
    for p in &pieces {
        assert!(Convex::new(p).is_ok());
    }
}
