//! A physical model of the paper's credence experiment (paper §4.2, DESIGN §6).
//!
//! The paper's Polaroid measurements are not public, so this module runs the
//! experiment on a model: a Polaroid 600-series transducer faces a long smooth
//! wall at range `R` (measured along the wall's normal), turned `θ` off that
//! normal. The wall's specular echo comes back from the foot of the normal,
//! `θ` off the transducer's axis, and is heard through the beam twice
//! (transmit and receive). Each of the 100 readings at a node draws its own
//! amplitude fluctuation and its own false early echo; a reading is *correct*
//! when the first echo detected lies within the range tolerance of `R`.
//!
//! Echo level above the detection threshold, dB:
//!
//! ```text
//! L = M₀ + 20·log₁₀ D²(θ + e) − 2·α(T, RH)·(R − 1 m) − 20·log₁₀ max(1, R / R_gain) + n_day + n_reading
//! ```
//!
//! with `D` the baffled-piston directivity averaged over the burst's spectrum,
//! `α` the ISO 9613-1 absorption, `e` a per-node alignment error, `n_day` the
//! day's noise level and `n_reading` the ping-to-ping fluctuation. The echo is
//! detected when `L > 0`; the receiver crosses its threshold late on a weak
//! echo (the burst's envelope rises over [`ENVELOPE_RISE_CYCLES`]), which costs
//! range. Before the true echo, a false echo (crosstalk, floor, people) may
//! trigger the receiver: a Poisson process of the day's rate, from the end of
//! blanking.
//!
//! Every constant below names its source; the ones marked *model assumption*
//! are not measured values but choices, each with its reason. Every random
//! draw comes from [`Rng`] seeded by the user's seed, and every transcendental
//! function is `libm`'s, so a seed gives the same bytes on every platform.

use std::f64::consts::PI;

use super::rng::Rng;

/// Radius of the transducer's vibrating face, m. DESIGN §6: Polaroid
/// 600-series instrument-grade electrostatic transducer, ka ≈ 17.4 at 49.4 kHz.
pub const PISTON_RADIUS_M: f64 = 0.0192;
/// Carrier frequency, Hz. Polaroid 6500 ranging module: 16 cycles at 49.4 kHz (DESIGN §5).
pub const CARRIER_HZ: f64 = 49_400.0;
/// Cycles in the transmitted burst (Polaroid 6500 ranging module, DESIGN §5).
pub const BURST_CYCLES: f64 = 16.0;
/// Speed of sound at 0 °C, m/s: `c(T) = 331.3·√(1 + T/273.15)` (DESIGN §5).
pub const C0_M_PER_S: f64 = 331.3;
/// 0 °C in kelvin.
pub const ZERO_C_K: f64 = 273.15;
/// Internal blanking after the burst, s (Polaroid 6500: 2.38 ms ≈ 0.4 m, DESIGN §5).
pub const BLANKING_S: f64 = 2.38e-3;
/// Atmospheric pressure for the absorption, kPa (ISO 9613-1 reference pressure; an office near sea level).
pub const PRESSURE_KPA: f64 = 101.325;

