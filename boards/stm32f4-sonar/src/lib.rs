//! What the STM32F429 sonar controller is made of: the wiring, the 1 MHz
//! clock the driver runs on and its ECHO capture, the host link's serial
//! port, the checked ring timing, the prediction and verdict settings, and
//! the fault and panic handlers. `main.rs` puts them together with the
//! core's controller into the whole loop.
//!
//! # The board
//!
//! An STM32F429ZI (Cortex-M4F, 2 MiB flash, 192 KiB SRAM), as on a
//! NUCLEO-F429ZI: HSE is the ST-LINK's 8 MHz clock output (bypass mode), the
//! core runs at 168 MHz, APB1 at 42 MHz, so TIM2–TIM5 count at 84 MHz before
//! their prescaler. One Polaroid 6500-class ranging module fires a 16-transducer
//! ring through a 1-of-16 analogue multiplexer (the Pioneer ring,
//! `echoloc::predict::PIONEER16`):
//!
//! | signal | pin | notes |
//! |---|---|---|
//! | INIT | PE6, push-pull output | through the module's level shifter; high fires a ping |
//! | BINH | PE7, push-pull output | ends blanking early (raised 1 ms after INIT: nearest range 172 mm) |
//! | ECHO | PA0, TIM5_CH1 (AF2) | open collector with an external pull-up to 3.3 V; the rising edge is captured by TIM5 channel 1 (hardware time stamp on the driver's own clock), handed to `Ring::echo_captured`; the level is read for the driver's stuck-high check and the window's end |
//! | A0..A3 | PE2, PE3, PE4, PE5, push-pull outputs | multiplexer address, `A0` is bit 0 of the transducer index |
//! | clock | TIM5 | 32 bits, prescaled to 1 MHz, free-running over the whole 2³² µs ([`Tim5Clock`]) |
//! | host link | USART3: PD8 TX, PD9 RX, 115 200 baud 8N1 | the ST-LINK's virtual COM port; framed messages (`docs/link.md`) through [`HostPort`] |
//! | log | RTT | `defmt` over the debug probe (`probe-rs run`, `.cargo/config.toml` in this folder) |
//! | LD1 (green) | PB0 | on after a ring cycle in which at least half the judged readings confirmed the map |
//! | LD3 (red) | PB14 | on after a ring cycle that saw an unknown obstacle |
//!
//! Every GPIO of the STM32F4 HAL has the error type `Infallible`, so the
//! driver's pin errors cannot happen here. The address lines are turned into
//! one type by erasing their pin numbers ([`Addr`]), as the driver asks.
//!
//! # Memory
//!
//! The map is the compiled office map, read in place from flash through a
//! `MapView` (validated once at boot): no copy of it in RAM, whatever its
//! size. By `llvm-size -A` on the release build: flash 68 712 bytes
//! (`.text` 58 468, `.rodata` 9 760 with the 2 676-byte map, vector table
//! 428, `.data` 56); static RAM 1 092 bytes (`.data` 56, `.bss` 12, and
//! defmt-rtt's 1 024-byte buffer in `.uninit`). The stack takes the rest of
//! the 192 KiB; the same loop with the host link peaks at 6 456 bytes on the
//! QEMU board (`--bin link`, whole program).
//!
//! Linked with flip-link (`scripts/thumb-link.sh`), the statics sit at the
//! top of RAM and the stack grows down from just below them to
//! `0x2000_0000`: an overflow runs off the bottom of SRAM and faults instead
//! of overwriting them. The stack is painted at reset (cortex-m-rt's
//! `paint-stack`) and the loop logs its high-water mark over defmt every
//! [`STACK_REPORT_CYCLES`] ring cycles ([`stack_high_water`]).
//! `scripts/stack-bound.sh` bounds it statically from the release image
//! built at the workspace root: 35 728 bytes for the whole program with an
//! exception frame and handler on top (13 800 for one reading through the
//! controller, ring-cycle end included), of the 195 512 bytes below the
//! statics (`boards/stack-bounds.txt`).
#![no_std]
#![deny(unsafe_code)]
#![deny(missing_docs)]

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m_rt::{exception, ExceptionFrame};
use echoloc::credence::net::CredenceNet;
use echoloc::driver::{Eeruf, ModuleConfig, Ring, RingConfig, RingTiming, SpeedOfSound, Timing};
use echoloc::predict::PredictParams;
use echoloc::referencing::{VerdictConfig, VerdictCounts};
use echoloc::window::WindowParams;
use stm32f4xx_hal::gpio::{self, Output, PushPull};
use stm32f4xx_hal::pac::TIM5;
use stm32f4xx_hal::rcc::Rcc;
use stm32f4xx_hal::timer::FTimer;

