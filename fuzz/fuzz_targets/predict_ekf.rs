//! Prediction and the EKF on the real maps with arbitrary poses, readings,
//! odometry and κ: every call returns a value or a typed error, never a
//! panic, and the filter's state stays finite or is refused.
#![no_main]

use echoloc::credence::net::CredenceNet;
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::{predict_ring, Pose, PredictParams, PIONEER16};
use echoloc::referencing::{Ekf, EkfConfig, Motion, Reading, Referencer, VerdictConfig};
use echoloc::window::WindowParams;
use libfuzzer_sys::fuzz_target;

static OFFICE: &Aligned<[u8]> = &Aligned(*include_bytes!("../../boards/qemu-mps2-an386/office.map"));
static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../boards/qemu-mps2-an386/depot.map"));

fn f32_at(d: &[u8], k: usize) -> f32 {
    let o = 4 * k;
    d.get(o..o + 4).map_or(0.0, |s| f32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

fuzz_target!(|data: &[u8]| {
    let blob = if data.first().is_some_and(|b| b & 1 == 1) { &DEPOT.0 } else { &OFFICE.0 };
    let Ok(map) = MapView::new(blob) else { return };
    let params = PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE });
    let net = CredenceNet::shipped();
    let pose = Pose { x_mm: f32_at(data, 1), y_mm: f32_at(data, 2), heading_rad: f32_at(data, 3) };
    let mut out = [None; 16];
    let _ = predict_ring(&map, &pose, &PIONEER16, &params, &net, &mut out);
    let start = [f32_at(data, 4), f32_at(data, 5), f32_at(data, 6)];
    let sigma = [f32_at(data, 7), f32_at(data, 8), f32_at(data, 9)];
    let Ok(ekf) = Ekf::new(start, sigma, EkfConfig::DEFAULT) else { return };
    let mut r = Referencer::new(ekf, VerdictConfig::POLAROID);
    for k in 0..((data.len() / 4).saturating_sub(10) / 4) {
        let b = 10 + 4 * k;
        let u = Motion { dx: f32_at(data, b), dy: f32_at(data, b + 1), dphi: f32_at(data, b + 2) };
        let _ = r.odometry(&u);
        let raw = f32_at(data, b + 3);
        let reading =
            if raw.is_finite() && raw >= 0.0 { Reading::Echo { range_mm: raw as u32 } } else { Reading::NoEcho };
        let _ = r.reading(&map, &PIONEER16[k % 16], &params, &net, reading);
        if k % 16 == 15 {
            let _ = r.end_cycle();
        }
        let x = r.ekf.state();
        assert!(x.iter().all(|v| v.is_finite()), "the filter's state went non-finite: {x:?}");
    }
});
