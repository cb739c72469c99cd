//! The scenario reader on arbitrary bytes; an accepted scenario is then
//! replayed through the ring driver over the replay bench and the
//! controller on the office map (a scenario made for another map or ring is
//! refused by `check`, and the replay's errors are typed: nothing panics).
#![no_main]

use echoloc::controller::replay::{check as replay_check, localizer, run, scenario_odometry, start, ReplaySetup};
use echoloc::credence::net::CredenceNet;
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::{Mount, PredictParams};
use echoloc::scenario::replay::Bench;
use echoloc::scenario::Scenario;
use echoloc::window::WindowParams;
use libfuzzer_sys::fuzz_target;

static OFFICE: &Aligned<[u8]> = &Aligned(*include_bytes!("../../boards/qemu-mps2-an386/office.map"));

fuzz_target!(|data: &[u8]| {
    check(data);
    // Mutations almost never keep the CRC right: also take each input with
    // its CRC recomputed, so that the reader's later checks are reached.
    if data.len() >= 4 {
        let mut sealed = data.to_vec();
        let n = sealed.len() - 4;
        let crc = echoloc::map::crc32(&sealed[..n]);
        sealed[n..].copy_from_slice(&crc.to_le_bytes());
        check(&sealed);
    }
});

fn check(data: &[u8]) {
    let Ok(s) = Scenario::parse(data) else { return };
    let _ = s.records().count();
    let _ = s.header().check_driver(1, 2, 3);
    let Ok(map) = MapView::new(&OFFICE.0) else { return };
    let Ok(setup) =
        ReplaySetup::<16>::standard(PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE }))
    else {
        return;
    };
    let mounts: Vec<Mount> = (0..s.transducers()).filter_map(|i| s.mount(i)).collect();
    let bench = Bench::new(s, 1_000);
    // The map check is passed on purpose (the scenario's own CRC), so that
    // arbitrary records reach the driver and the filter.
    if replay_check(&bench, s.header().map_crc, &setup).is_err() {
        return;
    }
    // No particles: the office map is compiled without a field, so the
    // localizer only tracks from the scenario's start.
    let mut loc = localizer::<0, 16>(&setup, 1);
    if start(&mut loc, &bench, map.field(), None).is_err() {
        return;
    }
    let _ = run::<_, _, 4, 16, 0>(
        &bench,
        &map,
        map.field(),
        &mounts,
        &CredenceNet::shipped(),
        &setup,
        &mut loc,
        scenario_odometry,
        |_, _, _, _| {},
    );
}
