//! The benchmark's windows on the emulated Cortex-M4 (issue #13 item 4):
//! the windows `echoloc-lab bench --export-windows` timed on the host, read
//! from the flash partition at 0x0030_0000 with the host's answers and the
//! occupancy grid, timed here in instructions (SysTick under `-icount
//! shift=0`) for echoloc's exact nearest obstacle, its full prediction, and
//! a 1° Bresenham fan on the grid (amcl's beam model, the same algorithm as
//! the host peer, on a bit-packed grid in flash).
//!
//! Checks that the exact answers equal the host's (within 1 mm) and that
//! the fan agrees with the host's fan on at least 99 % of the windows (f32
//! ray directions here, f64 there, can end a ray one cell apart). Prints
//! `metric bench_exact_insns_per_window`, `bench_full_insns_per_window`,
//! `bench_bresenham_insns_per_window` and exits 0 when every check passed.
//!
//! Run by `bash scripts/bench-m4.sh` (QEMU's loader puts the file in the partition).
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::geometry::Point;
use echoloc::map::{Aligned, MapSource, MapView};
use echoloc::predict::{nearest_in_window, predict, PredictParams};
use echoloc::window::{Window, WindowParams};
use qemu_mps2_an386::{calibrate, elapsed, exit, metric, start_systick, ticks};

static DEPOT: &Aligned<[u8]> = &Aligned(*include_bytes!("../../depot.map"));
const PARTITION: usize = 0x0030_0000;
const PARTITION_LEN: usize = 1024 * 1024;
const HEADER: usize = 44;

fn u32_at(b: &[u8], o: usize) -> u32 {
    b.get(o..o + 4).map_or(0, |s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// The exported file in the partition, its length from its header.
fn partition() -> Option<&'static [u8]> {
    // SAFETY: PARTITION..+PARTITION_LEN is SSRAM1 (mapped, readable, outside
    // everything the linker places), never written by this program.
    let head: &[u8] = unsafe { core::slice::from_raw_parts(PARTITION as *const u8, HEADER) };
    if &head[..4] != b"ECBW" || u32_at(head, 4) != 1 {
        return None;
    }
    let n = u32_at(head, 8) as usize;
    let (w, h) = (u32_at(head, 24) as usize, u32_at(head, 28) as usize);
    let len = HEADER + n * 12 + n * 8 + (w * h).div_ceil(8);
    // SAFETY: as above, and `len` is checked against the partition.
    (len <= PARTITION_LEN).then(|| unsafe { core::slice::from_raw_parts(PARTITION as *const u8, len) })
}

struct BitGrid<'a> {
    w: i32,
    h: i32,
    res_mm: i32,
    x0: i32,
    y0: i32,
    bits: &'a [u8],
}

impl BitGrid<'_> {
    fn occupied(&self, i: i32, j: i32) -> bool {
        if i < 0 || j < 0 || i >= self.w || j >= self.h {
            return true;
        }
        let k = (j * self.w + i) as usize;
        self.bits.get(k / 8).is_some_and(|b| b & (1 << (k % 8)) != 0)
    }

    fn cell_of(&self, x: f32, y: f32) -> (i32, i32) {
        (
            libm::floorf((x - self.x0 as f32) / self.res_mm as f32) as i32,
            libm::floorf((y - self.y0 as f32) / self.res_mm as f32) as i32,
        )
    }

    /// amcl's `map_calc_range`, as the host peer: mm, or `None`.
    fn bresenham(&self, o: (f32, f32), dir: (f32, f32), max_mm: f32) -> Option<f32> {
        let (ax, ay) = self.cell_of(o.0, o.1);
        let (bx, by) = self.cell_of(o.0 + dir.0 * max_mm, o.1 + dir.1 * max_mm);
        let steep = (by - ay).abs() > (bx - ax).abs();
        let (x0, y0, x1, y1) = if steep { (ay, ax, by, bx) } else { (ax, ay, bx, by) };
        let (dx, dy) = ((x1 - x0).abs(), (y1 - y0).abs());
        let xstep = if x0 < x1 { 1 } else { -1 };
        let ystep = if y0 < y1 { 1 } else { -1 };
        let (mut x, mut y, mut error) = (x0, y0, 0);
        loop {
            let hit = if steep { self.occupied(y, x) } else { self.occupied(x, y) };
            if hit {
                let (ddx, ddy) = ((x - x0) as f32, (y - y0) as f32);
                let r = echoloc::f32math::sqrt(ddx * ddx + ddy * ddy) * self.res_mm as f32;
                return (r <= max_mm).then_some(r);
            }
            if x == x1 {
                return None;
            }
            x += xstep;
            error += dy;
            if 2 * error >= dx {
                y += ystep;
                error -= dx;
            }
        }
    }

    /// A 1° fan over `half` either side of `heading`: the nearest range.
    fn fan(&self, o: (f32, f32), heading: f32, half_deg: i32, max_mm: f32) -> Option<f32> {
        let mut best: Option<f32> = None;
        for k in -half_deg..=half_deg {
            let (s, c) = echoloc::f32math::sin_cos(heading + (k as f32).to_radians());
            if let Some(r) = self.bresenham(o, (c, s), max_mm) {
                best = Some(best.map_or(r, |b: f32| b.min(r)));
            }
        }
        best
    }
}

