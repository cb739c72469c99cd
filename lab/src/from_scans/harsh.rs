//! A harsher sonar for the conversion (`simulate --from-scans --sonar
//! harsh`, issue #49 item 2): what a Polaroid ring in a furnished building
//! does that the nominal derivation does not, each part its own knob so its
//! effect can be measured alone (`--harsh-without PART`):
//!
//! - **threshold**: a less sensitive receiver (absorbing furnishings, a
//!   lower gain): every echo `threshold_db` weaker against the threshold,
//!   so a face is heard only at a smaller incidence and a shorter range
//!   ([`Harsh::face_level_db`] says by how much);
//! - **mirror**: a two-bounce echo loses nothing at its first bounce (glass,
//!   metal, smooth paint): the long phantom readings along mirror pairs come
//!   back as strongly as a face seen square;
//! - **crosstalk**: a neighbour's ping heard first: with probability
//!   `crosstalk` a firing's neighbour (either side, at random) has fired at
//!   the same moment, and its echo off what its own axis meets reaches this
//!   transducer after the two legs ([`crosstalk_range_m`]);
//! - **furniture**: what a laser plane misses (table tops, chair legs, a
//!   bin): posts standing in space the laser saw free, 0.15-0.6 m in front of
//!   what it saw, `furniture_per_m` for every metre of path, heard as point
//!   reflectors ([`POST_LOSS_DB`]) and never in the map.
//!
//! None of it reads the map the run is checked against (DESIGN §4.7): the
//! posts are placed from the scans alone.

use clap::ValueEnum;

use crate::credence::rng::Rng;
use crate::lidar::Scan;
use crate::simulate::world::Beam;

use super::surfaces::P;

/// Which sonar derives the readings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Sonar {
    /// The simulator's Polaroid physics over the scans (DESIGN §4.9).
    Nominal,
    /// [`Harsh::HARSH`]: calibrated so the shared buildings confirm 3-8 % of readings.
    Harsh,
}

/// A part of the harsh setting, to leave out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Part {
    Threshold,
    Mirror,
    Crosstalk,
    Furniture,
}

/// The harsh parts' settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Harsh {
    /// Every echo this much weaker against the threshold, dB.
    pub threshold_db: f64,
    /// Loss at a two-bounce echo's first bounce, dB.
    pub bounce_loss_db: f64,
    /// Probability that a neighbour fired with this transducer.
    pub crosstalk: f64,
    /// Unseen posts per metre of path.
    pub furniture_per_m: f64,
}

/// Loss of a mirror bounce on the way of a two-bounce echo in the nominal
/// sonar, dB. *Model assumption*: a painted wall reflects nearly all of a
/// 49 kHz ping.
pub const BOUNCE_LOSS_DB: f64 = 1.0;
/// Loss of a post (a chair leg, a table's edge below the laser) against a
/// face at normal incidence at 1 m, dB; it falls off as a point target
/// (20·log₁₀ r more). *Model assumption*: a leg 2-4 cm across is a weak
/// cylinder, a table's edge stronger; between an outside edge (20 dB) and
/// a person (6 dB).
pub const POST_LOSS_DB: f64 = 12.0;
/// Posts stand this far in front of what the laser saw, m.
pub const POST_IN_FRONT_M: (f64, f64) = (0.15, 0.6);
/// ... of returns at most this far from the laser, m (furniture is seen near).
const POST_SEEN_WITHIN_M: f64 = 5.0;
/// Sub-stream of the posts' draws.
const STREAM_POSTS: u64 = 0x5C_0004;
/// Sub-stream of the crosstalk draws (per firing: `+ index << 8`).
pub const STREAM_CROSSTALK: u64 = 0x5C_0005;

impl Harsh {
    /// The nominal derivation: nothing harsher than DESIGN §4.9's sonar.
    pub const NOMINAL: Harsh =
        Harsh { threshold_db: 0.0, bounce_loss_db: BOUNCE_LOSS_DB, crosstalk: 0.0, furniture_per_m: 0.0 };
    /// The harsh setting, calibrated on Intel, ACES and Freiburg 079
    /// (docs/real-buildings.md, "A harsher sonar").
    pub const HARSH: Harsh = Harsh { threshold_db: 30.0, bounce_loss_db: 0.0, crosstalk: 0.15, furniture_per_m: 8.0 };

