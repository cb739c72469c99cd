//! The physical sonar: a fan of `parry2d` rays over the beam, an echo level
//! per hit, and the receiver's first detection after blanking.
//!
//! Level above the detection threshold of an echo from range `r` heard `θ`
//! off the axis, dB (the credence model's, `credence::synth`, with the
//! surface's reflection added):
//!
//! ```text
//! L = M₀ + 20·log₁₀ D²(θ) − 2·a·(r − 1 m) − 20·log₁₀ max(1, r / R_gain) + S + n_surface − n_threshold
//! ```
//!
//! `S` is the surface term: for a flat face hit at incidence `α`, a specular
//! lobe `20·log₁₀ exp(−α² / 2σ²)`; for an inside corner (a free wedge of
//! about 90°) a retro-reflection nearly as strong as normal incidence from
//! any direction; for an outside edge a weak diffraction echo that falls off
//! as a point target; for a person a fixed loss. `n_surface` is drawn per
//! firing and per surface (so the same wall in the true world and in the
//! map's world fluctuates alike), `n_threshold` per firing. A detected echo
//! is timed late by the envelope's rise (a weak one more), then the range
//! noise of the reading is added; the driver's clock truncates it to a
//! whole µs. Crosstalk and false echoes are drawn per firing and compete
//! for the first detection in both worlds alike.

use super::geom::{wrap, P};
use super::run::{EchoKind, EchoSource};
use super::scene::{Hit, Owner, StaticScene, Target};
use super::timing::FiringPlan;
use crate::credence::rng::{mix64, Rng};
use crate::credence::synth::{
    absorption_db_per_m, speed_of_sound, two_way_directivity, BURST_CYCLES, CARRIER_HZ, ENVELOPE_RISE_CYCLES,
    GAIN_FULL_RANGE_M, LEVEL_AT_1M_DB, PISTON_RADIUS_M, PRESSURE_KPA, READING_FLUCTUATION_DB,
};

/// Half the ray fan, degrees: past the piston's second side lobe (29°) and
/// third null (≈ 36°), DESIGN §6; beyond, the beam is 60 dB down two-way.
pub const FAN_HALF_DEG: f64 = 40.0;
/// Angle between rays, degrees: 2.6 cm apart at 3 m, finer than any face.
pub const RAY_STEP_DEG: f64 = 0.5;
/// Width (standard deviation) of the specular lobe in amplitude, degrees.
/// *Model assumption*: painted plaster and wood at λ ≈ 7 mm are smooth with
/// some texture; Kuc & Siegel's measured lobes are about 8–10° wide.
pub const SPECULAR_WIDTH_DEG: f64 = 9.0;
/// Loss of an inside corner's retro-reflection against a face at normal
/// incidence, dB. *Model assumption*: two bounces and a finite aperture.
pub const CORNER_LOSS_DB: f64 = 3.0;
/// Free wedges this close to 90° reflect back like a dihedral corner,
/// degrees. *Model assumption*: a dihedral retro-reflects only near 90°.
pub const CORNER_WEDGE_DEG: (f64, f64) = (60.0, 120.0);
/// Diffraction loss of an outside edge against a face at normal incidence
/// at 1 m, dB; it then falls off as a point target (20·log₁₀ r more).
/// *Model assumption*: Kuc & Siegel's edges are some 20 dB below a plane.
pub const EDGE_LOSS_DB: f64 = 20.0;
/// Free wedges at least this wide are outside edges, degrees.
pub const EDGE_WEDGE_MIN_DEG: f64 = 200.0;
/// A ray's hit within this distance of a vertex hears that vertex, m (or
/// the rays' spacing at the range, if more).
pub const CORNER_CAPTURE_M: f64 = 0.03;
/// Loss of a person against a flat face, dB. *Model assumption*: clothing
/// absorbs and a body is curved; Polaroid rings see people to 3–4 m.
pub const PERSON_LOSS_DB: f64 = 6.0;
/// Receiver noise on the detection threshold per firing, dB (standard
/// deviation). *Model assumption*.
pub const THRESHOLD_NOISE_DB: f64 = 2.0;
/// Range noise, fixed part, m (standard deviation): the threshold crossing
/// jitters by about a carrier cycle (20 µs ≈ 3.5 mm).
pub const RANGE_NOISE_FIXED_M: f64 = 0.005;
/// Range noise, proportional part (standard deviation): air turbulence and
/// temperature gradients along the path.
pub const RANGE_NOISE_FRACTION: f64 = 0.005;
/// Probability that a firing hears another transducer's ping first, at a
/// random time (crosstalk; a ring with EERUF timing still hears some, 1–2 %).
pub const CROSSTALK_PROBABILITY: f64 = 0.015;
/// Rate of false echoes (electrical noise, floor, ultrasonic sources) per
/// second of listening: about 1 % of full windows. *Model assumption*.
pub const FALSE_ECHO_RATE_PER_S: f64 = 0.3;

