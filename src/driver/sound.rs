//! The speed of sound in air, and time of flight ↔ range, in integers.
//!
//! `c(T) = 331.3·√(1 + T/273.15)` m/s (DESIGN §5). The driver keeps `c` in
//! µm/s as a `u32` and does every conversion in `u64`, so it needs no FPU
//! (Cortex-M0 builds) and no `libm`.

use super::error::ConfigError;
use crate::geometry::isqrt;

/// c at 0 °C, mm/s.
const C0_MM_PER_S: u64 = 331_300;
/// 0 °C in hundredths of a kelvin.
const ZERO_C_CENTI_K: u64 = 27_315;
/// Round trip µs·(µm/s) → one-way mm: ×1/2 (there and back) ×10⁻⁶ (µs) ×10⁻³ (µm).
const ROUND_TRIP_DIVISOR: u64 = 2_000_000_000;

/// The speed of sound, held in µm/s.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SpeedOfSound {
    um_per_s: u32,
}

impl SpeedOfSound {
    /// Lowest temperature accepted, hundredths of °C.
    pub const MIN_CENTI_CELSIUS: i16 = -4_000;
    /// Highest temperature accepted, hundredths of °C.
    pub const MAX_CENTI_CELSIUS: i16 = 8_500;

    /// The speed of sound at `t` hundredths of a degree Celsius
    /// (`2000` = 20.00 °C, about 343.2 m/s).
    pub const fn at_centi_celsius(t: i16) -> Result<Self, ConfigError> {
        if t < Self::MIN_CENTI_CELSIUS || t > Self::MAX_CENTI_CELSIUS {
            return Err(ConfigError::Temperature);
        }
        // Positive: t ≥ −40 °C, so the kelvin value is ≥ 23 315.
        let tk = (t as i32 + ZERO_C_CENTI_K as i32) as u64;
        // c² = c0²·T_K/273.15 in (mm/s)², at most 3.9·10¹⁵: fits u64. Scale to
        // (µm/s)² after dividing, keeping the remainder, so nothing overflows
        // and the floor is exact.
        let num = C0_MM_PER_S * C0_MM_PER_S * tk;
        let q = num / ZERO_C_CENTI_K;
        let r = num % ZERO_C_CENTI_K;
        let c2 = q * 1_000_000 + r * 1_000_000 / ZERO_C_CENTI_K;
        // √ of at most 1.3·10¹⁷ is below 4·10⁸: fits u32.
        Ok(Self { um_per_s: isqrt(c2) as u32 })
    }

    /// A measured speed of sound, µm/s (for a board that calibrates against
    /// a known target). Must lie in 300 … 400 m/s.
    pub const fn from_um_per_s(um_per_s: u32) -> Result<Self, ConfigError> {
        if um_per_s < 300_000_000 || um_per_s > 400_000_000 {
            return Err(ConfigError::SpeedOfSound);
        }
        Ok(Self { um_per_s })
    }

    /// The speed, µm/s.
    pub const fn um_per_s(self) -> u32 {
        self.um_per_s
    }

    /// One-way range, mm, for a round-trip time of flight of `tof_us`,
    /// rounded to the nearest millimetre.
    pub const fn range_mm(self, tof_us: u32) -> u32 {
        // At most 4.3·10⁹ × 4·10⁸ = 1.7·10¹⁸ < 2⁶⁴; the quotient is < 2³².
        let p = tof_us as u64 * self.um_per_s as u64;
        ((p + ROUND_TRIP_DIVISOR / 2) / ROUND_TRIP_DIVISOR) as u32
    }

    /// The speed as a divisor. It is ≥ 3·10⁸ µm/s by construction; the floor
    /// of 1 only makes divisions by it total, so that no panic path is left
    /// for the compiler to keep (the firmware's panic-never check).
    const fn divisor(self) -> u64 {
        if self.um_per_s == 0 {
            1
        } else {
            self.um_per_s as u64
        }
    }

    /// Round-trip time of flight, µs, to a target `range_mm` away, rounded up
    /// (so a listening window of this length covers the whole range).
    pub const fn tof_us(self, range_mm: u32) -> u32 {
        // At most 4.3·10⁹ × 2·10⁹ = 8.6·10¹⁸ < 2⁶⁴.
        let t = (range_mm as u64 * ROUND_TRIP_DIVISOR).div_ceil(self.divisor());
        if t > u32::MAX as u64 {
            u32::MAX
        } else {
            t as u32
        }
    }

    /// The shortest round-trip time, µs, whose range reads more than
    /// `range_mm` ([`range_mm`](Self::range_mm) rounds to the nearest mm).
    pub const fn tof_us_beyond(self, range_mm: u32) -> u32 {
        // range_mm(t) > r  ⟺  t·c + 10⁹ ≥ (r+1)·2·10⁹  ⟺  t·c ≥ (2r+1)·10⁹.
        // (2r+1)·10⁹ < 8.6·10¹⁸ < 2⁶⁴.
        let t = ((2 * range_mm as u64 + 1) * (ROUND_TRIP_DIVISOR / 2)).div_ceil(self.divisor());
        if t > u32::MAX as u64 {
            u32::MAX
        } else {
            t as u32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_speeds() {
        // 331.3 m/s at 0 °C by definition; 343.21 m/s at 20 °C.
        assert_eq!(SpeedOfSound::at_centi_celsius(0).unwrap().um_per_s(), 331_300_000);
        let c20 = SpeedOfSound::at_centi_celsius(2000).unwrap().um_per_s();
        assert!((343_200_000..343_220_000).contains(&c20), "{c20}");
        assert_eq!(SpeedOfSound::at_centi_celsius(8501), Err(ConfigError::Temperature));
        assert_eq!(SpeedOfSound::at_centi_celsius(-4001), Err(ConfigError::Temperature));
    }

    #[test]
    fn range_and_tof_invert() {
        let c = SpeedOfSound::at_centi_celsius(2000).unwrap();
        for mm in [1u32, 400, 1000, 5500, 10_700] {
            assert_eq!(c.range_mm(c.tof_us(mm)), mm);
        }
        assert_eq!(c.tof_us(u32::MAX), u32::MAX);
    }

    #[test]
    fn tof_beyond_is_the_first_time_past_a_range() {
        for tc in [-4000i16, 0, 2000, 8500] {
            let c = SpeedOfSound::at_centi_celsius(tc).unwrap();
            for mm in [0u32, 1, 50, 51, 172, 5500] {
                let t = c.tof_us_beyond(mm);
                assert!(c.range_mm(t) > mm && (t == 0 || c.range_mm(t - 1) <= mm), "{tc} {mm} {t}");
            }
        }
    }
}