/// Echo level above the detection threshold for a wall 1 m away on the axis,
/// dB. *Model assumption*, chosen with [`GAIN_FULL_RANGE_M`] so that the main
/// lobe is heard over the whole 0.5–5.5 m grid, the first side lobe (−35.2 dB
/// two-way) at short and middle range, and the second (−47.6 dB) only close
/// in: the three lobes of the paper's Fig. 8.
pub const LEVEL_AT_1M_DB: f64 = 56.0;
/// Range out to which the receiver's time-varying gain keeps a plane's echo
/// level, m. *Model assumption*: the Polaroid 6500's receiver steps its gain
/// up with time after blanking (DESIGN §6) to a maximum; the step table is not
/// modelled, only its effect: spreading is compensated to here, not beyond.
pub const GAIN_FULL_RANGE_M: f64 = 2.5;
/// Ping-to-ping fluctuation of the echo level, dB (standard deviation).
/// *Model assumption*: air turbulence and the wall's texture; a few dB is
/// what indoor sonar logs show.
pub const READING_FLUCTUATION_DB: f64 = 3.0;
/// Day-to-day spread of the noise level, dB (standard deviation). *Model
/// assumption*: ventilation and machinery differ from day to day.
pub const DAY_NOISE_SPREAD_DB: f64 = 1.5;
/// Alignment error of the transducer at each node and day, degrees
/// (standard deviation). *Model assumption*: the transducer is turned by hand
/// to each grid angle.
pub const ALIGNMENT_ERROR_DEG: f64 = 0.5;
/// Cycles over which the received envelope rises to full amplitude.
/// *Model assumption*: half the burst, as for a transducer of Q ≈ 8; the
/// threshold is crossed `ENVELOPE_RISE_CYCLES / r` cycles late for an echo
/// `r` times the threshold (ranges are calibrated on strong echoes).
pub const ENVELOPE_RISE_CYCLES: f64 = 8.0;
/// Fixed part of the range tolerance, mm. *Model assumption*: the placement
/// error of the transducer on the grid.
pub const TOLERANCE_FIXED_MM: f64 = 10.0;
/// Proportional part of the range tolerance. Polaroid 6500 ranging module:
/// accuracy ±1 % of the reading.
pub const TOLERANCE_FRACTION: f64 = 0.01;
/// Median rate of false early echoes, per second of listening. *Model
/// assumption*: about one reading in six at 5.5 m (32 ms of listening) sees
/// one, as crosstalk from a ring and moving people give indoors.
pub const FALSE_ECHO_RATE_PER_S: f64 = 6.0;
/// Day-to-day spread of the false-echo rate, as the standard deviation of its
/// natural logarithm. *Model assumption*.
pub const FALSE_ECHO_RATE_LOG_SPREAD: f64 = 0.3;
/// Room temperature, °C: the paper kept it at 23 °C (§4.2); days vary by up to ±1 °C (*model assumption*).
pub const TEMPERATURE_C: (f64, f64) = (22.0, 24.0);
/// Relative humidity, %: an indoor range (*model assumption*).
pub const HUMIDITY_PCT: (f64, f64) = (30.0, 60.0);
/// Points over the burst's spectrum at which the directivity is averaged.
const SPECTRUM_POINTS: usize = 9;

/// The experiment's grid and size (paper §4.2).
#[derive(Clone, Copy, Debug)]
pub struct Grid {
    /// Ranges `r0, r0 + step, …`, mm.
    pub r_mm: (u32, u32, u32),
    /// Angles `0, step, …, max`, in tenths of a degree.
    pub theta_decideg: (u32, u32),
    /// Readings per node.
    pub readings: u32,
}

/// The paper's grid: R 500…5500 mm step 250 × θ 0…45° step 2.5°, 100 readings.
pub const PAPER_GRID: Grid = Grid { r_mm: (500, 5500, 250), theta_decideg: (450, 25), readings: 100 };

impl Grid {
    /// Every node, range-major.
    pub fn nodes(&self) -> Vec<(u32, f64)> {
        let (r0, r1, rs) = self.r_mm;
        let (tmax, ts) = self.theta_decideg;
        let mut out = Vec::new();
        for r in (r0..=r1).step_by(rs as usize) {
            for t in (0..=tmax).step_by(ts as usize) {
                out.push((r, f64::from(t) / 10.0));
            }
        }
        out
    }
}

/// One day's conditions.
#[derive(Clone, Debug, PartialEq)]
pub struct Day {
    /// File stem, `day1` …
    pub name: String,
    /// Air temperature, °C.
    pub temperature_c: f64,
    /// Relative humidity, %.
    pub humidity_pct: f64,
    /// Offset of the echo level against the noise, dB (negative: a noisier day).
    pub noise_offset_db: f64,
    /// Rate of false early echoes, per second of listening.
    pub false_echo_rate_per_s: f64,
}

impl Day {
    /// Speed of sound, m/s.
    pub fn speed_of_sound(&self) -> f64 {
        speed_of_sound(self.temperature_c)
    }
    /// Absorption at the carrier, dB/m.
    pub fn absorption_db_per_m(&self) -> f64 {
        absorption_db_per_m(CARRIER_HZ, self.temperature_c, self.humidity_pct, PRESSURE_KPA)
    }
    /// ka at the carrier.
    pub fn ka(&self) -> f64 {
        2.0 * PI * CARRIER_HZ * PISTON_RADIUS_M / self.speed_of_sound()
    }
}

/// One grid node's tally.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// Range along the wall's normal, mm.
    pub r_mm: u32,
    /// Angle off the normal, degrees.
    pub theta_deg: f64,
    /// Readings taken.
    pub readings: u32,
    /// Readings within tolerance of the true range.
    pub correct: u32,
}

/// `c(T)`, m/s (DESIGN §5).
pub fn speed_of_sound(temperature_c: f64) -> f64 {
    C0_M_PER_S * libm::sqrt(1.0 + temperature_c / ZERO_C_K)
}