pub use echoloc::driver::Clock;

/// Transducers on the ring.
pub const TRANSDUCERS: usize = 16;
/// Multiplexer address lines: `2^4 = 16` transducers.
pub const ADDRESS_LINES: usize = 4;

/// INIT: PE6.
pub type Init = gpio::PE6<Output<PushPull>>;
/// BINH: PE7.
pub type Binh = gpio::PE7<Output<PushPull>>;
/// ECHO: PA0 in TIM5_CH1, read as a level through [`EchoLevel`].
pub type Echo = EchoLevel;
/// One multiplexer address line: PE2..PE5 with the pin number erased.
pub type Addr = gpio::gpioe::PEn<Output<PushPull>>;
/// The sonar ring of this board, on a shared reference to its clock.
pub type SonarRing<'c> = Ring<Init, Echo, Binh, Addr, &'c Tim5Clock, ADDRESS_LINES, TRANSDUCERS>;

/// Speed of sound: 20.00 °C (a robot with a thermometer would recompute the
/// timing from it).
pub const SOUND: SpeedOfSound = match SpeedOfSound::at_centi_celsius(2000) {
    Ok(s) => s,
    Err(_) => panic!("20 C is a valid temperature"),
};

/// The ranging module: a Polaroid 6500 listening to 5.5 m, with BINH raised
/// 1 ms after INIT. Checked when the firmware is compiled.
pub const MODULE_TIMING: Timing =
    match (ModuleConfig { binh_after_us: Some(1_000), ..ModuleConfig::polaroid_6500(SOUND) }).timing() {
        Ok(t) => t,
        Err(_) => panic!("the module configuration is refused"),
    };

/// The ring: a 5 ms ring-down gap after every listening window, EERUF with a
/// 1 ms step and a 50 mm tolerance. Checked when the firmware is compiled.
pub const RING_TIMING: RingTiming<TRANSDUCERS> =
    match (RingConfig { ring_down_us: 5_000, eeruf: Some(Eeruf { alternating_us: 1_000, tolerance_mm: 50 }) })
        .timing::<TRANSDUCERS>(&MODULE_TIMING)
    {
        Ok(t) => t,
        Err(_) => panic!("the ring configuration is refused"),
    };

/// A free-running microsecond counter on TIM5 (32 bits): the driver's
/// [`Clock`], and the ECHO edge's hardware time stamp.
///
/// The HAL enables and resets TIM5 and sets its prescaler for 1 MHz from the
/// APB1 timer clock; the auto-reload is then the whole 32-bit range, so the
/// count wraps at 2³² µs exactly as [`Clock`] asks (the HAL's own `Counter`
/// cannot: it reloads at `ticks - 1`, which would wrap at 2³² − 1).
///
/// Channel 1 captures the count on ECHO's rising edge (PA0 is TIM5_CH1,
/// alternate function 2), through a 4-sample digital filter at the 84 MHz
/// timer clock (≈ 48 ns: it rejects glitches, not echoes). The stamp is the
/// timer's, taken by hardware at the edge; [`Tim5Clock::take_capture`] hands
/// it to the loop, which passes it to `Ring::echo_captured`.
#[derive(Debug)]
pub struct Tim5Clock {
    tim: TIM5,
}

impl Tim5Clock {
    /// Starts TIM5 counting microseconds from 0, with channel 1 capturing
    /// rising edges. The timer clock must be a whole number of MHz (the HAL
    /// asserts it).
    pub fn start(tim: TIM5, rcc: &mut Rcc) -> Self {
        let tim = FTimer::<TIM5, 1_000_000>::new(tim, rcc).release();
        tim.arr().write(|w| w.arr().set(u32::MAX));
        // CC1 as input from TI1, filter fCK_INT with N = 4 (0b0010).
        tim.ccmr1_input().modify(|_, w| w.cc1s().ti1().ic1f().set(0b0010));
        // Rising edge, capture enabled.
        tim.ccer().modify(|_, w| w.cc1p().clear_bit().cc1np().clear_bit().cc1e().set_bit());
        // The prescaler is buffered: an update event loads it (and zeroes
        // the count) before the counter starts.
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self { tim }
    }

