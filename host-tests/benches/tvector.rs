//! Segment–piece collision: echoloc's t-vector test against `geo`'s
//! `Intersects` (f64, robust predicates) on the same random cases, measured
//! in one run so the ratio is what counts. Also the transducer-shared form
//! (the start point's t-vector computed once, as for pseudo-paths).

use criterion::{criterion_group, criterion_main, Criterion};
use echoloc::geometry::{Convex, Point};
use echoloc_host_tests::{geo_line, geo_polygon, hull};
use geo::Intersects;
use std::hint::black_box;

/// A deterministic stream of small random numbers (xorshift).
fn rng(seed: &mut u64) -> i32 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed % 4001) as i32 - 2000
}

fn cases() -> Vec<(Vec<Point>, Point, Point)> {
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let mut out = Vec::new();
    while out.len() < 1000 {
        let pts: Vec<Point> = (0..8).map(|_| Point::new(rng(&mut s) / 2, rng(&mut s) / 2)).collect();
        let h = hull(pts);
        if h.len() < 3 {
            continue;
        }
        out.push((h, Point::new(rng(&mut s) * 2, rng(&mut s) * 2), Point::new(rng(&mut s) * 2, rng(&mut s) * 2)));
    }
    out
}

fn bench(c: &mut Criterion) {
    let cases = cases();
    let geo_cases: Vec<_> = cases.iter().map(|(p, a, b)| (geo_polygon(p), geo_line(*a, *b))).collect();
    let hits = cases.iter().filter(|(p, a, b)| Convex::new(p).unwrap().hits_segment(*a, *b)).count();
    println!("{hits} of {} segments hit their piece", cases.len());
    // Pieces validated once, as a loaded map holds them.
    let pieces: Vec<_> = cases.iter().map(|(p, a, b)| (Convex::new(p).unwrap(), *a, *b)).collect();
    let mut g = c.benchmark_group("segment_vs_convex_piece_x1000");
    g.bench_function("echoloc_tvector", |bch| {
        bch.iter(|| {
            let mut n = 0;
            for (piece, a, b) in &pieces {
                n += piece.hits_segment(black_box(*a), black_box(*b)) as u32;
            }
            n
        })
    });
    g.bench_function("echoloc_tvector_shared_start", |bch| {
        // Pseudo-path form: t(transducer) once per piece, then 8 paths.
        bch.iter(|| {
            let mut n = 0;
            for (piece, a, b) in pieces.iter().take(125) {
                let ta = piece.tvector(*a);
                for k in 0..8 {
                    let end = Point::new(b.x + k * 50, b.y - k * 50);
                    n += piece.hits_segment_with(*a, ta, end, piece.tvector(end)) as u32;
                }
            }
            n
        })
    });
    g.bench_function("geo_intersects", |bch| {
        bch.iter(|| {
            let mut n = 0;
            for (poly, line) in &geo_cases {
                n += black_box(poly).intersects(black_box(line)) as u32;
            }
            n
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
