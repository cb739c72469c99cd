//! The link-time proof that the firmware core cannot panic (issue #14 item
//! 2, the `panic-never` approach). This program runs every core path a
//! board runs on inputs the compiler cannot see (a compiled map, a scenario
//! and link bytes read from flash partitions, poses from memory):
//! validating the map, predicting rings with both strategies and the
//! geometric search, the whole loop (ring driver over the replay bench,
//! odometry, prediction, credence, verdicts, EKF, lost monitor, the
//! localizer's search with either hand-off), the host
//! link's decoder and encoder, the link over a serial port with the
//! odometry sync, and the threshold method. Its panic handler calls a
//! function that is declared but defined nowhere, so the program links only
//! if the optimiser removed every panic path from all of it: a bounds check
//! it could not prove, an `unwrap`, a division by zero. (Integer overflow
//! wraps in a release build, so it is not covered here: docs/robustness.md.)
//!
//! `cargo build -p panic-never --target thumbv7em-none-eabihf --release`
//! (run by `scripts/test.sh`; `scripts/panic-never.sh --plant` shows it
//! failing on a planted panic path). It is built, never run.
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use echoloc::controller::replay::{check, localizer, run, scenario_odometry, start, ReplaySetup};
use echoloc::controller::{OdometrySample, OdometrySync};
use echoloc::credence::net::CredenceNet;
use echoloc::link::frame::{encode, Decoder};
use echoloc::link::{FromController, Link, ToController};
use echoloc::localize::{PlaceTest, Start};
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{nearest_in_window, predict_ring, Mount, Pose, PredictParams, PIONEER16};
use echoloc::referencing::{MountM, Target, Threshold, ThresholdConfig};
use echoloc::scenario::replay::Bench;
use echoloc::scenario::Scenario;
use echoloc::window::{Strategy, Window, WindowParams};

/// Where the inputs are: flash partitions of the board (QEMU's loader
/// fills them), never written by the program.
const MAP_AT: usize = 0x0020_0000;
const MAP_LEN: usize = 1024 * 1024;
const SCENARIO_AT: usize = 0x0030_0000;
const SCENARIO_LEN: usize = 512 * 1024;
const INPUT_AT: usize = 0x0038_0000;
const INPUT_LEN: usize = 4096;

fn partition(at: usize, len: usize) -> &'static [u8] {
    // SAFETY: these ranges lie in SSRAM1 of mps2-an386 (4 MiB at 0, always
    // mapped), past the 1 MiB image, and nothing in this program writes them.
    unsafe { core::slice::from_raw_parts(at as *const u8, len) }
}

/// A byte slice's prefix of the length its own 32-bit field at `at` claims, bounded.
fn claimed(bytes: &'static [u8], at: usize) -> &'static [u8] {
    let n = match bytes.get(at..at + 4) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]) as usize,
        _ => 0,
    };
    bytes.get(..n).unwrap_or(&[])
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    match bytes.get(at..at + 4) {
        Some(&[a, b, c, d]) => f32::from_le_bytes([a, b, c, d]),
        _ => 0.0,
    }
}

/// A serial port over the input partition: what it holds is received, what
/// is sent is counted.
struct Port {
    rx: &'static [u8],
    tx: usize,
}

impl embedded_io::ErrorType for Port {
    type Error = core::convert::Infallible;
}

impl embedded_io::Read for Port {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let n = buf.len().min(self.rx.len());
        let (now, rest) = self.rx.split_at(n);
        if let Some(dst) = buf.get_mut(..n) {
            dst.copy_from_slice(now);
        }
        self.rx = rest;
        Ok(n)
    }
}

impl embedded_io::ReadReady for Port {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(!self.rx.is_empty())
    }
}