    /// The count latched at ECHO's last rising edge, if one came since the
    /// last call (reading CCR1 clears the flag). An overcapture (a second
    /// edge before this call) keeps the later stamp and clears the flag: it
    /// cannot happen within one ping, where ECHO rises once and stays up
    /// until INIT falls.
    pub fn take_capture(&self) -> Option<u32> {
        let sr = self.tim.sr().read();
        if !sr.cc1if().bit_is_set() {
            return None;
        }
        let stamp = self.tim.ccr1().read().ccr().bits();
        if sr.cc1of().bit_is_set() {
            self.tim.sr().modify(|_, w| w.cc1of().clear());
        }
        Some(stamp)
    }
}

impl Clock for Tim5Clock {
    fn now_us(&self) -> u32 {
        self.tim.cnt().read().cnt().bits()
    }
}

/// ECHO's level for the driver (its stuck-high check before a ping and the
/// end of the listening window), read from GPIOA's input data register:
/// PA0 is in its timer alternate function, where the HAL offers no input
/// pin, but the input data register still samples it.
#[derive(Debug)]
pub struct EchoLevel {
    _pin: gpio::PA0<gpio::Alternate<2>>,
}

impl EchoLevel {
    /// Over PA0 in alternate function 2 (TIM5_CH1).
    pub fn new(pin: gpio::PA0<gpio::Alternate<2>>) -> Self {
        Self { _pin: pin }
    }
}

impl embedded_hal::digital::ErrorType for EchoLevel {
    type Error = core::convert::Infallible;
}

impl embedded_hal::digital::InputPin for EchoLevel {
    fn is_high(&mut self) -> Result<bool, Self::Error> {
        // SAFETY: a read of GPIOA's input data register, which has no side
        // effects; this struct owns PA0, the only bit looked at.
        #[allow(unsafe_code)]
        let idr = unsafe { (*stm32f4xx_hal::pac::GPIOA::ptr()).idr().read().bits() };
        Ok(idr & 1 != 0)
    }

    fn is_low(&mut self) -> Result<bool, Self::Error> {
        self.is_high().map(|h| !h)
    }
}

/// USART3 (PD8 TX, PD9 RX: the NUCLEO's ST-LINK virtual COM port) as the
/// `embedded-io` port the host link runs over. The HAL's own `embedded-io`
/// writer returns `Ok(0)` when the transmitter is busy, which `write_all`
/// takes for a closed line, and it has no reader: this adapter blocks
/// correctly and reads only when a byte is there.
pub struct HostPort {
    serial: stm32f4xx_hal::serial::Serial<stm32f4xx_hal::pac::USART3>,
}

impl core::fmt::Debug for HostPort {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("HostPort(USART3)")
    }
}

impl HostPort {
    /// Over a configured USART3.
    pub fn new(serial: stm32f4xx_hal::serial::Serial<stm32f4xx_hal::pac::USART3>) -> Self {
        Self { serial }
    }
}

/// The port's error: the USART's (framing, noise, overrun, parity).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PortError(pub stm32f4xx_hal::serial::Error);

impl embedded_io::Error for PortError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

impl embedded_io::ErrorType for HostPort {
    type Error = PortError;
}

impl embedded_io::ReadReady for HostPort {
    fn read_ready(&mut self) -> Result<bool, PortError> {
        use stm32f4xx_hal::serial::RxISR;
        Ok(self.serial.is_rx_not_empty())
    }
}

impl embedded_io::Read for HostPort {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, PortError> {
        use embedded_hal_nb::serial::Read;
        let Some(first) = buf.first_mut() else { return Ok(0) };
        *first = nb::block!(self.serial.read()).map_err(PortError)?;
        Ok(1)
    }
}

