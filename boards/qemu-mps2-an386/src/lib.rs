//! What every echoloc binary on QEMU's `mps2-an386` shares: the SysTick cost
//! counter and its calibration loop, the stack high-water mark, the
//! semihosting exit, and the HardFault and panic handlers that turn a crash
//! into a failing exit code (linked into every binary that uses this crate).
#![no_std]

pub mod partition;
pub mod replay;
pub mod uart;

use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::{exception, ExceptionFrame};
use cortex_m_semihosting::{debug, hprintln};

/// Starts SysTick as a free-running 24-bit down-counter at the core clock
/// (25 MHz on this board): under the runner's `-icount shift=0` its counts
/// are deterministic, and one tick is 40 instructions. `None` if the core
/// peripherals were already taken (every reading is then 0).
pub fn start_systick() -> Option<SYST> {
    let mut syst = cortex_m::Peripherals::take().map(|p| p.SYST);
    if let Some(s) = syst.as_mut() {
        s.set_clock_source(SystClkSource::Core);
        s.set_reload(0x00FF_FFFF);
        s.clear_current();
        s.enable_counter();
    }
    syst
}

/// The counter now.
pub fn ticks(s: &Option<SYST>) -> u32 {
    s.as_ref().map_or(0, |_| SYST::get_current())
}

/// Ticks from `start` to `end`: SysTick counts down and wraps at 2²⁴, so
/// spans must stay below 0.67 s.
pub fn elapsed(start: u32, end: u32) -> u32 {
    start.wrapping_sub(end) & 0x00FF_FFFF
}

/// Exactly `2 * n` instructions (n ≥ 1): the calibration loop.
pub fn spin(n: u32) {
    // SAFETY: a register-only countdown loop; no memory is touched.
    unsafe {
        core::arch::asm!("1:", "subs {0}, {0}, #1", "bne 1b", inout(reg) n => _, options(nomem, nostack));
    }
}

/// The stack's high-water mark by painting (shared with the STM32 board).
pub use stack_paint::{first_unpainted, paint_free_stack, stack_bounds, stack_high_water};

/// Times a loop of exactly 20 000 instructions, prints the calibration line
/// every binary starts with, and returns instructions per SysTick tick.
pub fn calibrate(syst: &Option<SYST>) -> u32 {
    let t0 = ticks(syst);
    spin(10_000);
    let cal = elapsed(t0, ticks(syst)).max(1);
    hprintln!("calibration: 20000 instructions = {} SysTick ticks ({} instructions per tick)", cal, 20_000 / cal);
    20_000 / cal
}

/// Leaves QEMU through semihosting: exit code 0 when `ok`, 1 otherwise.
pub fn exit(ok: bool) -> ! {
    debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    // Only reached when semihosting is off (no debugger): stop here.
    loop {
        cortex_m::asm::wfi();
    }
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    // Written without `core::fmt`, whose calls through registers would
    // leave the handler's stack unbounded for `scripts/stack-bound.py`.
    let mut line = *b"HardFault at pc 0x00000000\n";
    let pc = ef.pc();
    for (k, d) in line[18..26].iter_mut().enumerate() {
        let nibble = (pc >> (28 - 4 * k)) & 0xf;
        *d = b"0123456789abcdef"[nibble as usize];
    }
    if let Ok(mut out) = cortex_m_semihosting::hio::hstdout() {
        let _ = out.write_all(&line);
    }
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    exit(false)
}

/// Bytes of RAM taken by statics: `.data`, `.bss` and `.uninit`, from
/// cortex-m-rt's linker symbols (the stack is the rest of RAM).
pub fn static_ram_bytes() -> usize {
    extern "C" {
        static __sdata: u32;
        static __euninit: u32;
    }
    core::ptr::addr_of!(__euninit) as usize - core::ptr::addr_of!(__sdata) as usize
}

