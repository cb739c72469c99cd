//! Configuration, checked once into timings the hot path trusts.

use super::error::ConfigError;
use super::sound::SpeedOfSound;

/// The 6500's transmit burst: 16 cycles at 49.4 kHz, µs (rounded up).
pub const TRANSMIT_BURST_US: u32 = 324;
/// The 6500's internal blanking after INIT rises, µs (≈ 0.41 m at 20 °C).
pub const POLAROID_BLANKING_US: u32 = 2_380;
/// Longest maximum range accepted, mm (the 6500 is specified to 10.7 m).
pub const MAX_RANGE_LIMIT_MM: u32 = 11_000;

/// How one ranging module is used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModuleConfig {
    /// Speed of sound for time of flight → range.
    pub sound: SpeedOfSound,
    /// Listen until an echo from this far could have come back, mm; later
    /// (or none) is "no echo".
    pub max_range_mm: u32,
    /// The module's internal blanking after INIT rises, µs: no echo can be
    /// reported before it unless BINH ends it sooner.
    pub blanking_us: u32,
    /// Raise BINH this long after INIT, µs, to end blanking early and see
    /// nearer targets; `None` leaves BINH alone.
    pub binh_after_us: Option<u32>,
}

impl ModuleConfig {
    /// A Polaroid 6500 as shipped: 2.38 ms blanking, no BINH, listening to
    /// 5.5 m (MARGE's `R_max`, DESIGN §5).
    pub const fn polaroid_6500(sound: SpeedOfSound) -> Self {
        Self { sound, max_range_mm: 5_500, blanking_us: POLAROID_BLANKING_US, binh_after_us: None }
    }

    /// Check the configuration and derive its timing.
    pub const fn timing(&self) -> Result<Timing, ConfigError> {
        if self.max_range_mm == 0 || self.max_range_mm > MAX_RANGE_LIMIT_MM {
            return Err(ConfigError::MaxRange);
        }
        let window_us = self.sound.tof_us(self.max_range_mm);
        if self.blanking_us >= window_us {
            return Err(ConfigError::Blanking);
        }
        if let Some(b) = self.binh_after_us {
            // Before the burst ends BINH would hear the transmitter itself;
            // at or after blanking ends it changes nothing.
            if b < TRANSMIT_BURST_US || b >= self.blanking_us {
                return Err(ConfigError::Binh);
            }
        }
        Ok(Timing {
            sound: self.sound,
            max_range_mm: self.max_range_mm,
            window_us,
            blanking_us: self.blanking_us,
            binh_after_us: self.binh_after_us,
        })
    }
}

/// A checked [`ModuleConfig`]: what the module runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Timing {
    sound: SpeedOfSound,
    max_range_mm: u32,
    window_us: u32,
    blanking_us: u32,
    binh_after_us: Option<u32>,
}

impl Timing {
    /// The speed of sound.
    pub const fn sound(&self) -> SpeedOfSound {
        self.sound
    }
    /// Maximum range, mm.
    pub const fn max_range_mm(&self) -> u32 {
        self.max_range_mm
    }
    /// Listening window after INIT rises, µs: the time of flight to
    /// `max_range_mm`, rounded up.
    pub const fn window_us(&self) -> u32 {
        self.window_us
    }
    /// Internal blanking, µs.
    pub const fn blanking_us(&self) -> u32 {
        self.blanking_us
    }
    /// When BINH is raised, µs after INIT, if it is.
    pub const fn binh_after_us(&self) -> Option<u32> {
        self.binh_after_us
    }
    /// Nearest range the module can report, mm: blanking (or BINH) in range.
    pub const fn min_range_mm(&self) -> u32 {
        let b = match self.binh_after_us {
            Some(b) => b,
            None => self.blanking_us,
        };
        self.sound.range_mm(b)
    }
}

/// Borenstein and Koren's EERUF: alternating firing delays and the
/// comparison of consecutive readings that rejects crosstalk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Eeruf {
    /// The delay step, µs. In odd cycles slot `j` fires `(j + 1)` steps later
    /// than in even cycles, so any echo caused by another ping moves by at
    /// least one step between two consecutive readings of a transducer.
    pub alternating_us: u32,
    /// Two consecutive readings of one transducer that differ by no more than
    /// this, mm, confirm each other; more is suspected crosstalk.
    pub tolerance_mm: u32,
}

