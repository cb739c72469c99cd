//! The compiled map read in place ([`MapView`]) answers exactly as the
//! host's [`Map`] rebuilt from the same true outlines (its own buffers, grid
//! and seams): every ring prediction with the quantised net by both
//! beacon-collection strategies, every geometric nearest point, every first
//! hit, bit for bit, over thousands of random poses on the three real maps;
//! and the predictor's shortcuts answer as its plain search does.

use std::path::Path;

use echoloc::credence::net::{CredenceNet, SHIPPED_WEIGHTS};
use echoloc::geometry::{Point, Segment};
use echoloc::map::{Layer, MapSource, MapView, StandardMap};
use echoloc::predict::{
    nearest_in_window, place_sensor, predict, predict_ring, predict_unpruned, Pose, PredictParams, PIONEER16,
};
use echoloc::window::{Strategy, Window, WindowParams};

use super::{build_map, read_shapes, AlignedBytes};
use crate::credence::rng::Rng;

fn compiled(source: &str) -> AlignedBytes {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let shapes = read_shapes(&root.join(source)).expect("map source reads");
    let (blob, _) = build_map(&shapes, 100, 1000).expect("map builds");
    AlignedBytes::new(&blob)
}

fn check(source: &str, poses: usize, seed: u64) {
    let bytes = compiled(source);
    let view = MapView::new(bytes.bytes()).expect("the compiled map validates");
    let mut map: Box<StandardMap> = Box::default();
    map.load(bytes.bytes()).expect("the host map loads it");
    assert_eq!(MapSource::piece_count(&*map), view.piece_count());
    let b = view.bounds().expect("a map with pieces");
    let net = CredenceNet::shipped();
    let unbounded = CredenceNet::new(&SHIPPED_WEIGHTS);
    let mut skipped = 0;
    let window = WindowParams { tb_mm: view.buffer_mm(), ..WindowParams::MARGE };
    let mut rng = Rng::new(seed);
    let mut predicted = 0;
    for i in 0..poses {
        let pose = Pose {
            x_mm: rng.uniform(b.min.x as f64, b.max.x as f64) as f32,
            y_mm: rng.uniform(b.min.y as f64, b.max.y as f64) as f32,
            heading_rad: rng.uniform(-3.2, 3.2) as f32,
        };
        // Pseudo-paths are slower: every fourth pose.
        let strategies: &[Strategy] =
            if i % 4 == 0 { &[Strategy::Exact, Strategy::PseudoPaths] } else { &[Strategy::Exact] };
        for &strategy in strategies {
            let params = PredictParams { strategy, ..PredictParams::new(window) };
            let (mut a, mut v) = ([None; 16], [None; 16]);
            let sa = predict_ring(&*map, &pose, &PIONEER16, &params, &net, &mut a);
            let sv = predict_ring(&view, &pose, &PIONEER16, &params, &net, &mut v);
            assert_eq!(sa, sv, "{source}: stats at {pose:?} ({strategy:?})");
            assert_eq!(a, v, "{source}: predictions at {pose:?} ({strategy:?})");
            // The κ bounds skip only what the net would have passed over.
            let mut u = [None; 16];
            let su = predict_ring(&view, &pose, &PIONEER16, &params, &unbounded, &mut u);
            assert_eq!(u, v, "{source}: the κ bounds changed a prediction at {pose:?} ({strategy:?})");
            let (su, sv) = (su.expect("predicts"), sv.expect("predicts"));
            assert_eq!((su.kappa_evals, su.kappa_bounded), (sv.kappa_evals + sv.kappa_bounded, 0));
            skipped += sv.kappa_bounded;
            predicted += a.iter().flatten().count();
        }
        // The predictor's shortcuts (nearest-first visit, early stop, occlusion
        // among the window's candidates) against the plain search.
        let params = PredictParams::new(window);
        for (k, mount) in PIONEER16.iter().enumerate() {
            let (apex, heading) = place_sensor(&pose, mount);
            let w = Window::place(&window, apex, heading).expect("window places");
            let fast = predict(&view, &w, &params, &net).expect("predicts").0;
            let plain = predict_unpruned(&view, &w, &params, &net).expect("predicts").0;
            assert_eq!(fast, plain, "{source}: transducer {k} at {pose:?}");
        }
        let apex = Point::new(pose.x_mm as i32, pose.y_mm as i32);
        let w = Window::place(&window, apex, pose.heading_rad).expect("window places");
        let (na, nv) = (nearest_in_window(&*map, &w).expect("query"), nearest_in_window(&view, &w).expect("query"));
        assert_eq!(na.map(|n| (n.range_mm.to_bits(), n.piece)), nv.map(|n| (n.range_mm.to_bits(), n.piece)));
        let end =
            Point::new(apex.x + rng.uniform(-8000.0, 8000.0) as i32, apex.y + rng.uniform(-8000.0, 8000.0) as i32);
        let seg = Segment::new(apex, end);
        assert_eq!(map.first_hit(seg).expect("query"), view.first_hit(seg).expect("query"), "{source}: {seg:?}");
        let (mut ha, mut hv) = (Vec::new(), Vec::new());
        map.for_each_hit(seg, Layer::Buffered, |p| ha.push(p.id)).expect("query");
        view.for_each_hit(seg, Layer::Buffered, |p| hv.push(p.id)).expect("query");
        assert_eq!(ha, hv, "{source}: buffered hits of {seg:?}");
    }
    // The comparison means something only if the poses see things.
    assert!(predicted > poses, "{source}: only {predicted} predictions over {poses} poses");
    assert!(skipped as usize > poses, "{source}: the κ bounds skipped only {skipped} evaluations");
}

#[test]
fn office_view_matches_map() {
    check("maps/office.geojson", 2000, 1);
}

#[test]
fn depot_view_matches_map() {
    check("../shared/data/maps/depot.yaml", 2000, 2);
}

#[test]
fn tb3_sandbox_view_matches_map() {
    check("../shared/data/maps/tb3_sandbox.yaml", 2000, 3);
}
