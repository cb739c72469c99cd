//! What the STM32F429 sonar controller is made of: the wiring, the 1 MHz
//! clock the driver runs on, the checked ring timing, one transducer's
//! prediction, the comparison of a reading with it, and the fault and panic
//! handlers. `main.rs` puts them together.
//!
//! # The board
//!
//! An STM32F429ZI (Cortex-M4F, 2 MiB flash, 192 KiB SRAM), as on a
//! NUCLEO-F429ZI: HSE is the ST-LINK's 8 MHz clock output (bypass mode), the
//! core runs at 168 MHz, APB1 at 42 MHz, so TIM2–TIM5 count at 84 MHz before
//! their prescaler. One Polaroid 6500-class ranging module fires a 16-transducer
//! ring through a 1-of-16 analogue multiplexer (the Pioneer ring,
//! [`PIONEER16`]):
//!
//! | signal | pin | notes |
//! |---|---|---|
//! | INIT | PE6, push-pull output | through the module's level shifter; high fires a ping |
//! | BINH | PE7, push-pull output | ends blanking early (raised 1 ms after INIT: nearest range 172 mm) |
//! | ECHO | PA0, input | open collector with an external pull-up to 3.3 V; PA0 is also TIM5_CH1, so a later revision can capture the edge on the clock's own timer and call `Ring::echo_captured` instead of polling |
//! | A0..A3 | PE2, PE3, PE4, PE5, push-pull outputs | multiplexer address, `A0` is bit 0 of the transducer index |
//! | clock | TIM5 | 32 bits, prescaled to 1 MHz, free-running over the whole 2³² µs ([`Tim5Clock`]) |
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
//! size. Static RAM is 4 bytes (`.bss`); flash 38 744 bytes (`.text` 33 580,
//! `.rodata` 4 736 with the 2 676-byte map, vector table 428), by
//! `llvm-size -A` on the release build. The stack takes the rest of the
//! 192 KiB; the QEMU board measures about 9 KiB for a whole ring cycle
//! (`metric stack_bytes`), which this board's one-transducer prediction
//! ([`expect`]) does not exceed.
#![no_std]
#![deny(unsafe_code)]
#![deny(missing_docs)]

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m_rt::{exception, ExceptionFrame};
use echoloc::credence::net::CredenceNet;
use echoloc::driver::{Eeruf, ModuleConfig, Outcome, Ring, RingConfig, RingTiming, SpeedOfSound, Timing};
use echoloc::map::MapView;
use echoloc::predict::{predict_mount, Pose, PredictError, PredictParams, Prediction, PIONEER16};
use echoloc::referencing::{self, Reading, Verdict, VerdictConfig, VerdictCounts};
use echoloc::window::WindowParams;
use stm32f4xx_hal::gpio::{self, Input, Output, PushPull};
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
/// ECHO: PA0 (TIM5_CH1).
pub type Echo = gpio::PA0<Input>;
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
/// [`Clock`].
///
/// The HAL enables and resets TIM5 and sets its prescaler for 1 MHz from the
/// APB1 timer clock; the auto-reload is then the whole 32-bit range, so the
/// count wraps at 2³² µs exactly as [`Clock`] asks (the HAL's own `Counter`
/// cannot: it reloads at `ticks - 1`, which would wrap at 2³² − 1).
#[derive(Debug)]
pub struct Tim5Clock {
    tim: TIM5,
}

impl Tim5Clock {
    /// Starts TIM5 counting microseconds from 0. The timer clock must be a
    /// whole number of MHz (the HAL asserts it).
    pub fn start(tim: TIM5, rcc: &mut Rcc) -> Self {
        let tim = FTimer::<TIM5, 1_000_000>::new(tim, rcc).release();
        tim.arr().write(|w| w.arr().set(u32::MAX));
        // The prescaler is buffered: an update event loads it (and zeroes
        // the count) before the counter starts.
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self { tim }
    }
}

impl Clock for Tim5Clock {
    fn now_us(&self) -> u32 {
        self.tim.cnt().read().cnt().bits()
    }
}

/// The window and prediction settings for a map buffered by `tb_mm`: MARGE's
/// window (`R_max` 5.5 m, as the module listens), exact beacon collection,
/// τ_κ = 0.5, the Polaroid's 30 mm + 1 % tolerance.
pub fn predict_params(tb_mm: u32) -> PredictParams {
    PredictParams::new(WindowParams { tb_mm, ..WindowParams::MARGE })
}

/// What one transducer should read from one pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Expected {
    /// Not predicted (yet), or the prediction failed: the reading cannot be judged.
    Unknown,
    /// No credible echo within range.
    Nothing,
    /// This echo.
    Echo(Prediction),
}

/// Predicts transducer `transducer` of the Pioneer ring from `pose`. About a
/// sixteenth of a ring prediction: it runs in the ring-down gap before that
/// transducer fires.
pub fn expect(
    map: &MapView<'_>,
    pose: &Pose,
    transducer: u8,
    params: &PredictParams,
    net: &CredenceNet<'_>,
) -> Result<Expected, PredictError> {
    let Some(mount) = PIONEER16.get(usize::from(transducer)) else {
        return Ok(Expected::Unknown);
    };
    let (p, _) = predict_mount(map, pose, mount, params, net)?;
    Ok(p.map_or(Expected::Nothing, Expected::Echo))
}

/// The verdict settings of this module: the core's Polaroid defaults with
/// the blanking BINH leaves ([`MODULE_TIMING`]) and a 1 µs clock.
pub const VERDICTS: VerdictConfig =
    VerdictConfig { min_range_mm: MODULE_TIMING.min_range_mm(), ..VerdictConfig::POLAROID };

/// Compares one ring outcome with what was expected for that transducer
/// (the core's [`echoloc::referencing::judge`]). Only echoes EERUF accepted
/// ([`Outcome::Range`]) and clean no-echoes are judged; an expectation not
/// made yet judges nothing.
pub fn judge(outcome: &Outcome, expected: &Expected) -> Verdict {
    let reading = match *outcome {
        Outcome::Range { range_mm, .. } => Reading::Echo { range_mm },
        Outcome::NoEcho => Reading::NoEcho,
        _ => Reading::Invalid,
    };
    match expected {
        Expected::Unknown => Verdict::Inconclusive,
        Expected::Nothing => referencing::judge(reading, None, &VERDICTS),
        Expected::Echo(p) => referencing::judge(reading, Some(p), &VERDICTS),
    }
}

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
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    park()
}

/// Interrupts off, then sleep for ever.
fn park() -> ! {
    cortex_m::interrupt::disable();
    loop {
        cortex_m::asm::wfi();
    }
}
