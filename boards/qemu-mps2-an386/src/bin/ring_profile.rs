//! A short fixed workload for an instruction profile under QEMU: the depot
//! map validated in place, then Pioneer rings at a few free poses. Run it
//! with QEMU's execution log and attribute the blocks to symbols with
//! `scripts/m4-profile.sh` (which does all of it).
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::{predict_ring, Pose, PredictParams, PIONEER16};
use echoloc::window::WindowParams;
use qemu_mps2_an386::exit;

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

/// Free poses of the depot (mm, rad), from the main firmware's generator.
const POSES: [(f32, f32, f32); 4] =
    [(5000.0, 10000.0, 0.3), (12000.0, 4000.0, 2.0), (20000.0, 8000.0, -1.0), (26000.0, 12000.0, -2.5)];

#[entry]
fn main() -> ! {
    let Ok(map) = MapView::new(black_box(&DEPOT.0)) else { exit(false) };
    let net = CredenceNet::shipped();
    let params = PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE });
    let mut echoes = 0;
    for &(x_mm, y_mm, heading_rad) in POSES.iter() {
        let mut out = [None; 16];
        let pose = Pose { x_mm, y_mm, heading_rad };
        if predict_ring(&map, black_box(&pose), &PIONEER16, &params, &net, &mut out).is_err() {
            exit(false);
        }
        echoes += out.iter().flatten().count();
    }
    hprintln!("{} rings, {} echoes", POSES.len(), echoes);
    exit(true);
}
