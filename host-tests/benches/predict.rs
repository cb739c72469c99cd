//! One ring prediction (16 Pioneer transducers, the quantised credence net)
//! on the office map, with each beacon-collection strategy, measured in one
//! run; the work counts per window are printed first. Maps that exist in
//! the tree (`boards/qemu-mps2-an386/*.map`) are all benchmarked.

use criterion::{criterion_group, criterion_main, Criterion};
use echoloc::credence::net::CredenceNet;
use echoloc::map::StandardMap;
use echoloc::predict::{predict_ring, Pose, PredictParams, PIONEER16};
use echoloc::window::{Strategy, WindowParams};
use std::hint::black_box;
use std::path::Path;

/// Poses on a lattice over the map's free-ish interior.
fn poses(m: &StandardMap) -> Vec<Pose> {
    let b = m.bounds().expect("a non-empty map");
    let mut out = Vec::new();
    for i in 1..8 {
        for j in 1..6 {
            let x = b.min.x as f32 + (b.max.x - b.min.x) as f32 * i as f32 / 8.0;
            let y = b.min.y as f32 + (b.max.y - b.min.y) as f32 * j as f32 / 6.0;
            out.push(Pose { x_mm: x, y_mm: y, heading_rad: (i * 7 + j) as f32 * 0.37 });
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../boards/qemu-mps2-an386");
    let mut maps: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "map"))
        .collect();
    maps.sort();
    let net = CredenceNet::shipped();
    for path in maps {
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let mut m: Box<StandardMap> = Box::default();
        m.load(&std::fs::read(&path).unwrap()).unwrap();
        let ps = poses(&m);
        let window = WindowParams { tb_mm: m.buffer_mm(), ..WindowParams::MARGE };
        let mut g = c.benchmark_group(format!("ring16_{name}"));
        for (label, strategy) in [("exact", Strategy::Exact), ("pseudo_paths", Strategy::PseudoPaths)] {
            let params = PredictParams { strategy, ..PredictParams::new(window) };
            let mut out = [None; 16];
            let mut tot = echoloc::predict::PredictStats::default();
            let mut predicted = 0;
            for p in &ps {
                let s = predict_ring(&*m, p, &PIONEER16, &params, &net, &mut out).unwrap();
                predicted += out.iter().filter(|o| o.is_some()).count();
                tot += s;
            }
            let n = (ps.len() * 16) as f64;
            println!(
                "{name} {label}: per window {:.1} candidates, {:.1} pseudo-path tests, {:.1} sector tests, {:.1} beacons, {:.1} edges, {:.1} κ, {:.1} occlusion tests; {:.0}% of transducers predicted (t_b {} mm, N_pp {})",
                tot.collect.candidates as f64 / n,
                tot.collect.path_tests as f64 / n,
                tot.collect.sector_tests as f64 / n,
                tot.beacons as f64 / n,
                tot.edges as f64 / n,
                tot.kappa_evals as f64 / n,
                tot.occlusion_tests as f64 / n,
                100.0 * predicted as f64 / n,
                m.buffer_mm(),
                window.n_pp().unwrap(),
            );
            g.bench_function(label, |b| {
                let mut k = 0;
                b.iter(|| {
                    k = (k + 1) % ps.len();
                    predict_ring(&*m, black_box(&ps[k]), &PIONEER16, &params, &net, &mut out).unwrap()
                })
            });
        }
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