    /// The setting of `sonar` without the parts in `without`.
    pub fn of(sonar: Sonar, without: &[Part]) -> Harsh {
        let mut h = match sonar {
            Sonar::Nominal => return Harsh::NOMINAL,
            Sonar::Harsh => Harsh::HARSH,
        };
        for p in without {
            match p {
                Part::Threshold => h.threshold_db = Harsh::NOMINAL.threshold_db,
                Part::Mirror => h.bounce_loss_db = Harsh::NOMINAL.bounce_loss_db,
                Part::Crosstalk => h.crosstalk = Harsh::NOMINAL.crosstalk,
                Part::Furniture => h.furniture_per_m = Harsh::NOMINAL.furniture_per_m,
            }
        }
        h
    }

    /// Checks the values; the message names the field.
    pub fn check(&self) -> Result<(), String> {
        let ok = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
        if !ok(self.threshold_db, 0.0, 60.0) {
            return Err(format!("harsh threshold {} dB: expected 0 to 60", self.threshold_db));
        }
        if !ok(self.bounce_loss_db, 0.0, 60.0) {
            return Err(format!("harsh bounce loss {} dB: expected 0 to 60", self.bounce_loss_db));
        }
        if !ok(self.crosstalk, 0.0, 1.0) {
            return Err(format!("harsh crosstalk {}: expected a probability, 0 to 1", self.crosstalk));
        }
        if !ok(self.furniture_per_m, 0.0, 100.0) {
            return Err(format!("harsh furniture {} per m: expected 0 to 100", self.furniture_per_m));
        }
        Ok(())
    }

    /// Level above the (harsh) threshold of a face `r` m away, on the beam's
    /// axis, met at `incidence_deg` off its normal, before the noise, dB.
    pub fn face_level_db(&self, beam: &Beam, r: f64, incidence_deg: f64) -> f64 {
        beam.face_level_db(r, 0.0, incidence_deg) - self.threshold_db
    }

    /// The widest incidence at which a face at 1 m on the axis is heard
    /// (noise aside), degrees.
    pub fn widest_heard_at_1m_deg(&self, beam: &Beam) -> f64 {
        beam.widest_heard_deg(beam.face_level_db(1.0, 0.0, 0.0) - self.threshold_db)
    }
}

/// The range a transducer at `o` reads off its neighbour's ping, fired at
/// the same moment from `o_j` and met at `r_j` m along its axis `axis_j`
/// (rad): the two legs, out to the hit and back to `o`, halved as the
/// driver halves every time of flight, m.
pub fn crosstalk_range_m(o: P, o_j: P, axis_j: f64, r_j: f64) -> f64 {
    let h = (o_j.0 + r_j * axis_j.cos(), o_j.1 + r_j * axis_j.sin());
    (r_j + (h.0 - o.0).hypot(h.1 - o.1)) / 2.0
}

/// Posts the laser never saw, in a grid of square buckets for lookup.
pub struct Posts {
    at: Vec<P>,
    cell_m: f64,
    origin: (i64, i64),
    size: (i64, i64),
    /// Per bucket, the posts' indices.
    buckets: Vec<Vec<u32>>,
}

/// Side of a bucket, m.
const BUCKET_M: f64 = 1.0;

impl Posts {
    /// No posts.
    pub fn none() -> Self {
        Self { at: Vec::new(), cell_m: BUCKET_M, origin: (0, 0), size: (0, 0), buckets: Vec::new() }
    }