#[entry]
fn main() -> ! {
    let syst = start_systick();
    hprintln!("echoloc {} on mps2-an386: the benchmark's windows from {:#010x}", env!("CARGO_PKG_VERSION"), PARTITION);
    let per_tick = u64::from(calibrate(&syst));
    let Some(b) = partition() else {
        hprintln!("FAIL: no window file in the partition");
        exit(false);
    };
    let Ok(map) = MapView::new(&DEPOT.0) else { exit(false) };
    if u32_at(b, 20) != echoloc::map::crc32(&DEPOT.0) {
        hprintln!("FAIL: the windows were made on another map");
        exit(false);
    }
    let n = u32_at(b, 8) as usize;
    let half_mdeg = u32_at(b, 12);
    let r_max = u32_at(b, 16);
    let grid = BitGrid {
        w: u32_at(b, 24) as i32,
        h: u32_at(b, 28) as i32,
        res_mm: u32_at(b, 32) as i32,
        x0: u32_at(b, 36) as i32,
        y0: u32_at(b, 40) as i32,
        bits: &b[HEADER + n * 20..],
    };
    let f32_at = |o: usize| f32::from_bits(u32_at(b, o));
    let wp = WindowParams {
        r_min_mm: 0,
        r_max_mm: r_max,
        half_angle_deg: half_mdeg as f32 / 1000.0,
        tb_mm: map.buffer_mm(),
        ..WindowParams::MARGE
    };
    let params = PredictParams::new(WindowParams { r_min_mm: WindowParams::MARGE.r_min_mm, ..wp });
    let net = CredenceNet::shipped();
    let (mut exact_t, mut full_t, mut fan_t) = (0u64, 0u64, 0u64);
    let (mut exact_ok, mut fan_ok) = (0usize, 0usize);
    for k in 0..n {
        let o = HEADER + k * 12;
        let apex = Point::new(u32_at(b, o) as i32, u32_at(b, o + 4) as i32);
        let heading = f32_at(o + 8);
        let host_exact = f32_at(HEADER + n * 12 + k * 4);
        let host_fan = f32_at(HEADER + n * 16 + k * 4);
        let Ok(w) = Window::place(&wp, apex, heading) else { exit(false) };
        let t0 = ticks(&syst);
        let e = nearest_in_window(&map, black_box(&w));
        exact_t += u64::from(elapsed(t0, ticks(&syst))) * per_tick;
        let e = e.ok().flatten().map_or(-1.0, |x| x.range_mm as f32);
        if (e < 0.0 && host_exact < 0.0) || (e - host_exact).abs() <= 1.0 {
            exact_ok += 1;
        }
        let Ok(fw) = Window::place(&params.window, apex, heading) else { exit(false) };
        let t0 = ticks(&syst);
        black_box(predict(&map, black_box(&fw), &params, &net).ok());
        full_t += u64::from(elapsed(t0, ticks(&syst))) * per_tick;
        let t0 = ticks(&syst);
        let f = grid.fan((apex.x as f32, apex.y as f32), black_box(heading), (half_mdeg / 1000) as i32, r_max as f32);
        fan_t += u64::from(elapsed(t0, ticks(&syst))) * per_tick;
        let f = f.unwrap_or(-1.0);
        if (f < 0.0 && host_fan < 0.0) || (f - host_fan).abs() <= 1.0 {
            fan_ok += 1;
        }
    }
    let nn = n.max(1) as u64;
    hprintln!(
        "{} windows, half-angle {} mdeg: exact answers equal the host's on {}, the fan's on {}",
        n,
        half_mdeg,
        exact_ok,
        fan_ok
    );
    metric("bench_exact_insns_per_window", exact_t / nn);
    metric("bench_full_insns_per_window", full_t / nn);
    metric("bench_bresenham_insns_per_window", fan_t / nn);
    hprintln!("grid in flash: {} bytes (bits); map: {} bytes", grid.bits.len(), DEPOT.0.len());
    let ok = n > 0 && exact_ok == n && fan_ok * 100 >= n * 99;
    if !ok {
        hprintln!("FAIL: answers differ from the host's");
    }
    exit(ok);
}