/// How the ring fires.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RingConfig {
    /// Quiet time after a full listening window before the next ping, µs:
    /// lets the last transducer ring down and distant echoes die. The ring
    /// keeps it after every ping, however late the ping fired.
    pub ring_down_us: u32,
    /// Crosstalk rejection; `None` reports every echo as it comes.
    pub eeruf: Option<Eeruf>,
}

impl RingConfig {
    /// Check the configuration for a ring of `N` transducers on a module
    /// with `module` timing, and derive the ring's timing.
    pub const fn timing<const N: usize>(&self, module: &Timing) -> Result<RingTiming<N>, ConfigError> {
        if self.ring_down_us > 1_000_000 {
            return Err(ConfigError::RingDown);
        }
        let (alt_us, tolerance_mm, late_limit_us) = match self.eeruf {
            Some(e) => {
                // The shift an alternating step gives a crosstalk echo must
                // exceed what consecutive true readings may differ by.
                let shift_us = module.sound.tof_us_beyond(e.tolerance_mm);
                if e.alternating_us == 0 || e.alternating_us < shift_us {
                    return Err(ConfigError::AlternatingDelay);
                }
                // Four firings enter one comparison (the reading's own and a
                // crosstalk source's, in two cycles), each late by 0..=L: the
                // shift keeps at least step − 2L, which must still beat the
                // tolerance.
                (e.alternating_us, Some(e.tolerance_mm), (e.alternating_us - shift_us) / 2)
            }
            None => (0, None, 0),
        };
        // Window ≤ 11 m of flight (< 70 ms), ring-down ≤ 1 s, late limit
        // < 2³¹ µs: the u64 sums below cannot overflow, and a cycle that fits
        // 2³¹ µs makes every u32 here fit.
        let slot = module.window_us as u64 + self.ring_down_us as u64 + late_limit_us as u64;
        if slot > i32::MAX as u64 {
            return Err(ConfigError::CycleTooLong);
        }
        let slot_us = slot as u32;
        let per_slot = slot_us as u64 + alt_us as u64;
        let period = per_slot * N as u64;
        if period == 0 || period > i32::MAX as u64 {
            return Err(ConfigError::CycleTooLong);
        }
        Ok(RingTiming { slot_us, alt_us, period_us: period as u32, tolerance_mm, late_limit_us })
    }
}

/// A checked [`RingConfig`] for `N` transducers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RingTiming<const N: usize> {
    slot_us: u32,
    alt_us: u32,
    period_us: u32,
    tolerance_mm: Option<u32>,
    late_limit_us: u32,
}

impl<const N: usize> RingTiming<N> {
    /// Slot length, µs: listening window + ring-down gap + [late
    /// limit](Self::late_limit_us), so that a ping fired up to the late limit
    /// after its time still leaves the whole ring-down gap before the next.
    pub const fn slot_us(&self) -> u32 {
        self.slot_us
    }
    /// How late a slot may fire, µs after its scheduled time, and keep the
    /// schedule: `(step − shift) / 2`, where `shift` is the shortest time of
    /// flight that moves a range by more than the tolerance, so that EERUF
    /// still tells every crosstalk echo from a true one. Without EERUF it is
    /// 0: nothing depends on the pattern, so the ring simply follows a late
    /// firing. A firing later than this moves the schedule on (re-anchors).
    pub const fn late_limit_us(&self) -> u32 {
        self.late_limit_us
    }
    /// EERUF's delay step, µs (0 without EERUF).
    pub const fn alternating_us(&self) -> u32 {
        self.alt_us
    }
    /// One full cycle, µs: `N · (slot + step)`, the same for odd and even
    /// cycles so the cycle rate is steady.
    pub const fn period_us(&self) -> u32 {
        self.period_us
    }
    /// EERUF's tolerance, mm, if EERUF is on.
    pub const fn tolerance_mm(&self) -> Option<u32> {
        self.tolerance_mm
    }
    /// When slot `slot` of cycle `cycle` fires, µs after the cycle-0 start
    /// (wrapping): `cycle·period + slot·slot_us + [cycle odd]·(slot+1)·step`.
    pub const fn fire_offset_us(&self, cycle: u32, slot: usize) -> u32 {
        // Modulo 2³² throughout, `slot` included: every argument has an answer.
        let shift = if cycle % 2 == 1 { (slot as u32).wrapping_add(1).wrapping_mul(self.alt_us) } else { 0 };
        cycle.wrapping_mul(self.period_us).wrapping_add((slot as u32).wrapping_mul(self.slot_us)).wrapping_add(shift)
    }
}