impl embedded_io::Write for HostPort {
    fn write(&mut self, buf: &[u8]) -> Result<usize, PortError> {
        use embedded_hal_nb::serial::Write;
        for &b in buf {
            nb::block!(Write::write(&mut self.serial, b)).map_err(PortError)?;
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), PortError> {
        use embedded_hal_nb::serial::Write;
        nb::block!(Write::flush(&mut self.serial)).map_err(PortError)
    }
}

/// The window and prediction settings for `map`: MARGE's window (`R_max`
/// 5.5 m, as the module listens) with the map's buffer and face lobe
/// (`WindowParams::with_map_lobe`), exact beacon collection, τ_κ = 0.5, the
/// Polaroid's 30 mm + 1 % tolerance, `R_min` at its blanking.
pub fn predict_params(map: &echoloc::map::MapView<'_>) -> PredictParams {
    use echoloc::map::MapSource;
    PredictParams::new(
        WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::POLAROID_6500 }.with_map_lobe(map.field()),
    )
}

/// The verdict settings of this module: the core's Polaroid defaults with
/// the blanking BINH leaves ([`MODULE_TIMING`]) and a 1 µs clock.
pub const VERDICTS: VerdictConfig =
    VerdictConfig { min_range_mm: MODULE_TIMING.min_range_mm(), ..VerdictConfig::POLAROID };

/// At least half the judged readings of a cycle agreed with the map (and
/// some were judged).
pub fn map_agrees(v: &VerdictCounts) -> bool {
    let agree = v.confirmed + v.nothing_as_predicted;
    v.judged() > 0 && 2 * agree >= v.judged()
}

/// The network the firmware rates predictions with: the shipped quantised
/// 2-10-1 net.
pub const fn credence() -> CredenceNet<'static> {
    CredenceNet::shipped()
}

/// The stack's high-water mark by painting (shared with the QEMU board):
/// cortex-m-rt painted the stack at reset (feature `paint-stack`); linked
/// with flip-link, it runs from just below `.data` down to the start of RAM.
/// `stack_high_water` reads every word from the bottom up to the mark
/// (about 48 000 reads when little is used: under 1 ms at 168 MHz).
pub use stack_paint::{first_unpainted, stack_bounds, stack_high_water};

/// Ring cycles between two reports of the stack's high-water mark.
pub const STACK_REPORT_CYCLES: u32 = 16;

impl defmt::Format for PortError {
    fn format(&self, f: defmt::Formatter<'_>) {
        use stm32f4xx_hal::serial::Error;
        let what = match self.0 {
            Error::Overrun => "overrun",
            Error::FrameFormat => "frame format",
            Error::Parity => "parity",
            Error::Noise => "noise",
            _ => "other",
        };
        defmt::write!(f, "USART3 {=str}", what);
    }
}

/// The program counter of the last HardFault, for a debugger (0: none).
pub static HARDFAULT_PC: AtomicU32 = AtomicU32::new(0);

// SAFETY: cortex-m-rt requires the HardFault handler to be an `unsafe fn`; it
// only stores the stacked PC into an atomic and then parks the core, touching
// no other state.
#[allow(unsafe_code)]
#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    HARDFAULT_PC.store(ef.pc(), Ordering::Relaxed);
    park()
}

/// A panic parks the core with interrupts off. The ranging module is left as
/// it was: a 6500 sends one burst per rising INIT, so an INIT left high sends
/// nothing more. A watchdog (not enabled here) would restart the controller.
///
/// The log names the place and the message when it is a plain string (every
/// `panic!` of this firmware), without `core::fmt`: its calls through
/// function pointers would leave the whole program without a static stack
/// bound (`scripts/stack-bound.sh`), and it costs flash.
///
/// A panic inside the handler (the logger already taken: defmt-rtt panics
/// on re-entry, and so would every log of this handler) parks at once: no
/// recursion until the stack runs out.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    if PANICKING.swap(true, Ordering::Relaxed) {
        park()
    }
    let msg = info.message().as_str().unwrap_or("(a formatted message)");
    match info.location() {
        Some(at) => defmt::error!("panic at {=str}:{=u32}: {=str}", at.file(), at.line(), msg),
        None => defmt::error!("panic: {=str}", msg),
    }
    park()
}

/// Set by the first panic: a second one parks without logging.
static PANICKING: AtomicBool = AtomicBool::new(false);

/// Interrupts off, then sleep for ever.
fn park() -> ! {
    cortex_m::interrupt::disable();
    loop {
        cortex_m::asm::wfi();
    }
}
