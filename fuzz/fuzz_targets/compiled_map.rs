//! The compiled-map validator on arbitrary bytes; what it accepts is then
//! queried (a segment, candidates, a window's prediction), which must not
//! panic either.
#![no_main]

use echoloc::credence::net::CredenceNet;
use echoloc::geometry::{Point, Rect, Segment};
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{predict, PredictParams};
use echoloc::window::{Window, WindowParams};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    check(data, false);
    // Mutations almost never keep the CRC right: also take each input with
    // its CRC recomputed, so that the validator's later checks are reached.
    check(data, true);
});

fn check(data: &[u8], reseal: bool) {
    // 8-byte-aligned storage, as the firmware's flash image guarantees.
    let mut words = vec![0u64; data.len().div_ceil(8)];
    let buf = &mut bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..data.len()];
    buf.copy_from_slice(data);
    if reseal && buf.len() >= 16 {
        let crc = echoloc::map::crc32(&buf[16..]);
        buf[12..16].copy_from_slice(&crc.to_le_bytes());
    }
    let bytes = &bytemuck::cast_slice::<u64, u8>(&words)[..data.len()];
    let Ok(map) = MapView::new(bytes) else { return };
    let Some(b) = map.bounds() else { return };
    let mid = Point::new(b.min.x / 2 + b.max.x / 2, b.min.y / 2 + b.max.y / 2);
    let _ = map.first_hit(Segment::new(b.min, b.max));
    let _ = map.for_each_candidate(Rect::around(mid), |_| {});
    let params = PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE });
    for heading in [0.0f32, 2.1, -1.3] {
        if let Ok(w) = Window::place(&params.window, mid, heading) {
            let _ = predict(&map, &w, &params, &CredenceNet::shipped());
        }
    }
}
