//! A fixed workload for profilers: Pioneer rings with the quantised net on
//! the compiled depot map, read in place, at the firmware's free poses.
//!
//! `cargo build --release -p echoloc-host-tests --example ring_profile &&
//! valgrind --tool=callgrind target/release/examples/ring_profile [RINGS]
//! [exact|pseudo]` (the beacon strategy; exact by default).
use echoloc::credence::net::CredenceNet;
use echoloc::geometry::{Point, Rect, Segment};
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::{predict_ring, Pose, PredictParams, PredictStats, PIONEER16};
use echoloc::window::{Strategy, WindowParams};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../boards/qemu-mps2-an386/depot.map"));

fn main() {
    let map = MapView::new(&DEPOT.0).expect("depot validates");
    let b = map.bounds().expect("pieces");
    let net = CredenceNet::shipped();
    let strategy = match std::env::args().nth(2).as_deref() {
        Some("pseudo") => Strategy::PseudoPaths,
        _ => Strategy::Exact,
    };
    let params = PredictParams {
        strategy,
        ..PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE })
    };
    let mut s = 0x2545_F491u32;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s
    };
    let rings: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(200);
    let (mut done, mut total) = (0, PredictStats::default());
    let mut echoes = 0;
    while done < rings {
        let x = b.min.x + (next() % (b.max.x - b.min.x) as u32) as i32;
        let y = b.min.y + (next() % (b.max.y - b.min.y) as u32) as i32;
        let heading = (next() % 6283) as f32 / 1000.0 - std::f32::consts::PI;
        let p = Point::new(x, y);
        let mut free = true;
        map.for_each_candidate(Rect::around(p), |piece| free &= !piece.shape.tvector(p).is_inside()).unwrap();
        for seg in [
            Segment::new(Point::new(x - 300, y), Point::new(x + 300, y)),
            Segment::new(Point::new(x, y - 300), Point::new(x, y + 300)),
        ] {
            free &= map.first_hit(seg).unwrap().is_none();
        }
        if !free {
            continue;
        }
        let mut out = [None; 16];
        let pose = Pose { x_mm: x as f32, y_mm: y as f32, heading_rad: heading };
        total += predict_ring(&map, &pose, &PIONEER16, &params, &net, &mut out).unwrap();
        echoes += out.iter().flatten().count();
        done += 1;
    }
    println!("{rings} rings, {echoes} echoes; {total:?}");
}