/// The air and the transducer's beam, fixed for a run.
pub struct Beam {
    /// True speed of sound, m/s.
    pub c: f64,
    /// Air absorption at the carrier, dB/m.
    absorption: f64,
    /// 20·log₁₀ D²(θ) at `θ = −FAN_HALF_DEG + k·TABLE_STEP_DEG`.
    dir_db: Vec<f64>,
    /// The rays: (angle off the axis, rad; index into `dir_db`).
    rays: Vec<(f64, usize)>,
    /// Width of the specular lobe, degrees ([`SPECULAR_WIDTH_DEG`] unless set).
    specular_width_deg: f64,
}

/// Resolution of the directivity table, degrees.
const TABLE_STEP_DEG: f64 = 0.1;

impl Beam {
    /// The beam in air at `temperature_c` and `humidity_pct`.
    pub fn new(temperature_c: f64, humidity_pct: f64) -> Self {
        let c = speed_of_sound(temperature_c);
        let ka = 2.0 * std::f64::consts::PI * CARRIER_HZ * PISTON_RADIUS_M / c;
        let n = libm::round(2.0 * FAN_HALF_DEG / TABLE_STEP_DEG) as usize;
        let dir_db = (0..=n)
            .map(|k| {
                let th = (-FAN_HALF_DEG + k as f64 * TABLE_STEP_DEG).to_radians();
                20.0 * libm::log10(two_way_directivity(ka, th).max(1e-30))
            })
            .collect();
        let per = libm::round(RAY_STEP_DEG / TABLE_STEP_DEG) as usize;
        let rays = (0..=n / per)
            .map(|i| ((-FAN_HALF_DEG + (i * per) as f64 * TABLE_STEP_DEG).to_radians(), i * per))
            .collect();
        Self {
            c,
            absorption: absorption_db_per_m(CARRIER_HZ, temperature_c, humidity_pct, PRESSURE_KPA),
            dir_db,
            rays,
            specular_width_deg: SPECULAR_WIDTH_DEG,
        }
    }

    /// The same beam over faces whose specular lobe is `deg` wide (standard
    /// deviation of the amplitude, degrees): smoother faces than the
    /// simulator's.
    pub fn with_specular_width(mut self, deg: f64) -> Self {
        self.specular_width_deg = deg;
        self
    }

    /// The widest incidence at which a face at normal incidence `margin_db`
    /// above the threshold is still heard, degrees.
    pub fn widest_heard_deg(&self, margin_db: f64) -> f64 {
        self.specular_width_deg * (2.0 * margin_db.max(0.0) * std::f64::consts::LN_10 / 20.0).sqrt()
    }

    /// 20·log₁₀ D²(θ), θ in radians within the fan (interpolated).
    fn dir_at(&self, theta: f64) -> f64 {
        let f = (theta.to_degrees() + FAN_HALF_DEG) / TABLE_STEP_DEG;
        let i = (libm::floor(f).max(0.0) as usize).min(self.dir_db.len() - 2);
        let s = (f - i as f64).clamp(0.0, 1.0);
        self.dir_db[i] * (1.0 - s) + self.dir_db[i + 1] * s
    }

