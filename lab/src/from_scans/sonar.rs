//! The ring fired along a lidar run's path, each ping heard off the scans'
//! surfaces through the simulator's own sonar physics
//! ([`crate::simulate::world::Listener`]: the beam pattern, the specular
//! lobe, corners and edges, air absorption, the receiver's threshold and
//! noise, crosstalk and false echoes) and timed by the driver's own plan.
//!
//! Each ray of a ping is heard off the scan nearest in time whose laser
//! saw that ray's way free up to what it hit (or up to the sonar's reach):
//! the world as it was then, people where they stood. A ray no scan saw is
//! not heard; a transducer whose main lobe (±12.7°, the piston's first
//! null) is less than [`MIN_COVERED`] seen makes no reading (the laser
//! does not cover it: the ring's rear half, mostly).

use crate::simulate::world::{
    point_key, wrap, Beam, Draws, EchoKind, EchoSource, FiringPlan, Listener, FAN_HALF_DEG, RAY_STEP_DEG,
};

use super::harsh::{Harsh, Posts, POST_LOSS_DB};
use super::surfaces::{Surfaces, P};

/// The main lobe the coverage is judged on, degrees (the first null, DESIGN §6).
pub const MAIN_LOBE_DEG: f64 = 12.7;
/// Least fraction of the main lobe's rays the scans must have seen.
pub const MIN_COVERED: f64 = 0.9;
/// Scans tried for one ray, nearest in time first.
const MAX_TRIES: usize = 40;
/// Scans further than this in time are not tried, s.
const MAX_AGE_S: f64 = 120.0;
/// Steps along a ray at which the laser's view is checked, m.
const SEEN_STEP_M: f64 = 0.1;
/// The part of a ray before its hit that need not be seen, m (the hit's own neighbourhood).
const HIT_SLACK_M: f64 = 0.05;

/// Scans sorted by time, and the sonar to hear them with.
pub struct Ears<'a> {
    pub surfaces: &'a [Surfaces],
    pub beam: &'a Beam,
    pub plan: &'a FiringPlan,
    pub seed: u64,
    /// Whether a ray mirrored by a face may come back off a second one
    /// (multipath: the long readings a sonar gives along a wall).
    pub multipath: bool,
    /// How much harsher than DESIGN §4.9's sonar ([`Harsh::NOMINAL`]: not at all).
    pub harsh: Harsh,
    /// What the laser plane missed ([`Posts::none`] unless harsh).
    pub posts: &'a Posts,
}

/// One ping's outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ping {
    /// The echo time as the driver's clock counts it, and what made it.
    pub echo_us: Option<u32>,
    pub source: EchoSource,
    /// The fraction of the main lobe's rays some scan saw.
    pub covered: f64,
}

