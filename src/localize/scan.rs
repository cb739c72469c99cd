//! The search's proposals: a sweep over the field's free nodes, each
//! scored at every one of its headings against the cycle's readings, cheaply
//! enough to cover a depot-sized map in a few cycles; the best go to the
//! particle set as candidates, and the particles' own, exact model judges
//! them over the next cycles.
//!
//! The score of a node at heading bin `b` is the sum over the readings of
//! the beam model's log-likelihood for the byte the field holds at the
//! node nearest the transducer (within two nodes of the robot's node) for
//! the transducer's heading bin: no interpolation, and the hit's variance
//! grown by `extra_sigma_mm` to cover what that costs (a transducer is up
//! to a node's diagonal from the node it is read at). Per reading, the
//! log-likelihood of each of the 256 field bytes is computed once a cycle
//! (in 1/16 nat); per reading and heading bin, the neighbour and the
//! heading bin are too. A node then costs its 25 neighbours' lookups and
//! one table read and add per reading and heading.

use super::beam::BeamModel;
use super::expect::FieldLookup;
use super::particles::Sensed;
use super::{SAME_PLACE_DEG, SAME_PLACE_M};
use crate::f32math::{ln_fast, sin_cos};
use crate::map::field::Expected;
use crate::referencing::Reading;

/// Readings a scan uses (the first ones of the cycle that are not invalid).
pub const SCAN_READINGS: usize = 16;
/// Headings a scan covers: the field's, when it has at most this many.
pub const SCAN_DIRS: usize = 64;
/// Candidates a scan keeps.
pub const SCAN_KEEP: usize = 64;

/// The scan's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScanConfig {
    /// Free nodes scored each cycle (0: no scan).
    pub nodes_per_cycle: u16,
    /// The best this many (at most [`SCAN_KEEP`]) become candidates.
    pub keep: u8,
    /// The hit's σ grows by this (in quadrature), mm.
    pub extra_sigma_mm: f32,
}

impl ScanConfig {
    /// 384 nodes a cycle (a 400 m² map every 17 cycles at 250 mm nodes),
    /// the best 48 kept, hits widened by 150 mm.
    pub const DEFAULT: Self = Self { nodes_per_cycle: 384, keep: 48, extra_sigma_mm: 150.0 };
}

/// A proposal: a pose and its scan score (nats).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Candidate {
    /// x m, y m, φ rad.
    pub pose: [f32; 3],
    /// The scan's log-likelihood.
    pub score: f32,
    /// How many particles it becomes (more once verified on the history).
    pub copies: u16,
}

/// Where the sweep is: the next node, and the stride through the nodes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sweep {
    next: u32,
}

/// The neighbour offsets a transducer may fall on: −2..=2 nodes each way.
const REACH: i32 = 2;
const SIDE: usize = (2 * REACH + 1) as usize;
/// A node's score sums one byte (|·| ≤ 128) per reading: far inside `i32`.
const _SCORE_FITS: () = assert!(SCAN_READINGS as i64 * 128 < i32::MAX as i64);

/// A stride through `n` nodes that visits each once per pass and spreads
/// consecutive visits over the map: a prime near n·0.618 not dividing n.
fn stride(n: u32) -> u32 {
    const PRIMES: [u32; 12] = [7_919, 6_143, 4_099, 3_079, 2_053, 1_543, 1_031, 769, 521, 257, 131, 61];
    let target = (n as u64 * 618 / 1000) as u32;
    PRIMES.iter().copied().find(|&p| p <= target.max(1) && n.checked_rem(p) != Some(0)).unwrap_or(1)
}

