//! The mps2-an386's CMSDK APB UART0 as an `embedded-io` serial port: the
//! board's end of the host link. QEMU connects it to whatever `-serial`
//! names (a Unix socket for `echoloc-lab link`).
//!
//! Registers (ARM CMSDK APB UART, base 0x4000_4000): DATA at +0x00; STATE at
//! +0x04 (bit 0 TX buffer full, bit 1 RX buffer full); CTRL at +0x08 (bit 0
//! TX enable, bit 1 RX enable); BAUDDIV at +0x10 (QEMU's model sends
//! nothing with a divider below 16). Receiving has a one-byte buffer: QEMU
//! holds further bytes back until it is read, so nothing is lost to a slow
//! reader.

use core::convert::Infallible;

use embedded_io::{ErrorType, Read, ReadReady, Write};

const BASE: usize = 0x4000_4000;
const DATA: usize = BASE;
const STATE: usize = BASE + 0x04;
const CTRL: usize = BASE + 0x08;
const BAUDDIV: usize = BASE + 0x10;
const TX_FULL: u32 = 1;
const RX_FULL: u32 = 2;

/// UART0, owned: there is one, so [`Uart0::take`] hands it out once.
#[derive(Debug)]
pub struct Uart0(());

static TAKEN: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

fn read(reg: usize) -> u32 {
    // SAFETY: `reg` is one of UART0's registers above, always mapped on
    // mps2-an386; a 32-bit volatile read has no side effect but on DATA,
    // where it takes the received byte, which is what the callers want.
    unsafe { core::ptr::read_volatile(reg as *const u32) }
}

fn write(reg: usize, v: u32) {
    // SAFETY: as in `read`: a 32-bit volatile write to a UART0 register,
    // which only this (single) owner of the UART writes.
    unsafe { core::ptr::write_volatile(reg as *mut u32, v) }
}

impl Uart0 {
    /// The UART, enabled for both directions (`None` the second time).
    pub fn take() -> Option<Self> {
        if TAKEN.swap(true, core::sync::atomic::Ordering::Relaxed) {
            return None;
        }
        write(BAUDDIV, 16);
        write(CTRL, 0b11);
        Some(Self(()))
    }
}

impl ErrorType for Uart0 {
    type Error = Infallible;
}

impl ReadReady for Uart0 {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(read(STATE) & RX_FULL != 0)
    }
}

impl Read for Uart0 {
    /// Blocks until a byte has come (as `embedded-io` asks); the link only
    /// reads after [`ReadReady`] said one is there.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let Some(first) = buf.first_mut() else { return Ok(0) };
        while read(STATE) & RX_FULL == 0 {}
        *first = read(DATA) as u8;
        Ok(1)
    }
}

impl Write for Uart0 {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        for &b in buf {
            while read(STATE) & TX_FULL != 0 {}
            write(DATA, u32::from(b));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while read(STATE) & TX_FULL != 0 {}
        Ok(())
    }
}