impl Ears<'_> {
    /// Scans in order of their distance in time from `t`.
    fn nearest(&self, t: f64) -> Vec<usize> {
        let s = self.surfaces;
        let mut hi = s.partition_point(|x| x.time_s < t);
        let mut lo = hi;
        let mut out = Vec::with_capacity(MAX_TRIES);
        while out.len() < MAX_TRIES {
            let before = lo.checked_sub(1).filter(|&i| t - s[i].time_s <= MAX_AGE_S);
            let after = (hi < s.len() && s[hi].time_s - t <= MAX_AGE_S).then_some(hi);
            match (before, after) {
                (Some(b), Some(a)) => {
                    if t - s[b].time_s <= s[a].time_s - t {
                        out.push(b);
                        lo = b;
                    } else {
                        out.push(a);
                        hi += 1;
                    }
                }
                (Some(b), None) => {
                    out.push(b);
                    lo = b;
                }
                (None, Some(a)) => {
                    out.push(a);
                    hi += 1;
                }
                (None, None) => break,
            }
        }
        out
    }

    /// Ping number `index` at time `t` from a transducer at `o` facing `axis` (rad).
    pub fn ping(&self, index: u64, t: f64, o: P, axis: f64) -> Ping {
        let draws = Draws::new(self.seed, index, self.plan);
        let mut ear = Listener::new(self.beam, &draws, self.plan, o, axis);
        let rmax = self.beam.max_range(self.plan);
        let cands = self.nearest(t);
        let rays: Vec<(P, usize)> = ear.rays().collect();
        // A less sensitive receiver: every echo this much weaker.
        let deaf = self.harsh.threshold_db;
        // Per ray: the scan that saw it, and its hit there.
        let mut chosen: Vec<Option<(usize, Option<super::surfaces::SurfaceHit>)>> = vec![None; rays.len()];
        let (mut lobe, mut lobe_seen) = (0usize, 0usize);
        for (&(d, i), slot) in rays.iter().zip(chosen.iter_mut()) {
            for &k in &cands {
                let s = &self.surfaces[k];
                let hit = s.cast(o, d, rmax);
                let until = hit.map_or(rmax, |h| h.r - HIT_SLACK_M);
                if s.seen_free_along(o, d, SEEN_STEP_M / 2.0, until, SEEN_STEP_M) {
                    *slot = Some((k, hit));
                    break;
                }
            }
            let off = ray_angle(i);
            if off.abs() <= MAIN_LOBE_DEG {
                lobe += 1;
                lobe_seen += usize::from(slot.is_some());
            }
        }
        for (&(d, i), c) in rays.iter().zip(&chosen) {
            if let Some((k, Some(h))) = *c {
                let s = &self.surfaces[k];
                ear.hear_face(
                    i,
                    d,
                    h.r,
                    h.normal,
                    s.key ^ (u64::from(h.surface) << 20),
                    deaf,
                    EchoSource::World { kind: EchoKind::Face },
                );
                // Multipath: the ray mirrored by this face, heard back off a
                // second face it meets square enough, along the same way
                // back (a two-bounce echo, as long as both legs together).
                if self.multipath {
                    let dn = d.0 * h.normal.0 + d.1 * h.normal.1;
                    let m = (d.0 - 2.0 * dn * h.normal.0, d.1 - 2.0 * dn * h.normal.1);
                    let at = (o.0 + d.0 * h.r + m.0 * 0.01, o.1 + d.1 * h.r + m.1 * 0.01);
                    if let Some(h2) = s.cast(at, m, rmax - h.r) {
                        ear.hear_face(
                            i,
                            m,
                            h.r + 0.01 + h2.r,
                            h2.normal,
                            s.key ^ (u64::from(h2.surface) << 20) ^ 0xB0,
                            self.harsh.bounce_loss_db + deaf,
                            EchoSource::World { kind: EchoKind::Face },
                        );
                    }
                }
            }
        }
        // Corners and edges of the scans heard, where the ray at their
        // bearing saw that scan and nothing nearer.
        let mut heard: Vec<usize> = chosen.iter().filter_map(|c| c.map(|c| c.0)).collect();
        heard.sort_unstable();
        heard.dedup();
        let capture = |r: f64| 0.03f64.max(r * RAY_STEP_DEG.to_radians());
        for k in heard {
            for pe in &self.surfaces[k].points {
                let v = pe.at;
                let Some((rv, j)) = in_fan(o, axis, v, rmax) else { continue };
                let visible = match chosen.get(j).copied().flatten() {
                    Some((kk, h)) => kk == k && h.is_none_or(|h| h.r >= rv - capture(rv)),
                    None => false,
                };
                if !visible {
                    continue;
                }
                if let Some((term, kind)) = Listener::point_term(pe.wedge_deg, rv) {
                    ear.hear_point(v, term - deaf, point_key(v), EchoSource::World { kind });
                }
            }
        }
        // Posts the laser missed, where the ray at their bearing saw some
        // scan at least as far (behind a nearer surface they are not heard).
        for v in self.posts.near(o, rmax) {
            let Some((rv, j)) = in_fan(o, axis, v, rmax).filter(|&(rv, _)| rv > 0.0) else { continue };
            let open = match chosen.get(j).copied().flatten() {
                Some((_, h)) => h.is_none_or(|h| h.r >= rv),
                None => false,
            };
            if open {
                let term = -POST_LOSS_DB - 20.0 * rv.max(0.1).log10() - deaf;
                ear.hear_point(v, term, point_key(v) ^ 0x9057, EchoSource::Unmapped);
            }
        }
        let (echo_us, source) = ear.reading(self.plan);
        Ping { echo_us, source, covered: if lobe == 0 { 0.0 } else { lobe_seen as f64 / lobe as f64 } }
    }
}

/// A point reflector at `v` heard from `o` facing `axis`: its range and the
/// fan's ray at its bearing, if it is within `rmax` and the fan.
fn in_fan(o: P, axis: f64, v: P, rmax: f64) -> Option<(f64, usize)> {
    let rv = (v.0 - o.0).hypot(v.1 - o.1);
    let th = wrap((v.1 - o.1).atan2(v.0 - o.0) - axis).to_degrees();
    (rv <= rmax && th.abs() <= FAN_HALF_DEG).then(|| (rv, ((th + FAN_HALF_DEG) / RAY_STEP_DEG).round() as usize))
}