impl Sweep {
    /// Scores the next `cfg.nodes_per_cycle` free nodes of the field at
    /// every heading bin against `sensed` and keeps the best `cfg.keep`
    /// in `out` (cleared first), best first. Nothing when the field has
    /// more than [`SCAN_DIRS`] headings, no free node, or no usable reading.
    pub fn scan(
        &mut self,
        sensed: &[Sensed],
        lookup: &FieldLookup<'_, '_>,
        beam: &BeamModel,
        cfg: &ScanConfig,
        out: &mut heapless::Vec<Candidate, SCAN_KEEP>,
    ) {
        out.clear();
        let f = lookup.field();
        let dirs = f.dirs() as usize;
        let nodes = f.nodes();
        if dirs == 0 || dirs > SCAN_DIRS || f.free_nodes() == 0 || cfg.nodes_per_cycle == 0 {
            return;
        }
        let node_mm = f.header().node_mm as f32;
        let keep = usize::from(cfg.keep).min(SCAN_KEEP);
        // Per reading: the log-likelihood of every field byte (1/16 nat),
        // and per heading bin the neighbour and the transducer's heading bin.
        let mut lut = [[0i8; 256]; SCAN_READINGS];
        let mut geo = [[(0u8, 0u8); SCAN_DIRS]; SCAN_READINGS];
        let extra = cfg.extra_sigma_mm * cfg.extra_sigma_mm;
        let mut k = 0usize;
        for r in sensed.iter().filter(|r| r.reading != Reading::Invalid) {
            let (Some(l), Some(g)) = (lut.get_mut(k), geo.get_mut(k)) else { break };
            for (b, v) in l.iter_mut().enumerate() {
                let e = Expected::decode(b as u8);
                let ll = ln_fast(beam.likelihood_with(r.reading, Some(e), extra));
                *v = libm::roundf(ll * 16.0).clamp(-127.0, 127.0) as i8;
            }
            for (b, slot) in g.iter_mut().enumerate().take(dirs) {
                let th = b as f32 * core::f32::consts::TAU / dirs as f32;
                let (s, c) = sin_cos(th);
                let (x, y) = ((c * r.pose[0] - s * r.pose[1]) * 1e3, (s * r.pose[0] + c * r.pose[1]) * 1e3);
                // Clamped again as integers: the compiler sees `nb < 25`.
                let di = (libm::roundf(x / node_mm).clamp(-REACH as f32, REACH as f32) as i32).clamp(-REACH, REACH);
                let dj = (libm::roundf(y / node_mm).clamp(-REACH as f32, REACH as f32) as i32).clamp(-REACH, REACH);
                let nb = ((dj + REACH) * SIDE as i32 + (di + REACH)) as u8;
                let d = libm::roundf((th + r.pose[2]) * dirs as f32 / core::f32::consts::TAU) as i32;
                *slot = (nb, d.checked_rem_euclid(dirs as i32).unwrap_or(0) as u8);
            }
            k += 1;
        }
        if k == 0 {
            return;
        }
        let (lut, geo) = (lut.get(..k).unwrap_or(&[]), geo.get(..k).unwrap_or(&[]));
        let step = stride(nodes);
        // 20° in heading bins.
        let apart = (dirs as f32 * SAME_PLACE_DEG / 360.0) as usize;
        let mut scored = 0u32;
        let mut visited = 0u32;
        // Two lists. The best `keep − keep/3` by score alone (one place's
        // neighbouring nodes crowd it: the refinement wants them); and the
        // best `keep/3` no two within a metre and 20° of each other (the
        // better kept), so that an alias equal to the best place on the
        // readings but a little worse on the node grid is still proposed:
        // without it the verification never sees a rival and hands off to
        // whichever of two identical rooms scored a node higher.
        let n_diverse = keep / 3;
        let mut best = KeptList::new(keep - n_diverse);
        let mut diverse = KeptList::new(n_diverse);
        while scored < u32::from(cfg.nodes_per_cycle) && visited < nodes {
            let n = self.next.checked_rem(nodes).unwrap_or(0);
            // `n + step` past the end wraps to the start (`step ≤ nodes`),
            // written without a sum that could pass `u32::MAX`.
            let to_end = nodes - step.min(nodes);
            // (Below `nodes` in the second case: the sum in u64 is exact.)
            self.next = if n >= to_end { n - to_end } else { (u64::from(n) + u64::from(step)) as u32 };
            visited += 1;
            if !f.is_free(n) {
                continue;
            }
            scored += 1;
            let Some((col, row)) = f.cell_of(n) else { continue };
            // The 5 × 5 neighbours' entries (empty where not stored).
            // (32 places, 25 used: a masked index needs no bounds check.)
            let mut nb: [&[u8]; 32] = [&[]; 32];
            for (j, line) in nb.chunks_mut(SIDE).enumerate() {
                let rr = i64::from(row) + j as i64 - i64::from(REACH);
                if j >= SIDE {
                    break;
                }
                if rr < 0 {
                    continue;
                }
                for (i, e) in line.iter_mut().enumerate() {
                    let cc = i64::from(col) + i as i64 - i64::from(REACH);
                    if cc >= 0 {
                        *e = f.node_at(cc as u32, rr as u32).and_then(|m| f.entries(m)).unwrap_or(&[]);
                    }
                }
            }
            // The node's best heading, and its best one more than 20° from
            // that (a symmetric room's other way round): a node offers at
            // most two proposals, so one place cannot fill the list.
            // Readings outside, headings inside: the inner loop walks three
            // arrays in step, with no bounds checks left but the neighbour's
            // entry (42 k instructions a node on the M4 the other way round).
            let mut scores = [0i32; SCAN_DIRS];
            // A field of SCAN_DIRS headings whose node has all 25
            // neighbours (most nodes: the stored nodes reach 400 mm past
            // the free ones) takes the fast path; both add the same terms.
            let mut whole: [&[u8; SCAN_DIRS]; 32] = [&UNUSED; 32];
            let all =
                nb.iter().take(SIDE * SIDE).zip(whole.iter_mut()).all(|(e, w)| {
                    match <&[u8; SCAN_DIRS]>::try_from(*e) {
                        Ok(a) => {
                            *w = a;
                            true
                        }
                        Err(_) => false,
                    }
                });
            if all {
                add_whole(&mut scores, lut, geo, &whole);
            } else {
                for (l, g) in lut.iter().zip(geo) {
                    for (s, &(nbi, d)) in scores.iter_mut().zip(g.iter()).take(dirs) {
                        // Off the field: as bad as the worst byte, and a little worse.
                        // At most SCAN_READINGS terms of |·| ≤ 128 (`SCORE_FITS`):
                        // the sum never nears i32's limits, so wrapping is exact.
                        *s = s.wrapping_add(match nb[usize::from(nbi) & 31].get(usize::from(d)) {
                            Some(&v) => i32::from(l[usize::from(v)]),
                            None => -128,
                        });
                    }
                }
            }
            let mut top = [(i32::MIN, 0usize); 2];
            for (b, &score) in scores.iter().enumerate().take(dirs) {
                if score > top[0].0 {
                    let far = bins_apart(top[0].1, b, dirs) > apart;
                    if far || top[0].0 == i32::MIN {
                        top[1] = top[0];
                    }
                    top[0] = (score, b);
                } else if score > top[1].0 && bins_apart(top[0].1, b, dirs) > apart {
                    top[1] = (score, b);
                }
            }
            for &(score, b) in top.iter().filter(|t| t.0 > i32::MIN) {
                if !best.wants(score) && !diverse.wants(score) {
                    continue;
                }
                let Some((x, y)) = f.position_mm(n) else { continue };
                let new = Kept { score, x, y, dir: b as u8 };
                best.offer(new, |_| false);
                diverse.offer(new, |k| {
                    let (dx, dy) = (i64::from(k.x) - i64::from(x), i64::from(k.y) - i64::from(y));
                    // Each within APART_MM first: then the squares are small.
                    let (ax, ay, near) = (dx.unsigned_abs(), dy.unsigned_abs(), APART_MM as u64);
                    ax <= near
                        && ay <= near
                        && ax * ax + ay * ay <= near * near
                        && bins_apart(usize::from(k.dir), b, dirs) <= apart
                });
            }
        }
        // The diverse ones the best list already holds are not repeated.
        for k in diverse.kept.iter() {
            if !best.kept.iter().any(|b| (b.x, b.y, b.dir) == (k.x, k.y, k.dir)) {
                let _ = best.kept.push(*k);
            }
        }
        let mut best = best.kept;
        // Best first: an insertion sort (at most SCAN_KEEP).
        for i in 1..best.len() {
            let mut j = i;
            while j > 0 {
                let (Some(a), Some(b)) = (best.get(j - 1), best.get(j)) else { break };
                if a.score >= b.score {
                    break;
                }
                best.swap(j - 1, j);
                j -= 1;
            }
        }
        for k in &best {
            let th = crate::referencing::wrap(f32::from(k.dir) * core::f32::consts::TAU / dirs as f32);
            let _ = out.push(Candidate {
                pose: [k.x as f32 * 1e-3, k.y as f32 * 1e-3, th],
                score: k.score as f32 / 16.0,
                copies: 1,
            });
        }
    }
}