    /// About `per_m · path_m` posts, each in front of a return of a scan
    /// drawn at random, seeded `seed`.
    pub fn place(scans: &[Scan], path_m: f64, per_m: f64, seed: u64) -> Self {
        let want = (per_m * path_m).round() as usize;
        if want == 0 || scans.is_empty() {
            return Self::none();
        }
        let mut rng = Rng::substream(seed, STREAM_POSTS);
        let mut at = Vec::with_capacity(want);
        let mut tries = 0usize;
        while at.len() < want && tries < 20 * want {
            tries += 1;
            let s = &scans[(rng.next_u64() % scans.len() as u64) as usize];
            if s.ranges.is_empty() {
                continue;
            }
            let i = (rng.next_u64() % s.ranges.len() as u64) as usize;
            let r = f64::from(s.ranges[i]);
            let back = rng.uniform(POST_IN_FRONT_M.0, POST_IN_FRONT_M.1);
            if !(r.is_finite() && r <= POST_SEEN_WITHIN_M && r > back + 0.3) {
                continue;
            }
            let a = s.laser[2] + s.bearing(i);
            at.push((s.laser[0] + (r - back) * a.cos(), s.laser[1] + (r - back) * a.sin()));
        }
        Self::index(at)
    }

    /// Posts at `at`, indexed.
    pub fn index(at: Vec<P>) -> Self {
        if at.is_empty() {
            return Self::none();
        }
        let key = |v: f64| (v / BUCKET_M).floor() as i64;
        let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
        for p in &at {
            let (x, y) = (key(p.0), key(p.1));
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
        let size = (hi.0 - lo.0 + 1, hi.1 - lo.1 + 1);
        let mut buckets = vec![Vec::new(); (size.0 * size.1) as usize];
        for (k, p) in at.iter().enumerate() {
            let (x, y) = (key(p.0) - lo.0, key(p.1) - lo.1);
            buckets[(y * size.0 + x) as usize].push(k as u32);
        }
        Self { at, cell_m: BUCKET_M, origin: lo, size, buckets }
    }

    /// How many.
    pub fn len(&self) -> usize {
        self.at.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.at.is_empty()
    }

    /// The posts within `r` m of `o` (and perhaps a few more).
    pub fn near(&self, o: P, r: f64) -> impl Iterator<Item = P> + '_ {
        let key = |v: f64| (v / self.cell_m).floor() as i64;
        let (x0, x1) = ((key(o.0 - r) - self.origin.0).max(0), (key(o.0 + r) - self.origin.0).min(self.size.0 - 1));
        let (y0, y1) = ((key(o.1 - r) - self.origin.1).max(0), (key(o.1 + r) - self.origin.1).min(self.size.1 - 1));
        (y0..=y1)
            .flat_map(move |y| (x0..=x1).map(move |x| (x, y)))
            .flat_map(move |(x, y)| self.buckets[(y * self.size.0 + x) as usize].iter())
            .map(move |&k| self.at[k as usize])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::credence::synth::LEVEL_AT_1M_DB;

    #[test]
    fn a_face_at_its_lobe_width_is_an_amplitude_e_to_the_minus_half_down() {
        // Hand derivation: at 1 m on the axis, absorption (r − 1 = 0) and the
        // gain's spreading (r below full gain) vanish and D²(0) = 1: the level
        // is LEVEL_AT_1M_DB + 20·log₁₀ exp(−α²/2w²) − threshold. At α = w the
        // amplitude is e^(−1/2): 20·log₁₀ e^(−1/2) = −4.343 dB.
        let w = 7.0;
        let beam = Beam::new(20.0, 50.0).with_specular_width(w);
        let h = Harsh { threshold_db: 12.0, ..Harsh::NOMINAL };
        let want = LEVEL_AT_1M_DB - 10.0 / std::f64::consts::LN_10 - 12.0;
        assert!(
            (h.face_level_db(&beam, 1.0, w) - want).abs() < 1e-9,
            "{} against {want}",
            h.face_level_db(&beam, 1.0, w)
        );
        // Square on, nothing but the threshold.
        assert!((h.face_level_db(&beam, 1.0, 0.0) - (LEVEL_AT_1M_DB - 12.0)).abs() < 1e-9);
        // The widest incidence heard: where the lobe has spent the margin,
        // α* = w·√(2·ln 10 / 20 · (L − threshold)).
        let margin = LEVEL_AT_1M_DB - 12.0;
        let widest = w * (2.0 * std::f64::consts::LN_10 / 20.0 * margin).sqrt();
        assert!((h.widest_heard_at_1m_deg(&beam) - widest).abs() < 1e-9);
        assert!(h.face_level_db(&beam, 1.0, widest).abs() < 1e-9);
    }

    #[test]
    fn a_crosstalk_echo_takes_both_legs() {
        // A neighbour 0.1 m to the side, facing the same wall 2 m ahead: its
        // ping meets the wall at (2, 0.1), and comes back to the origin over
        // √(2² + 0.1²) = 2.002498 m: the reading is half of 4.002498 m.
        let r = crosstalk_range_m((0.0, 0.0), (0.0, 0.1), 0.0, 2.0);
        assert!((r - 2.001249).abs() < 1e-6, "{r}");
        // A neighbour at 15° round a ring of radius 0.2 m, both facing out,
        // its wall square 1.5 m beyond its face: the hit at 1.7 m from the
        // centre on its axis; back to the listener at 0.2 m on the x axis.
        let a = 15f64.to_radians();
        let o_j = (0.2 * a.cos(), 0.2 * a.sin());
        let h = (1.7 * a.cos(), 1.7 * a.sin());
        let back = ((h.0 - 0.2).powi(2) + h.1.powi(2)).sqrt();
        let r = crosstalk_range_m((0.2, 0.0), o_j, a, 1.5);
        assert!((r - (1.5 + back) / 2.0).abs() < 1e-12);
        // Law of cosines by hand: back² = 1.7² + 0.2² − 2·1.7·0.2·cos 15°.
        let by_hand = (1.7f64 * 1.7 + 0.04 - 2.0 * 1.7 * 0.2 * a.cos()).sqrt();
        assert!((back - by_hand).abs() < 1e-12);
    }

    #[test]
    fn posts_stand_in_front_of_what_the_laser_saw_and_are_found_near() {
        // A laser at the origin seeing a wall 3 m ahead over ±45°.
        let ranges: Vec<f32> = (0..181)
            .map(|i| {
                let b = (-45.0 + 0.5 * f64::from(i)).to_radians();
                (3.0 / b.cos()) as f32
            })
            .collect();
        let scan = Scan::taken_at([0.0; 3], -std::f64::consts::FRAC_PI_4, 0.5f64.to_radians(), ranges);
        let posts = Posts::place(&[scan], 50.0, 1.0, 9);
        assert_eq!(posts.len(), 50);
        for p in &posts.at {
            // In front of the wall by the drawn distance, within the scan's fan.
            assert!(p.0 > 3.0 - POST_IN_FRONT_M.1 * 1.0001 && p.0 < 3.0 - POST_IN_FRONT_M.0 * 0.70, "{p:?}");
            assert!(p.1.abs() <= p.0 + 1e-9, "{p:?}");
        }
        // `near` finds every post within the radius, against a brute force.
        for o in [(0.0, 0.0), (2.5, 1.0), (3.0, -2.0), (10.0, 0.0)] {
            for r in [0.3, 1.0, 2.5] {
                let mut got: Vec<P> = posts.near(o, r).filter(|p| (p.0 - o.0).hypot(p.1 - o.1) <= r).collect();
                let mut want: Vec<P> = posts.at.iter().copied().filter(|p| (p.0 - o.0).hypot(p.1 - o.1) <= r).collect();
                got.sort_by(|a, b| a.partial_cmp(b).unwrap());
                want.sort_by(|a, b| a.partial_cmp(b).unwrap());
                assert_eq!(got, want, "{o:?} {r}");
            }
        }
        assert!(Posts::place(&[], 50.0, 1.0, 9).is_empty());
    }

    #[test]
    fn the_parts_leave_out_one_at_a_time() {
        let h = Harsh::of(Sonar::Harsh, &[Part::Mirror, Part::Furniture]);
        assert_eq!(h.bounce_loss_db, Harsh::NOMINAL.bounce_loss_db);
        assert_eq!(h.furniture_per_m, 0.0);
        assert_eq!(h.threshold_db, Harsh::HARSH.threshold_db);
        assert_eq!(h.crosstalk, Harsh::HARSH.crosstalk);
        assert_eq!(Harsh::of(Sonar::Nominal, &[]), Harsh::NOMINAL);
        assert!(Harsh { crosstalk: 1.5, ..Harsh::HARSH }.check().is_err());
        assert!(Harsh { threshold_db: f64::NAN, ..Harsh::HARSH }.check().is_err());
        assert!(Harsh::HARSH.check().is_ok());
    }
}