/// The angle of ray `i` off the axis, degrees (the simulator's fan).
fn ray_angle(i: usize) -> f64 {
    -FAN_HALF_DEG + i as f64 * RAY_STEP_DEG
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::from_scans::surfaces::Surfaces;
    use crate::lidar::Scan;

    /// A laser at the origin facing +x, 361 beams over 180°, in the room
    /// x ≤ 2, y ≤ 2: the distance along each bearing, from the geometry.
    fn room() -> Surfaces {
        scanned(&[((2.0, -20.0), (2.0, 2.0)), ((-20.0, 2.0), (2.0, 2.0))])
    }

    /// The range each of 20 pings of a transducer at `o` facing `deg` reads, mm.
    fn pings(s: &[Surfaces], o: P, deg: f64) -> Vec<(Option<u32>, f64)> {
        let plan = FiringPlan::new(1, None).unwrap();
        let beam = Beam::new(20.0, 50.0).with_specular_width(2.8);
        let ears = Ears {
            surfaces: s,
            beam: &beam,
            plan: &plan,
            seed: 7,
            multipath: false,
            harsh: Harsh::NOMINAL,
            posts: &Posts::none(),
        };
        (0..20)
            .map(|k| {
                let p = ears.ping(k, 0.0, o, deg.to_radians());
                (p.echo_us.map(|u| plan.range_mm(u)), p.covered)
            })
            .collect()
    }

    #[test]
    fn a_wall_is_heard_at_its_perpendicular_range_and_a_corner_at_its_own() {
        let s = [room()];
        // Facing the wall x = 2: 2 m, to a few centimetres (the envelope's rise, noise).
        for (r, covered) in pings(&s, (0.0, 0.0), 0.0) {
            assert_eq!(covered, 1.0);
            let r = r.expect("the wall ahead echoes");
            // Range noise: 5 mm + 0.5 % (σ 15 mm at 2 m); an echo is timed late by its rise.
            assert!((1950..2080).contains(&r), "{r}");
        }
        // Facing the inside corner (2, 2): 2.83 m, a retro-reflection; the
        // walls' perpendicular feet are 45° off the axis, beyond the fan.
        let heard: Vec<u32> = pings(&s, (0.0, 0.0), 45.0).into_iter().filter_map(|p| p.0).collect();
        assert!(heard.len() >= 18, "{heard:?}");
        assert!(heard.iter().all(|&r| (2800..2900).contains(&r)), "{heard:?}");
    }

    /// A laser at the origin facing +x over 180°, among `walls` (its reach 10 m).
    fn scanned(walls: &[(P, P)]) -> Surfaces {
        let ranges = (0..361)
            .map(|i| {
                let b = (-90.0 + 0.5 * f64::from(i)).to_radians();
                let d = (b.cos(), b.sin());
                walls
                    .iter()
                    .filter_map(|&(a, c)| crate::bench::brute::ray_cross((0.0, 0.0), d, a, c))
                    .map(|p| p.0.hypot(p.1))
                    .filter(|&t| t > 0.0 && t < 10.0)
                    .fold(f64::INFINITY, f64::min) as f32
            })
            .collect();
        let scan = Scan::taken_at([0.0; 3], -std::f64::consts::FRAC_PI_2, 0.5f64.to_radians(), ranges);
        Surfaces::of_scan(&scan, 0.0, 1, &|_| true)
    }

    #[test]
    fn a_face_mirrors_the_ping_onto_another_a_long_reading() {
        // A wall y = 1 met at 45° (too far off its normal to echo), whose
        // mirror sends the ping square onto a wall 2 m on: with multipath the
        // transducer facing 45° reads both legs, √2 + 2 m; without, nothing
        // of either wall comes back.
        let m = (std::f64::consts::FRAC_1_SQRT_2, -std::f64::consts::FRAC_1_SQRT_2);
        let at = (1.0 + 2.0 * m.0, 1.0 + 2.0 * m.1);
        let along = (-m.1, m.0);
        let b = ((at.0 - 0.5 * along.0, at.1 - 0.5 * along.1), (at.0 + 0.5 * along.0, at.1 + 0.5 * along.1));
        let s = [scanned(&[((-1.0, 1.0), (10.0, 1.0)), b])];
        let plan = FiringPlan::new(1, None).unwrap();
        let beam = Beam::new(20.0, 50.0).with_specular_width(2.8);
        let read = |multipath: bool| -> Vec<Option<u32>> {
            let ears = Ears {
                surfaces: &s,
                beam: &beam,
                plan: &plan,
                seed: 3,
                multipath,
                harsh: Harsh::NOMINAL,
                posts: &Posts::none(),
            };
            (0..20)
                .map(|k| ears.ping(k, 0.0, (0.0, 0.0), 45f64.to_radians()).echo_us.map(|u| plan.range_mm(u)))
                .collect()
        };
        let want = 2f64.sqrt() + 2.0;
        let with: Vec<u32> = read(true).into_iter().flatten().collect();
        assert!(with.len() >= 18, "{with:?}");
        assert!(with.iter().all(|&r| (f64::from(r) / 1000.0 - want).abs() < 0.08), "{with:?} against {want}");
        // Without: only the odd false echo or crosstalk, never at that range.
        assert!(
            read(false).into_iter().flatten().filter(|&r| (f64::from(r) / 1000.0 - want).abs() < 0.08).count() <= 1
        );
    }

    #[test]
    fn what_the_laser_did_not_see_is_not_covered() {
        let s = [room()];
        // Behind the laser: no scan saw that way.
        assert!(pings(&s, (0.0, 0.0), 180.0).iter().all(|p| p.1 == 0.0 && p.0.is_none()));
        // Beside it, half the lobe is behind the laser's field.
        let half = pings(&s, (0.0, 0.0), 90.0)[0].1;
        assert!(half > 0.3 && half < 0.7, "{half}");
    }
}
