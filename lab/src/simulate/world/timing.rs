//! When each transducer fires, and how the driver times and converts its
//! echo: taken from the core's driver (the same `ModuleConfig`, `RingConfig`
//! and `Schedule` the STM32 board uses), never re-derived.

use echoloc::driver::{Eeruf, ModuleConfig, RingConfig, Schedule, SpeedOfSound, Timing};

use super::config::{WorldError, MAX_TRANSDUCERS};

/// The driver's assumed air temperature, hundredths of °C (the STM32
/// board's `SOUND`: 20.00 °C).
pub const DRIVER_CENTI_CELSIUS: i16 = 2000;
/// Ring-down gap after every listening window, µs (the STM32 board's `RING_TIMING`).
pub const RING_DOWN_US: u32 = 5_000;
/// EERUF: alternating delay step and tolerance (the STM32 board's `RING_TIMING`).
pub const EERUF: Eeruf = Eeruf { alternating_us: 1_000, tolerance_mm: 50 };

/// The ring's firing plan for one run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FiringPlan {
    /// Transducer fired in each slot.
    pub order: Vec<u8>,
    /// One cycle, µs.
    pub period_us: u32,
    /// One slot (listening window, ring-down gap and late limit), µs.
    pub slot_us: u32,
    /// Offset of each slot from its cycle's start, µs: even cycles, odd cycles (EERUF).
    offsets: [Vec<u32>; 2],
    /// The module's timing: listening window, blanking, the driver's speed of sound.
    pub module: Timing,
}

impl FiringPlan {
    /// The plan for `n` transducers, with BINH raised `binh_after_us` after INIT if given.
    pub fn new(n: usize, binh_after_us: Option<u32>) -> Result<Self, WorldError> {
        let err = |e| WorldError::Timing(format!("{e:?}"));
        let sound = SpeedOfSound::at_centi_celsius(DRIVER_CENTI_CELSIUS).map_err(err)?;
        let module = ModuleConfig { binh_after_us, ..ModuleConfig::polaroid_6500(sound) }.timing().map_err(err)?;
        let ring = RingConfig { ring_down_us: RING_DOWN_US, eeruf: Some(EERUF) };
        macro_rules! dispatch {
            ($($n:literal)*) => {
                match n {
                    $($n => plan::<$n>(&ring, &module),)*
                    _ => Err(WorldError::Config(format!("{n} transducers: expected 1 to {MAX_TRANSDUCERS}"))),
                }
            };
        }
        let (order, period_us, slot_us, offsets) = dispatch!(
            1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
            33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59 60 61 62 63 64
        )?;
        Ok(Self { order, period_us, slot_us, offsets, module })
    }

    /// When slot `slot` of cycle `cycle` fires, µs from the run's start
    /// (`cycle·period + offset`, the driver's `fire_offset_us` without its
    /// 32-bit wrap).
    pub fn fire_us(&self, cycle: u32, slot: usize) -> u64 {
        u64::from(cycle) * u64::from(self.period_us) + u64::from(self.offsets[(cycle % 2) as usize][slot])
    }

    /// Earliest echo the module reports, µs after INIT: blanking, or BINH if sooner.
    pub fn min_echo_us(&self) -> u32 {
        self.module.binh_after_us().map_or(self.module.blanking_us(), |b| b.min(self.module.blanking_us()))
    }

    /// The module's listening window, µs: a later echo is "no echo".
    pub fn window_us(&self) -> u32 {
        self.module.window_us()
    }

    /// The driver's range for a time of flight, mm.
    pub fn range_mm(&self, tof_us: u32) -> u32 {
        self.module.sound().range_mm(tof_us)
    }
}

type Plan = (Vec<u8>, u32, u32, [Vec<u32>; 2]);

fn plan<const N: usize>(ring: &RingConfig, module: &Timing) -> Result<Plan, WorldError> {
    let t = ring.timing::<N>(module).map_err(|e| WorldError::Timing(format!("{e:?}")))?;
    let s = Schedule::<N>::spread();
    let order = (0..N).map(|j| s.transducer(j).unwrap_or(0)).collect();
    let offsets = [0u32, 1].map(|c| (0..N).map(|j| t.fire_offset_us(c, j) - c * t.period_us()).collect());
    Ok((order, t.period_us(), t.slot_us(), offsets))
}

#[cfg(test)]
mod tests {
    use super::*;
    use echoloc::driver::RingTiming;

    fn pinned<const N: usize>() {
        let p = FiringPlan::new(N, None).unwrap();
        let module = ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(2000).unwrap()).timing().unwrap();
        let t: RingTiming<N> = RingConfig { ring_down_us: 5_000, eeruf: Some(EERUF) }.timing::<N>(&module).unwrap();
        let s = Schedule::<N>::spread();
        assert_eq!((p.period_us, p.slot_us), (t.period_us(), t.slot_us()));
        for cycle in [0u32, 1, 2, 7, 100] {
            for slot in 0..N {
                assert_eq!(p.fire_us(cycle, slot), u64::from(t.fire_offset_us(cycle, slot)));
                assert_eq!(Some(p.order[slot]), s.transducer(slot));
            }
        }
        assert_eq!(p.min_echo_us(), 2_380);
        assert_eq!(p.window_us(), module.window_us());
    }

    #[test]
    fn plan_is_the_drivers_for_16_and_24() {
        pinned::<16>();
        pinned::<24>();
        assert_eq!(FiringPlan::new(16, None).unwrap().order[1], 3);
        assert_eq!(FiringPlan::new(16, Some(1_000)).unwrap().min_echo_us(), 1_000);
        assert!(FiringPlan::new(65, None).is_err());
    }
}