impl embedded_io::Write for Port {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.tx = self.tx.wrapping_add(black_box(buf).len());
        Ok(buf.len())
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

#[entry]
fn main() -> ! {
    let input = partition(INPUT_AT, INPUT_LEN);
    let net = CredenceNet::shipped();
    // What the paths found, kept from the optimiser: a checksum, so it wraps.
    let mut found = 0u32;
    let map_bytes = claimed(partition(MAP_AT, MAP_LEN), 0);
    if let Ok(map) = MapView::new(map_bytes) {
        let pose = Pose { x_mm: f32_at(input, 0), y_mm: f32_at(input, 4), heading_rad: f32_at(input, 8) };
        let window = WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::MARGE };
        for strategy in [Strategy::Exact, Strategy::PseudoPaths] {
            let params = PredictParams { strategy, ..PredictParams::new(window) };
            let mut out = [None; 16];
            if predict_ring(&map, &pose, &PIONEER16, &params, &net, &mut out).is_ok() {
                found = found.wrapping_add(out.iter().flatten().fold(0u32, |n, _| n.wrapping_add(1)));
            }
        }
        let apex = echoloc::geometry::Point::new(pose.x_mm as i32, pose.y_mm as i32);
        if let Ok(w) = Window::place(&window, apex, pose.heading_rad) {
            found = found.wrapping_add(u32::from(matches!(nearest_in_window(&map, &w), Ok(Some(_)))));
        }
        // The whole loop over a scenario, through the ring driver.
        let params = PredictParams::new(window);
        if let (Ok(mut setup), Ok(s)) =
            (ReplaySetup::<16>::standard(params), Scenario::parse(claimed(partition(SCENARIO_AT, SCENARIO_LEN), 0)))
        {
            // The hand-off by the cluster or by the sequential test between
            // places (issue #48), as the input says: both reachable.
            let bound = f32_at(input, 12);
            if bound > 0.0 {
                setup.localizer.place_test = Some(PlaceTest { bound, ..PlaceTest::DEFAULT });
            }
            let mut mounts = [Mount { x_mm: 0, y_mm: 0, heading_mdeg: 0 }; 16];
            for (i, m) in mounts.iter_mut().enumerate() {
                *m = s.mount(i).unwrap_or(*m);
            }
            let bench = Bench::new(s, 1_000);
            if check(&bench, echoloc::map::crc32(map_bytes), &setup).is_ok() {
                // With the particles: a search from no pose (the localizer's
                // every mode is reachable from it: hand-off, tracking, wake-up).
                let mut loc = localizer::<1024, 16>(&setup, 1);
                if start(&mut loc, &bench, map.field(), Some(Start::Unknown)).is_ok() {
                    if let Ok(summary) = run::<_, _, 4, 16, 1024>(
                        &bench,
                        &map,
                        map.field(),
                        &mounts,
                        &net,
                        &setup,
                        &mut loc,
                        scenario_odometry,
                        |_, _, _, _| {},
                    ) {
                        found = found.wrapping_add(summary.accepted);
                    }
                }
            }
        }
    }
    // The host link: frames in, a status out.
    let mut decoder: Decoder<256> = Decoder::new();
    for &b in input.get(12..).unwrap_or(&[]) {
        if let Some(Ok(ToController::Odometry { .. })) = decoder.push::<ToController>(b) {
            found = found.wrapping_add(1);
        }
    }
    let status = FromController::Status { rx: decoder.counts(), odometry_refused: 0, readings: found, stale: 0 };
    let mut frame = [0u8; 300];
    let n = encode::<_, 256>(&status, &mut frame).unwrap_or(0);
    // The link over a serial port (what the boards run): odometry in through
    // the sync that interpolates it to firing times, the threshold method
    // fed from it, a status out.
    let mut link = Link::new(Port { rx: input.get(12..).unwrap_or(&[]), tx: 0 });
    let mut sync: OdometrySync<8> = OdometrySync::default();
    let mut threshold = Threshold::new([0.0; 3], ThresholdConfig::DEFAULT);
    let target = Target::Point { point: [f32_at(input, 0), f32_at(input, 4)] };
    let mount = MountM::from(&PIONEER16[3]);
    for _ in 0..64 {
        match link.poll(64) {
            Ok(Some(ToController::Odometry { time_us, x, y, theta })) => {
                if sync.push(OdometrySample { time_us, pose: [x, y, theta] }).is_ok() {
                    let t = time_us.wrapping_sub(black_box(500));
                    if let Ok(u) = sync.increment_to(t) {
                        threshold.predict(&u);
                        found = found.wrapping_add(u32::from(threshold.update(f32_at(input, 8), 0.9, mount, &target)));
                    }
                }
            }
            Ok(Some(_)) => found = found.wrapping_add(1),
            Ok(None) | Err(_) => break,
        }
    }
    let _ = link.send(&status);
    black_box((found, frame, n, threshold.state(), link.rx_counts()));
    loop {
        cortex_m::asm::wfi();
    }
}

#[cfg(feature = "locate")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

#[cfg(not(feature = "locate"))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    extern "Rust" {
        /// Defined nowhere: any call left in the program fails the link.
        fn echoloc_core_panic_path_remains() -> !;
    }
    // SAFETY: never executed — the program links only if no call to this
    // handler survives optimisation.
    unsafe { echoloc_core_panic_path_remains() }
}

/// cortex-m-rt's HardFault handler, without printing.
#[cortex_m_rt::exception]
unsafe fn HardFault(_: &cortex_m_rt::ExceptionFrame) -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
