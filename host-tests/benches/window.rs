//! The core paths of `echoloc-lab bench` under criterion: one window on the
//! real depot map (compiled, read in place), the exact nearest obstacle
//! (`predict --geometric`), the pseudo-path collection and the full
//! prediction, at the bench's half-angles. The peers and the side-by-side
//! ratios are `echoloc-lab bench` (docs/benchmarks.md).

use criterion::{criterion_group, criterion_main, Criterion};
use echoloc::credence::net::CredenceNet;
use echoloc::geometry::{Point, Rect};
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{nearest_in_window, predict, PredictParams};
use echoloc::window::{collect_beacons, Strategy, Window, WindowParams};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../boards/qemu-mps2-an386/depot.map");
    let bytes = std::fs::read(path).unwrap();
    let mut words = vec![0u64; bytes.len().div_ceil(8)];
    bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..bytes.len()].copy_from_slice(&bytes);
    let map = MapView::new(&bytemuck::cast_slice::<u64, u8>(&words)[..bytes.len()]).unwrap();
    let b = map.bounds().unwrap();
    // Free poses on a lattice, headings spread.
    let mut apexes = Vec::new();
    for i in 1..20 {
        for j in 1..10 {
            let p = Point::new(b.min.x + (b.max.x - b.min.x) * i / 20, b.min.y + (b.max.y - b.min.y) * j / 10);
            let mut free = true;
            let _ = map.for_each_candidate(Rect::around(p), |q| free &= !q.buffered.tvector(p).is_inside());
            if free {
                apexes.push((p, (i * 7 + j) as f32 * 0.37));
            }
        }
    }
    let net = CredenceNet::shipped();
    for half in [15.0f32, 30.0] {
        let wp = WindowParams { r_min_mm: 0, half_angle_deg: half, tb_mm: map.buffer_mm(), ..WindowParams::MARGE };
        let params = PredictParams::new(WindowParams { r_min_mm: WindowParams::MARGE.r_min_mm, ..wp });
        let geo: Vec<Window> = apexes.iter().map(|&(p, h)| Window::place(&wp, p, h).unwrap()).collect();
        let paths: Vec<Window> =
            apexes.iter().map(|&(p, h)| Window::place_for(&wp, p, h, Strategy::PseudoPaths).unwrap()).collect();
        let full: Vec<Window> = apexes.iter().map(|&(p, h)| Window::place(&params.window, p, h).unwrap()).collect();
        let mut g = c.benchmark_group(format!("depot_window_{half}deg"));
        g.bench_function("exact_nearest", |bn| {
            bn.iter(|| {
                geo.iter()
                    .map(|w| nearest_in_window(&map, black_box(w)).unwrap().map_or(0.0, |n| n.range_mm))
                    .sum::<f64>()
            })
        });
        g.bench_function("pseudo_path_collection", |bn| {
            let mut ids: heapless::Vec<u16, 512> = heapless::Vec::new();
            bn.iter(|| {
                paths
                    .iter()
                    .map(|w| collect_beacons(&map, black_box(w), Strategy::PseudoPaths, &mut ids).unwrap().candidates)
                    .sum::<u32>()
            })
        });
        g.bench_function("full_prediction", |bn| {
            bn.iter(|| full.iter().filter(|w| predict(&map, black_box(*w), &params, &net).unwrap().0.is_some()).count())
        });
        g.finish();
        println!("({} windows per iteration)", apexes.len());
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