/// Pure-tone atmospheric absorption, dB/m: ISO 9613-1:1993, equations (3)–(5)
/// and Annex B for the saturation pressure.
pub fn absorption_db_per_m(f_hz: f64, temperature_c: f64, humidity_pct: f64, pressure_kpa: f64) -> f64 {
    const REF_PRESSURE_KPA: f64 = 101.325; // p_r
    const REF_TEMPERATURE_K: f64 = 293.15; // T_0
    const TRIPLE_POINT_K: f64 = 273.16; // T_01
    let t = temperature_c + ZERO_C_K;
    let pa = pressure_kpa / REF_PRESSURE_KPA;
    let c = -6.8346 * libm::pow(TRIPLE_POINT_K / t, 1.261) + 4.6151;
    let p_sat = libm::pow(10.0, c); // relative to p_r
    let h = humidity_pct * p_sat / pa; // molar concentration of water vapour, %
    let fr_o = pa * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h));
    let tr = t / REF_TEMPERATURE_K;
    let fr_n = pa * libm::pow(tr, -0.5) * (9.0 + 280.0 * h * libm::exp(-4.170 * (libm::pow(tr, -1.0 / 3.0) - 1.0)));
    let f2 = f_hz * f_hz;
    8.686
        * f2
        * (1.84e-11 / pa * libm::sqrt(tr)
            + libm::pow(tr, -2.5)
                * (0.01275 * libm::exp(-2239.1 / t) / (fr_o + f2 / fr_o)
                    + 0.1068 * libm::exp(-3352.0 / t) / (fr_n + f2 / fr_n)))
}

/// Baffled circular piston, far field: `D = 2·J₁(ka·sin θ) / (ka·sin θ)`
/// (Kinsler & Frey, *Fundamentals of Acoustics*, §7.4; DESIGN §6).
pub fn piston_directivity(ka: f64, theta_rad: f64) -> f64 {
    let v = ka * libm::sin(theta_rad);
    if v.abs() < 1e-9 {
        1.0
    } else {
        2.0 * libm::j1(v) / v
    }
}

/// Two-way directivity `D²` averaged over the spectrum of the 16-cycle burst
/// (weights sinc² of the burst's spectrum, ±f/16 to its first zeros): the
/// finite bandwidth fills the nulls a little, as on a real transducer.
pub fn two_way_directivity(ka: f64, theta_rad: f64) -> f64 {
    let mut sum = 0.0;
    let mut wsum = 0.0;
    for k in 0..SPECTRUM_POINTS {
        let u = -1.0 + 2.0 * k as f64 / (SPECTRUM_POINTS - 1) as f64; // in units of f/16
        let w = if u == 0.0 { 1.0 } else { (libm::sin(PI * u) / (PI * u)).powi(2) };
        let d = piston_directivity(ka * (1.0 + u / BURST_CYCLES), theta_rad);
        sum += w * d * d;
        wsum += w;
    }
    sum / wsum
}

/// Draws `n` days' conditions from `rng`.
pub fn draw_days(rng: &mut Rng, n: usize) -> Vec<Day> {
    (0..n)
        .map(|i| Day {
            name: format!("day{}", i + 1),
            temperature_c: rng.uniform(TEMPERATURE_C.0, TEMPERATURE_C.1),
            humidity_pct: rng.uniform(HUMIDITY_PCT.0, HUMIDITY_PCT.1),
            noise_offset_db: DAY_NOISE_SPREAD_DB * rng.normal(),
            false_echo_rate_per_s: FALSE_ECHO_RATE_PER_S * libm::exp(FALSE_ECHO_RATE_LOG_SPREAD * rng.normal()),
        })
        .collect()
}

/// The outcome of one reading at a node.
fn reading_is_correct(day: &Day, r_m: f64, level_db_mean: f64, rng: &mut Rng) -> bool {
    let c = day.speed_of_sound();
    let tol_m = (TOLERANCE_FIXED_MM + TOLERANCE_FRACTION * r_m * 1000.0) / 1000.0;
    // The true echo: detected or not, and how late the threshold is crossed.
    let level = level_db_mean + READING_FLUCTUATION_DB * rng.normal();
    let true_echo_m = if level > 0.0 {
        let ratio = libm::pow(10.0, level / 20.0);
        Some(r_m + c / 2.0 * ENVELOPE_RISE_CYCLES / CARRIER_HZ / ratio)
    } else {
        None
    };
    // A false early echo: exponential waiting time after blanking.
    let wait_s = -libm::log(1.0 - rng.next_f64()) / day.false_echo_rate_per_s;
    let false_echo_m = c / 2.0 * (BLANKING_S + wait_s);
    let first = match true_echo_m {
        Some(t) if t <= false_echo_m => t,
        _ => false_echo_m,
    };
    (first - r_m).abs() <= tol_m
}