/// The unused places of a node's neighbour table (never read: the
/// neighbour indices are below 25).
static UNUSED: [u8; SCAN_DIRS] = [0; SCAN_DIRS];

/// A node's scores when all its neighbours hold `SCAN_DIRS` headings: the
/// same sum as the general loop with neither an off-field case nor a bounds
/// check left (the masks are no-ops: indices below 32 and `SCAN_DIRS`), 14
/// instructions a reading and heading on the M4 against 24 (issue #36 item 4).
#[inline(always)]
fn add_whole(
    scores: &mut [i32; SCAN_DIRS],
    lut: &[[i8; 256]],
    geo: &[[(u8, u8); SCAN_DIRS]],
    whole: &[&[u8; SCAN_DIRS]; 32],
) {
    const _POW2: () = assert!(SCAN_DIRS.is_power_of_two());
    for (l, g) in lut.iter().zip(geo) {
        for (s, &(nbi, d)) in scores.iter_mut().zip(g.iter()) {
            let e = whole.get(usize::from(nbi) & 31).and_then(|w| w.get(usize::from(d) & (SCAN_DIRS - 1)));
            let v = e.and_then(|&v| l.get(usize::from(v))).copied().unwrap_or(0);
            // As the general loop: at most SCAN_READINGS terms of |·| ≤ 128.
            *s = s.wrapping_add(i32::from(v));
        }
    }
}