    /// Level above threshold before the surface term and the noise, dB.
    fn base_db(&self, r: f64, dir_db: f64) -> f64 {
        LEVEL_AT_1M_DB + dir_db
            - 2.0 * self.absorption * (r - 1.0)
            - 20.0 * libm::log10((r / GAIN_FULL_RANGE_M).max(1.0))
    }

    /// The specular lobe's term for a face met `incidence_deg` off its normal, dB.
    fn specular_db(&self, incidence_deg: f64) -> f64 {
        let w = self.specular_width_deg;
        -20.0 / std::f64::consts::LN_10 * incidence_deg * incidence_deg / (2.0 * w * w)
    }

    /// Level above the threshold of a flat face `r` m away, `off_axis` rad
    /// off the beam's axis, met `incidence_deg` off its normal, before the
    /// noise, dB (the module's formula).
    pub fn face_level_db(&self, r: f64, off_axis: f64, incidence_deg: f64) -> f64 {
        self.base_db(r, self.dir_at(off_axis)) + self.specular_db(incidence_deg)
    }

    /// Longest one-way path worth tracing for `plan`'s listening window, m.
    pub fn max_range(&self, plan: &FiringPlan) -> f64 {
        self.c * f64::from(plan.window_us()) * 1e-6 / 2.0 + 0.05
    }
}

/// The random draws of one firing, shared by the true world and the map's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Draws {
    key: u64,
    threshold_db: f64,
    range_z: f64,
    /// An extra echo, s after firing, and what made it.
    extra: Option<(f64, EchoSource)>,
}

impl Draws {
    /// The draws of firing number `index` of a run seeded `seed` (its own
    /// sub-stream, so a pilot run that skips firings draws the same).
    pub fn new(seed: u64, index: u64, plan: &FiringPlan) -> Self {
        let mut rng = Rng::substream(seed, STREAM_FIRINGS.wrapping_add(index));
        let key = rng.next_u64();
        let threshold_db = THRESHOLD_NOISE_DB * rng.normal();
        let range_z = rng.normal();
        let (lo, hi) = (f64::from(plan.min_echo_us()) * 1e-6, f64::from(plan.window_us()) * 1e-6);
        let cross = rng.next_f64() < CROSSTALK_PROBABILITY;
        let cross_t = rng.uniform(lo, hi);
        // Waiting time from the end of blanking (earlier noise is not heard).
        let noise_t = lo - libm::log(1.0 - rng.next_f64()) / FALSE_ECHO_RATE_PER_S;
        let extra = match (cross, noise_t < hi) {
            (true, true) if noise_t < cross_t => Some((noise_t, EchoSource::Noise)),
            (true, _) => Some((cross_t, EchoSource::Crosstalk)),
            (false, true) => Some((noise_t, EchoSource::Noise)),
            (false, false) => None,
        };
        Self { key, threshold_db, range_z, extra }
    }

    /// The fluctuation of surface `key` in this firing, dB.
    fn fluctuation(&self, surface: u64) -> f64 {
        let mut r = Rng::new(mix64(self.key ^ mix64(surface.wrapping_add(0x5EED))));
        READING_FLUCTUATION_DB * r.normal()
    }
}

/// Sub-stream numbers of the firings' draws (other streams use small numbers).
const STREAM_FIRINGS: u64 = 1 << 40;

/// Where a ray stopped in one world, and in which scene.
#[derive(Clone, Copy)]
pub struct Surf<'a> {
    /// The hit.
    pub hit: Hit,
    /// The scene of a shape hit (`None` for a person).
    pub scene: Option<&'a StaticScene>,
}

/// The earliest echo detected so far in one world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heard {
    /// When the receiver fires, s after the ping (after the envelope's rise).
    t: f64,
    /// The echo's own range, m.
    r: f64,
    source: EchoSource,
}

