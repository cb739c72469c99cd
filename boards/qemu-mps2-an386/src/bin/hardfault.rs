//! Proves the crash path: executes a permanently undefined instruction
//! (`udf`), which escalates to a HardFault; the shared handler must print
//! where and leave QEMU with exit code 1. CI runs this and expects exactly
//! that, so a crash can never pass for success.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use qemu_mps2_an386::exit;

#[entry]
fn main() -> ! {
    hprintln!("about to execute udf: expect a HardFault and exit code 1");
    // SAFETY: deliberately faults; nothing after it runs.
    unsafe { core::arch::asm!("udf #0") };
    hprintln!("FAIL: still running after udf");
    exit(true)
}
