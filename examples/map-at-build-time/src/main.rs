//! The map `build.rs` compiled, linked into the program as a firmware links
//! it (`static MAP: &Aligned<[u8]> = &Aligned(*include_bytes!(…))`), read in
//! place by `MapView` (validated once, no copy), and a Pioneer ring
//! predicted in it. Exits non-zero if the map is refused or the prediction
//! disagrees with the room's known geometry.

use echoloc::credence::net::CredenceNet;
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::{predict_ring, Pose, PredictParams, PIONEER16};
use echoloc::window::WindowParams;

static MAP: &Aligned<[u8]> = &Aligned(*include_bytes!(concat!(env!("OUT_DIR"), "/room.map")));

fn main() -> std::process::ExitCode {
    let map = match MapView::new(&MAP.0) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("the compiled map was refused: {e:?}");
            return std::process::ExitCode::FAILURE;
        }
    };
    println!("room.map: {} bytes, {} obstacles, {} pieces", MAP.0.len(), map.obstacle_count(), map.piece_count());
    // In the middle of the room's free floor, facing +x (the east wall at x = 6 m).
    let pose = Pose { x_mm: 2500.0, y_mm: 2000.0, heading_rad: 0.0 };
    let params = PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE });
    let mut out = [None; 16];
    if let Err(e) = predict_ring(&map, &pose, &PIONEER16, &params, &CredenceNet::shipped(), &mut out) {
        eprintln!("prediction failed: {e}");
        return std::process::ExitCode::FAILURE;
    }
    for (i, p) in out.iter().enumerate() {
        match p {
            Some(p) => println!("transducer {i:2}: {:5} mm, κ {:.2}", p.range_mm, p.kappa.to_num::<f32>()),
            None => println!("transducer {i:2}: nothing predicted"),
        }
    }
    // By hand, from the room's drawing (walls 10 cm thick inside a 6 m × 4 m
    // box): transducer 0 sits at (2.575, 2.130) m looking +y at the north
    // wall's face, y = 3.9 m: 1 770 mm. Transducer 4 at (2.670, 1.975) m
    // looks 10° right of +x at the east face, x = 5.9 m: 3 230 mm
    // perpendicular, within its cone. Transducer 12 at (2.250, 2.025) m looks
    // 170° at the west face, x = 0.1 m: 2 150 mm. The importer traces the
    // grid's cell edges and simplifies within 50 mm: allow 60 mm.
    for (i, want) in [(0usize, 1_770u32), (4, 3_230), (12, 2_150)] {
        let got = out[i].map(|p| p.range_mm);
        if got.is_none_or(|r| r.abs_diff(want) > 60) {
            eprintln!("transducer {i}: predicted {got:?} mm, the room says {want} mm");
            return std::process::ExitCode::FAILURE;
        }
    }
    println!("transducers 0, 4 and 12 within 60 mm of the room's hand-derived ranges");
    std::process::ExitCode::SUCCESS
}