/// Bytes of flash the image takes: the vector table, `.text`, `.rodata`
/// and `.data`'s initial values (flash starts at 0 on this board).
pub fn flash_bytes() -> usize {
    extern "C" {
        static __erodata: u32;
        static __sdata: u32;
        static __edata: u32;
    }
    let data = core::ptr::addr_of!(__edata) as usize - core::ptr::addr_of!(__sdata) as usize;
    core::ptr::addr_of!(__erodata) as usize + data
}

/// Prints one `metric NAME VALUE` line, the form `scripts/metrics.sh` reads.
pub fn metric(name: &str, value: u64) {
    hprintln!("metric {} {}", name, value);
}

/// Up to `N` poses spread through the map's free space by a fixed generator
/// (xorshift32 from a fixed seed, so every run and every binary times the
/// same poses): none inside a piece, none with a piece within 300 mm along
/// either axis. Gives up after `max_tries` candidates (a map with no free
/// space returns fewer).
pub fn free_poses<const N: usize>(
    map: &echoloc::map::MapView<'_>,
    max_tries: u32,
) -> heapless::Vec<echoloc::predict::Pose, N> {
    use echoloc::geometry::{Point, Rect, Segment};
    use echoloc::map::MapSource;
    let mut out = heapless::Vec::new();
    let Some(b) = map.bounds() else { return out };
    let mut s = 0x2545_F491u32;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s
    };
    let mut tries = 0;
    while !out.is_full() && tries < max_tries {
        tries += 1;
        let x = b.min.x + (next() % (b.max.x - b.min.x).max(1) as u32) as i32;
        let y = b.min.y + (next() % (b.max.y - b.min.y).max(1) as u32) as i32;
        let heading = (next() % 6283) as f32 / 1000.0 - core::f32::consts::PI;
        let p = Point::new(x, y);
        let mut free = true;
        let _ = map.for_each_candidate(Rect::around(p), |piece| {
            free &= !piece.shape.tvector(p).is_inside();
        });
        for seg in [
            Segment::new(Point::new(x - 300, y), Point::new(x + 300, y)),
            Segment::new(Point::new(x, y - 300), Point::new(x, y + 300)),
        ] {
            free &= matches!(map.first_hit(seg), Ok(None));
        }
        if free {
            let _ = out.push(echoloc::predict::Pose { x_mm: x as f32, y_mm: y as f32, heading_rad: heading });
        }
    }
    out
}

/// What [`time_rings`] measured.
pub struct RingTimes {
    /// Instructions over every ring.
    pub total: u64,
    /// Instructions of the costliest ring.
    pub worst: u64,
    /// Windows that predicted an echo.
    pub predicted: usize,
    /// Whether every prediction succeeded.
    pub ok: bool,
}

/// Times a Pioneer ring prediction at each pose, in instructions (`per_tick`
/// from [`calibrate`]).
pub fn time_rings(
    map: &echoloc::map::MapView<'_>,
    poses: &[echoloc::predict::Pose],
    params: &echoloc::predict::PredictParams,
    net: &echoloc::credence::net::CredenceNet<'_>,
    syst: &Option<SYST>,
    per_tick: u32,
) -> RingTimes {
    use echoloc::predict::{predict_ring, PIONEER16};
    let mut t = RingTimes { total: 0, worst: 0, predicted: 0, ok: true };
    for pose in poses {
        let mut out = [None; 16];
        let t0 = ticks(syst);
        let r = predict_ring(map, core::hint::black_box(pose), &PIONEER16, params, net, &mut out);
        let n = (elapsed(t0, ticks(syst)) * per_tick) as u64;
        if let Err(e) = r {
            // In whole mm and mrad: the image then carries no float formatting.
            let mrad = (pose.heading_rad * 1000.0) as i32;
            hprintln!("FAIL: ring at ({} mm, {} mm, {} mrad): {:?}", pose.x_mm as i32, pose.y_mm as i32, mrad, e);
            t.ok = false;
        }
        t.predicted += out.iter().flatten().count();
        t.total += n;
        t.worst = t.worst.max(n);
    }
    t
}