/// Collects one world's echoes during one firing.
pub struct Listener<'b> {
    beam: &'b Beam,
    draws: &'b Draws,
    o: P,
    axis: f64,
    blank_s: f64,
    best: Option<Heard>,
}

impl<'b> Listener<'b> {
    /// A listener for a transducer at `o` facing `axis` (rad).
    pub fn new(beam: &'b Beam, draws: &'b Draws, plan: &FiringPlan, o: P, axis: f64) -> Self {
        Self { beam, draws, o, axis, blank_s: f64::from(plan.min_echo_us()) * 1e-6, best: None }
    }

    /// The rays: (unit direction, index).
    pub fn rays(&self) -> impl Iterator<Item = (P, usize)> + '_ {
        self.beam.rays.iter().enumerate().map(move |(i, &(a, _))| {
            let h = self.axis + a;
            ((libm::cos(h), libm::sin(h)), i)
        })
    }

    /// Hears what ray `i` (direction `d`) hit.
    pub fn hear(&mut self, i: usize, d: P, s: Surf<'_>) {
        let h = s.hit;
        match (h.target, s.scene) {
            (Target::Person(p), _) => {
                self.hear_face(i, d, h.r, h.normal, (2 << 32) | p as u64, PERSON_LOSS_DB, EchoSource::Unmapped)
            }
            (Target::Shape(sh), Some(sc)) => {
                let owner = sc.owner(sh);
                self.corners(sc, sh, (self.o.0 + d.0 * h.r, self.o.1 + d.1 * h.r), h.r);
                self.hear_face(i, d, h.r, h.normal, owner.key(), 0.0, source_of(owner, EchoKind::Face));
            }
            (Target::Shape(_), None) => {}
        }
    }

    /// Hears a face that ray `i` (unit direction `d`) met at range `r` with
    /// unit normal `normal`: the specular lobe from the incidence angle,
    /// less `loss_db`; `surface` keys its fluctuation. Any scene's faces
    /// come through here (the simulator's polygons, a lidar run's scans).
    #[allow(clippy::too_many_arguments)]
    pub fn hear_face(&mut self, i: usize, d: P, r: f64, normal: P, surface: u64, loss_db: f64, source: EchoSource) {
        let Some(&(_, k)) = self.beam.rays.get(i) else { return };
        let base = self.beam.base_db(r, self.beam.dir_db[k]);
        let cos_a = -(d.0 * normal.0 + d.1 * normal.1);
        let alpha = libm::acos(cos_a.abs().min(1.0)).to_degrees();
        let specular = self.beam.specular_db(alpha);
        let level = base + specular - loss_db + self.draws.fluctuation(surface) - self.draws.threshold_db;
        self.offer(r, level, source);
    }

    /// Hears a point-like reflector at `v` (an inside corner's
    /// retro-reflection, an outside edge's diffraction): `term_db` against
    /// a face at normal incidence, heard at its own bearing in the beam.
    pub fn hear_point(&mut self, v: P, term_db: f64, key: u64, source: EchoSource) {
        let rv = libm::hypot(v.0 - self.o.0, v.1 - self.o.1);
        let th = wrap(libm::atan2(v.1 - self.o.1, v.0 - self.o.0) - self.axis);
        if th.abs() > FAN_HALF_DEG.to_radians() || rv <= 0.0 {
            return;
        }
        let level = self.beam.base_db(rv, self.beam.dir_at(th)) + term_db + self.draws.fluctuation(key)
            - self.draws.threshold_db;
        self.offer(rv, level, source);
    }

    /// The term of a corner or edge whose free wedge is `wedge_deg` wide,
    /// seen from `rv` m (`None`: it echoes as no point does).
    pub fn point_term(wedge_deg: f64, rv: f64) -> Option<(f64, EchoKind)> {
        if (CORNER_WEDGE_DEG.0..=CORNER_WEDGE_DEG.1).contains(&wedge_deg) {
            Some((-CORNER_LOSS_DB, EchoKind::InsideCorner))
        } else if wedge_deg >= EDGE_WEDGE_MIN_DEG {
            Some((-EDGE_LOSS_DB - 20.0 * libm::log10(rv.max(0.1)), EchoKind::OutsideEdge))
        } else {
            None
        }
    }

    /// Inside corners and outside edges of shape `sh` near the hit point `p`.
    fn corners(&mut self, sc: &StaticScene, sh: usize, p: P, r: f64) {
        let capture = CORNER_CAPTURE_M.max(r * RAY_STEP_DEG.to_radians());
        for (vi, &v) in sc.vertices(sh).iter().enumerate() {
            if libm::hypot(v.0 - p.0, v.1 - p.1) > capture {
                continue;
            }
            let rv = libm::hypot(v.0 - self.o.0, v.1 - self.o.1);
            let th = wrap(libm::atan2(v.1 - self.o.1, v.0 - self.o.0) - self.axis);
            if th.abs() > FAN_HALF_DEG.to_radians() || rv <= 0.0 {
                continue;
            }
            let back = libm::atan2(self.o.1 - v.1, self.o.0 - v.0);
            let Some(wedge) = sc.wedge_deg(sh, vi, back) else { continue };
            let Some((term, kind)) = Self::point_term(wedge, rv) else { continue };
            self.hear_point(v, term, point_key(v), source_of(sc.owner(sh), kind));
        }
    }

    /// An echo from range `r` at `level` dB above threshold: kept if
    /// detected and earlier than the best so far.
    fn offer(&mut self, r: f64, level: f64, source: EchoSource) {
        if level <= 0.0 {
            return;
        }
        let arrive = 2.0 * r / self.beam.c;
        let late = ENVELOPE_RISE_CYCLES / CARRIER_HZ / libm::pow(10.0, level / 20.0);
        let burst = BURST_CYCLES / CARRIER_HZ;
        // Masked by blanking unless the burst still rings when blanking ends.
        let t = if arrive + late >= self.blank_s {
            arrive + late
        } else if arrive + burst > self.blank_s {
            self.blank_s
        } else {
            return;
        };
        if self.best.is_none_or(|b| t < b.t) {
            self.best = Some(Heard { t, r, source });
        }
    }

    /// The reading: time of flight as the driver's µs clock counts it (None
    /// past the listening window), and what made it.
    pub fn reading(&self, plan: &FiringPlan) -> (Option<u32>, EchoSource) {
        let echo = self.best.map(|b| {
            let sigma = RANGE_NOISE_FIXED_M + RANGE_NOISE_FRACTION * b.r;
            // Noise cannot move an echo heard at the end of blanking earlier.
            ((b.t + 2.0 * sigma * self.draws.range_z / self.beam.c).max(self.blank_s), b.source)
        });
        let first = match (echo, self.draws.extra) {
            (Some(e), Some(x)) if x.0 < e.0 => Some(x),
            (Some(e), _) => Some(e),
            (None, x) => x,
        };
        match first {
            Some((t, src)) if t >= self.blank_s => {
                // Whole µs as the driver's clock counts them, never before
                // blanking ends (`blank_s·1e6` can round to a hair below it,
                // and the driver would take that for an echo in blanking).
                let us = libm::floor(t * 1e6).max(f64::from(plan.min_echo_us()));
                if us <= f64::from(plan.window_us()) {
                    (Some(us as u32), src)
                } else {
                    (None, EchoSource::None)
                }
            }
            _ => (None, EchoSource::None),
        }
    }
}

/// The fluctuation key of a point reflector at `v` (m).
pub fn point_key(v: P) -> u64 {
    mix64((libm::round(v.0 * 1000.0) as i64 as u64) ^ mix64(libm::round(v.1 * 1000.0) as i64 as u64))
}

fn source_of(owner: Owner, kind: EchoKind) -> EchoSource {
    match owner {
        Owner::Mapped { obstacle, .. } => EchoSource::Mapped { obstacle, kind },
        Owner::Furniture(_) => EchoSource::Unmapped,
    }
}