/// How far apart two proposals must stand, mm (or 20° in heading).
const APART_MM: i64 = (SAME_PLACE_M * 1000.0) as i64;

/// A proposal while the sweep runs: its score (1/16 nat), node position
/// (mm) and heading bin.
#[derive(Clone, Copy)]
struct Kept {
    score: i32,
    x: i32,
    y: i32,
    dir: u8,
}

/// The best `cap` proposals so far (unsorted), and the worst of them once
/// full.
struct KeptList {
    kept: heapless::Vec<Kept, SCAN_KEEP>,
    cap: usize,
    worst: i32,
}

impl KeptList {
    /// An empty list of at most `cap` (and `SCAN_KEEP`) proposals.
    fn new(cap: usize) -> Self {
        KeptList { kept: heapless::Vec::new(), cap: cap.min(SCAN_KEEP), worst: i32::MIN }
    }

    /// Whether a proposal of `score` could enter.
    fn wants(&self, score: i32) -> bool {
        self.cap > 0 && (self.kept.len() < self.cap || score > self.worst)
    }

    /// Offers `new`: it replaces a kept proposal `near` it if better (and
    /// is dropped if not), else takes a free place or the worst one's.
    fn offer(&mut self, new: Kept, near: impl Fn(&Kept) -> bool) {
        if !self.wants(new.score) {
            return;
        }
        if let Some(k) = self.kept.iter_mut().find(|k| near(k)) {
            if k.score < new.score {
                *k = new;
            }
        } else if self.kept.len() < self.cap {
            let _ = self.kept.push(new);
        } else if let Some(k) = self.kept.iter_mut().min_by_key(|k| k.score) {
            *k = new;
        }
        if self.kept.len() >= self.cap {
            self.worst = self.kept.iter().map(|k| k.score).min().unwrap_or(i32::MIN);
        }
    }
}

/// Heading bins between `a` and `b` of `dirs`, the shorter way round.
fn bins_apart(a: usize, b: usize, dirs: usize) -> usize {
    let d = a.abs_diff(b);
    d.min(dirs.saturating_sub(d))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stride_visits_every_node_once_a_pass() {
        for n in [1u32, 2, 7, 61, 100, 1031, 6291, 8000, 70_001] {
            let s = stride(n);
            let mut seen = [false; 80_000];
            let mut k = 0u32;
            for _ in 0..n {
                assert!(!seen[k as usize], "n {n} stride {s}");
                seen[k as usize] = true;
                k = (k + s) % n;
            }
        }
    }

    /// The fast path's sums against a plain triple loop in `i64` over the
    /// same tables (random bytes, neighbour indices and headings), for one
    /// to SCAN_READINGS readings.
    #[test]
    fn the_fast_path_adds_what_a_plain_loop_adds() {
        let mut rng = crate::localize::rng::Rng::new(36);
        let mut byte = || rng.next_u32() as u8;
        let mut rows = [[0u8; SCAN_DIRS]; 25];
        for _ in 0..20 {
            for r in rows.iter_mut() {
                r.iter_mut().for_each(|v| *v = byte());
            }
            let mut lut = [[0i8; 256]; SCAN_READINGS];
            let mut geo = [[(0u8, 0u8); SCAN_DIRS]; SCAN_READINGS];
            for (l, g) in lut.iter_mut().zip(geo.iter_mut()) {
                l.iter_mut().for_each(|v| *v = byte() as i8);
                g.iter_mut().for_each(|p| *p = (byte() % 25, byte() % SCAN_DIRS as u8));
            }
            let mut whole: [&[u8; SCAN_DIRS]; 32] = [&UNUSED; 32];
            for (w, r) in whole.iter_mut().zip(rows.iter()) {
                *w = r;
            }
            let k = 1 + usize::from(byte()) % SCAN_READINGS;
            let mut fast = [0i32; SCAN_DIRS];
            add_whole(&mut fast, &lut[..k], &geo[..k], &whole);
            for (b, &f) in fast.iter().enumerate() {
                let mut want = 0i64;
                for r in 0..k {
                    let (nbi, d) = geo[r][b];
                    want += i64::from(lut[r][usize::from(rows[usize::from(nbi)][usize::from(d)])]);
                }
                assert_eq!(i64::from(f), want, "heading {b}, {k} readings");
            }
        }
    }
}