/// Runs one day of the experiment over `grid`.
pub fn run_day(day: &Day, grid: &Grid, rng: &mut Rng) -> Vec<Node> {
    let ka = day.ka();
    let alpha = day.absorption_db_per_m();
    grid.nodes()
        .into_iter()
        .map(|(r_mm, theta_deg)| {
            let r_m = f64::from(r_mm) / 1000.0;
            let aim_deg = theta_deg + ALIGNMENT_ERROR_DEG * rng.normal();
            let d2 = two_way_directivity(ka, aim_deg.to_radians()).max(1e-30);
            let level = LEVEL_AT_1M_DB + 20.0 * libm::log10(d2)
                - 2.0 * alpha * (r_m - 1.0)
                - 20.0 * libm::log10((r_m / GAIN_FULL_RANGE_M).max(1.0))
                + day.noise_offset_db;
            let correct = (0..grid.readings).filter(|_| reading_is_correct(day, r_m, level, rng)).count() as u32;
            Node { r_mm, theta_deg, readings: grid.readings, correct }
        })
        .collect()
}

/// The generator of day `index` (from 0) of the experiment seeded `seed`.
pub fn day_rng(seed: u64, index: usize) -> Rng {
    Rng::substream(seed, index as u64 + 1)
}

/// The whole experiment: `days` data sets, deterministic for `seed`.
pub fn run(seed: u64, days: usize, grid: &Grid) -> Vec<(Day, Vec<Node>)> {
    let mut rng = Rng::new(seed);
    let conditions = draw_days(&mut rng, days);
    conditions
        .into_iter()
        .enumerate()
        .map(|(i, day)| {
            // Each day its own stream, independent of the conditions' stream
            // and of the other days', so adding days leaves earlier ones alone.
            let nodes = run_day(&day, grid, &mut day_rng(seed, i));
            (day, nodes)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polaroid_constants_match_design() {
        // DESIGN §6: λ ≈ 6.95 mm at 20 °C, ka ≈ 17.4.
        let c = speed_of_sound(20.0);
        assert!((c / CARRIER_HZ * 1000.0 - 6.95).abs() < 0.01);
        let ka = 2.0 * PI * CARRIER_HZ * PISTON_RADIUS_M / c;
        assert!((ka - 17.4).abs() < 0.05, "ka = {ka}");
        // Nulls near 12.7°, 23.8°; side lobes near 17.2° (−17.6 dB) and 29° (−23.8 dB), one way.
        for null in [12.7f64, 23.8] {
            assert!(piston_directivity(ka, null.to_radians()).abs() < 0.01, "null at {null}");
        }
        let db = |deg: f64| 20.0 * piston_directivity(ka, deg.to_radians()).abs().log10();
        assert!((db(17.2) + 17.6).abs() < 0.3, "{}", db(17.2));
        assert!((db(29.0) + 23.8).abs() < 0.5, "{}", db(29.0));
    }

    #[test]
    fn iso_9613_absorption_at_50_khz() {
        // DESIGN §6: about 1.3–2 dB/m at 50 kHz indoors.
        for rh in [30.0, 45.0, 60.0] {
            let a = absorption_db_per_m(CARRIER_HZ, 23.0, rh, PRESSURE_KPA);
            assert!((1.3..=2.0).contains(&a), "rh {rh}: {a}");
        }
    }

    #[test]
    fn bandwidth_fills_the_nulls_but_keeps_the_lobes() {
        let ka = 17.4;
        let null = two_way_directivity(ka, 12.7f64.to_radians());
        let lobe = two_way_directivity(ka, 17.2f64.to_radians());
        assert!(null > 0.0 && null < lobe / 10.0, "{null} {lobe}");
        assert!((two_way_directivity(ka, 0.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn days_draw_from_streams_disjoint_from_each_other_and_the_conditions() {
        // With the former seeding (`seed ^ γ·(day + 1)`), seeds 0 and 1 gave
        // days whose draws were the conditions' stream a few draws on.
        for seed in [0u64, 1] {
            let mut seen = std::collections::HashSet::new();
            let streams = std::iter::once(Rng::new(seed)).chain((0..5).map(|i| day_rng(seed, i)));
            for (k, mut r) in streams.enumerate() {
                for n in 0..50_000 {
                    let v = r.next_u64();
                    assert!(seen.insert(v), "seed {seed}: stream {k} draw {n} repeats an earlier stream's");
                }
            }
        }
        // Adding days leaves the earlier ones alone; the days differ.
        let grid = Grid { r_mm: (500, 1500, 250), theta_decideg: (100, 25), readings: 20 };
        let three = run(0, 3, &grid);
        assert_eq!(run(0, 2, &grid)[..], three[..2]);
        assert!(three[0].1 != three[1].1 && three[1].1 != three[2].1);
    }
}
