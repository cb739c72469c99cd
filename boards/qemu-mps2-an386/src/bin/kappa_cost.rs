//! The cost of one credence evaluation κ(R, θ) on QEMU's `mps2-an386`
//! (Cortex-M4F), with the quantised 2-10-1 net the firmware ships
//! (`echoloc::credence::net`).
//!
//! Times `N` evaluations over a sweep of the input domain with SysTick
//! (deterministic under the runner's `-icount shift=0`), subtracts the same
//! sweep without the net, and prints ticks and instructions per call; the
//! instructions per tick come from a calibration loop of known length, as in
//! the board's main firmware. Checks a few κ values on the way (the axis,
//! the first null and side lobe), then measures the stack one evaluation
//! uses: the free stack below `main`'s frame is painted again (cortex-m-rt's
//! `paint-stack` painted it before `main`, but the printing since has used
//! it), one κ is evaluated for each point of the sweep through a call that
//! is never inlined, and the deepest word overwritten gives the bytes below
//! the caller's stack pointer. Exits through semihosting: 0 when every check
//! passed, 1 otherwise; a HardFault or panic exits with 1 too.
//!
//! `cargo run -p qemu-mps2-an386 --bin kappa_cost --target thumbv7em-none-eabihf --release`
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::credence::net::CredenceNet;
use echoloc::credence::{Credence, EchoGeometry, Kappa};
use qemu_mps2_an386::{
    calibrate, elapsed, exit, first_unpainted, paint_free_stack, stack_bounds, stack_high_water, start_systick, ticks,
};

/// Evaluations timed: a 16 × 16 sweep of (R, θ).
const SIDE: u32 = 16;
const N: u32 = SIDE * SIDE;

#[entry]
fn main() -> ! {
    let mut ok = true;
    let syst = start_systick();
    hprintln!("echoloc {} credence cost on mps2-an386 (Cortex-M4F)", env!("CARGO_PKG_VERSION"));
    let per_tick = calibrate(&syst);

    let net = black_box(CredenceNet::shipped());
    // Sanity: the shipped net's lobes (host tests pin every value bit-exactly).
    let k = |r: u32, mdeg: i32| net.kappa(&EchoGeometry { range_mm: r, theta_mdeg: mdeg, delta_mdeg: 0 });
    let (axis, null, lobe) = (k(1000, 0), k(1000, 12_500), k(1000, -17_500));
    hprintln!(
        "kappa at 1 m: axis {} (bits {}), 12.5 deg {} , -17.5 deg {}",
        axis.to_num::<f32>(),
        axis.to_bits(),
        null.to_num::<f32>(),
        lobe.to_num::<f32>()
    );
    if !(axis > Kappa::from_num(0.85) && lobe > null) {
        hprintln!("FAIL: the shipped net lost its lobes");
        ok = false;
    }

    // The sweep with the net, then the same sweep without it.
    let t0 = ticks(&syst);
    let mut sum = 0u32;
    for i in 0..N {
        let e = black_box(sweep(i));
        sum = sum.wrapping_add(u32::from(net.kappa(&e).to_bits()));
    }
    let with_net = elapsed(t0, ticks(&syst));
    black_box(sum);
    let t0 = ticks(&syst);
    let mut base = 0u32;
    for i in 0..N {
        let e = black_box(sweep(i));
        base = base.wrapping_add(e.range_mm ^ e.theta_mdeg as u32);
    }
    let without = elapsed(t0, ticks(&syst));
    black_box(base);
    let net_ticks = with_net.saturating_sub(without);
    hprintln!(
        "{} evaluations: {} ticks with the net, {} without; {} ticks = {} instructions per kappa (checksum {})",
        N,
        with_net,
        without,
        net_ticks / N,
        net_ticks * per_tick / N,
        sum
    );

    // Stack: the deepest use so far (the printing, mostly), then repaint below
    // this frame, evaluate the sweep again and find the deepest word written.
    let (used, size) = stack_high_water();
    let (top, bottom) = stack_bounds();
    let sp = paint_free_stack(bottom);
    let mut again = 0u32;
    for i in 0..N {
        again = again.wrapping_add(u32::from(kappa_call(&net, &black_box(sweep(i))).to_bits()));
    }
    let kappa_stack = sp - first_unpainted(bottom, sp);
    if again != sum || kappa_stack == 0 {
        hprintln!("FAIL: stack sweep checksum {} (expected {}), {} bytes measured", again, sum, kappa_stack);
        ok = false;
    }
    hprintln!(
        "stack: {} bytes per kappa call, below main's frame of {}; high-water mark before: {} of {} bytes",
        kappa_stack,
        top - sp,
        used,
        size
    );
    exit(ok);
}

/// One κ through a call that is never inlined, so that its frame lies below
/// the caller's stack pointer.
#[inline(never)]
fn kappa_call(net: &CredenceNet<'_>, e: &EchoGeometry) -> Kappa {
    black_box(net).kappa(e)
}

/// The i-th point of a 16 × 16 sweep over R 500…5500 mm × θ −45…45°.
fn sweep(i: u32) -> EchoGeometry {
    let (a, b) = ((i % SIDE) as i32, (i / SIDE) as i32);
    EchoGeometry { range_mm: 500 + 333 * a as u32, theta_mdeg: -45_000 + 6_000 * b, delta_mdeg: 0 }
}
