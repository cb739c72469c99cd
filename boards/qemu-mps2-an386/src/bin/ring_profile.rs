//! A fixed workload for an instruction profile under QEMU: the depot map
//! validated in place, then Pioneer rings at the first 16 of the main
//! firmware's 32 metric poses (its generator), four times over, so that
//! prediction dominates (the map with its localization field takes some
//! 7 M instructions to validate, 16 rings 5.5 M). Run it
//! with QEMU's execution log and attribute the blocks to symbols with
//! `scripts/m4-profile.sh` (which does all of it).
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::{predict_ring, PredictParams, PIONEER16};
use echoloc::window::WindowParams;
use qemu_mps2_an386::{exit, free_poses};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));

#[entry]
fn main() -> ! {
    let Ok(map) = MapView::new(black_box(&DEPOT.0)) else { exit(false) };
    let net = CredenceNet::shipped();
    let params = PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE });
    let mut echoes = 0;
    let poses = free_poses::<16>(&map, u32::MAX);
    for pose in poses.iter().cycle().take(4 * poses.len()) {
        let mut out = [None; 16];
        if predict_ring(&map, black_box(pose), &PIONEER16, &params, &net, &mut out).is_err() {
            exit(false);
        }
        echoes += out.iter().flatten().count();
    }
    hprintln!("{} rings, {} echoes", 4 * poses.len(), echoes);
    exit(true);
}
