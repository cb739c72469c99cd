//! Resampling in place: low-variance, sized by KLD sampling, with random
//! particles injected over free space when the short-term likelihood falls
//! below the long-term one (augmented MCL).

use super::super::expect::FieldLookup;
use super::super::measure::Measure;
use super::super::scan::Candidate;
use super::{McConfig, ParticleSet, Sensed};
use crate::f32math::{exp_fast, sqrt};
use crate::referencing::wrap;

/// KLD sampling's bound (Fox 2003, eq. 11): particles needed so that, with
/// probability 1 − δ, the K–L divergence between the sample-based and the
/// true posterior stays below ε, when the samples fall into `k` bins:
/// `(k − 1)/(2ε) · (1 − 2/(9(k − 1)) + √(2/(9(k − 1))) · z₁₋δ)³`; 0 for `k ≤ 1`.
pub fn kld_bound(k: u32, epsilon: f32, z: f32) -> f32 {
    if k <= 1 {
        return 0.0;
    }
    let km1 = (k - 1) as f32;
    let a = 2.0 / (9.0 * km1);
    let b = 1.0 - a + sqrt(a) * z;
    km1 / (2.0 * epsilon) * b * b * b
}

impl<const N: usize> ParticleSet<N> {
    /// Resamples the weighted set: low-variance resampling to the capacity,
    /// then KLD sampling's size from the bins the new set fills (at least
    /// `min_particles`), then augmented MCL's injection of poses drawn over
    /// free space (`1 − w_fast / w_slow`, at least `explore` and at most
    /// `max_inject` of the set), each drawn among `inject_tries` random poses
    /// in proportion to their likelihood under `sensed`. Weights become
    /// uniform.
    pub fn resample(
        &mut self,
        sensed: &[Sensed],
        lookup: &FieldLookup<'_, '_>,
        cfg: &McConfig,
        inject_prior: f32,
        candidates: &[Candidate],
    ) {
        let n = self.n;
        if n == 0 || N == 0 {
            return;
        }
        // 1. Copies of each particle: a comb of N teeth, one random offset.
        let step = 1.0 / N as f32;
        let mut u = self.rng.uniform() * step;
        let mut cum = 0.0f32;
        let mut teeth = 0usize;
        // Each weight, once added to the running sum, is replaced by the
        // particle's number of copies.
        for (i, c) in self.weight.iter_mut().take(n).enumerate() {
            cum += *c;
            // The last particle takes the teeth rounding leaves.
            let end = if i + 1 == n { f32::INFINITY } else { cum };
            let mut copies = 0u32;
            while u < end && teeth < N {
                copies += 1;
                teeth += 1;
                u += step;
            }
            *c = copies as f32;
        }
        // 2. In place: each particle keeps its slot for its first copy; each
        //    extra copy goes to a slot nobody keeps (a particle with no
        //    copies), then past the old set. The copies add up to N, so the
        //    N slots end up full.
        let mut free = 0usize;
        let mut next = n;
        for i in 0..n {
            let copies = self.weight.get(i).map_or(0, |&c| c as u32);
            let src = self.pose.get(i).copied().unwrap_or_default();
            for _ in 1..copies {
                while free < n && self.weight.get(free).is_some_and(|&c| c != 0.0) {
                    free += 1;
                }
                let slot = if free < n {
                    // Claimed: it holds one copy now, and is nobody's source.
                    if let Some(c) = self.weight.get_mut(free) {
                        *c = 1.0;
                    }
                    free
                } else {
                    let s = next;
                    next = next.saturating_add(1);
                    s
                };
                if let Some(p) = self.pose.get_mut(slot) {
                    *p = src;
                }
            }
        }
        let full = N;
        // 3. KLD: bins the new set fills (counted up to half the capacity,
        //    where the bound passes any capacity worth having), hashed into
        //    the weights' words (the weights are spent).
        let bins = self.count_bins(full, cfg);
        let want = libm::ceilf(kld_bound(bins, cfg.kld_epsilon, cfg.kld_z)) as usize;
        let m = want.max(usize::from(cfg.min_particles)).clamp(1, full);
        // 4. Keep m of them, evenly at random (a partial Fisher–Yates shuffle).
        if m < full {
            for t in 0..m {
                let j = t + self.rng.below((full - t) as u32) as usize;
                if j != t {
                    self.pose.swap(t, j.min(N - 1));
                }
            }
        }
        // 5. Augmented MCL's injection.
        let frac = if self.w_slow > 0.0 { (1.0 - self.w_fast / self.w_slow).max(0.0) } else { 0.0 };
        let frac = frac.min(cfg.max_inject);
        let inject = ((frac.max(cfg.explore) * m as f32) as usize).min(m / 2);
        self.injected = inject as f32 / m as f32;
        // The scan's candidates first (jittered within their node and
        // heading bin), then draws over free space.
        let wanted = candidates.iter().fold(0usize, |n, c| n.saturating_add(usize::from(c.copies.max(1))));
        let inject = inject.max(wanted.min(m / 2));
        self.injected = inject as f32 / m as f32;
        // (`inject ≤ m / 2`: saturating only shows it to the compiler.)
        let first_injected = m.saturating_sub(inject);
        let h = lookup.node_mm() * 1e-3;
        let bin = core::f32::consts::TAU / lookup.field().dirs().max(1) as f32;
        // Candidates in order, each as many times as it has copies.
        let mut copies = candidates.iter().flat_map(|c| core::iter::repeat_n(c, usize::from(c.copies.max(1))));
        for t in first_injected..m {
            let p = match copies.next() {
                Some(c) if c.copies > 1 => {
                    // A verified candidate: copies spread as a small cloud.
                    let r = &mut self.rng;
                    let (a, b, d) = (r.normal(), r.normal(), r.normal());
                    Some([c.pose[0] + 0.05 * a, c.pose[1] + 0.05 * b, wrap(c.pose[2] + 0.5 * bin * d)])
                }
                Some(c) => {
                    let r = &mut self.rng;
                    let (jx, jy, jt) = (r.uniform() - 0.5, r.uniform() - 0.5, r.uniform() - 0.5);
                    Some([c.pose[0] + jx * h, c.pose[1] + jy * h, wrap(c.pose[2] + jt * bin)])
                }
                None => self.inject_one(sensed, lookup, cfg),
            };
            if let (Some(p), Some(slot)) = (p, self.pose.get_mut(t)) {
                *slot = p;
            }
        }
        self.set_uniform(m);
        // Injected poses enter with the belief's mass outside its heaviest
        // cluster as their prior (Mixture MCL weighs its draws from the
        // readings by the belief at them): they take over from a cluster
        // only where the readings say so, not by sheer number.
        self.injected_from = first_injected;
        self.injected_prior = inject_prior.clamp(1e-3, 1.0);
    }

    /// One pose for injection: the likeliest-in-proportion of
    /// `inject_tries` drawn over free space.
    fn inject_one(&mut self, sensed: &[Sensed], lookup: &FieldLookup<'_, '_>, cfg: &McConfig) -> Option<[f32; 3]> {
        let tries = cfg.inject_tries.max(1);
        let first = self.candidate(sensed, lookup, cfg)?;
        if tries == 1 {
            return Some(first);
        }
        // A running weighted choice (reservoir of one), with weights relative
        // to the first candidate's.
        let m = Measure::new(lookup, &cfg.beam, self.extra_var(cfg));
        let base = m.log_likelihood(&first, sensed);
        let (mut pick, mut total) = (first, 1.0f32);
        for _ in 1..tries {
            let p = self.candidate(sensed, lookup, cfg)?;
            let w = exp_fast(cfg.temper * (m.log_likelihood(&p, sensed) - base)).min(1e30);
            total += w;
            if self.rng.uniform() * total < w {
                pick = p;
            }
        }
        Some(pick)
    }

    /// A pose for injection: a free position, and the heading the cycle's
    /// readings favour there among `scan_headings` evenly spaced (at a
    /// random offset), or any heading when that is 0 or there are no
    /// readings.
    fn candidate(&mut self, sensed: &[Sensed], lookup: &FieldLookup<'_, '_>, cfg: &McConfig) -> Option<[f32; 3]> {
        let mut p = Self::free_pose(&mut self.rng, lookup)?;
        let h = u32::from(cfg.scan_headings);
        if h == 0 || sensed.is_empty() {
            return Some(p);
        }
        let step = core::f32::consts::TAU / h as f32;
        let off = self.rng.uniform() * step - core::f32::consts::PI;
        let mut best = (f32::NEG_INFINITY, p[2]);
        let m = Measure::new(lookup, &cfg.beam, self.extra_var(cfg));
        for b in 0..h {
            let th = off + b as f32 * step;
            let ll = m.log_likelihood(&[p[0], p[1], th], sensed);
            if ll > best.0 {
                best = (ll, th);
            }
        }
        p[2] = wrap(best.1);
        Some(p)
    }

    /// Distinct KLD bins among the first `count` particles, counted in an
    /// open-addressing table in the weights' words (up to half of them).
    fn count_bins(&mut self, count: usize, cfg: &McConfig) -> u32 {
        let cap = N;
        for s in self.weight.iter_mut() {
            *s = f32::from_bits(0);
        }
        let (inv_xy, inv_t) = (1.0 / cfg.bin_m, 1.0 / cfg.bin_rad);
        let mut bins = 0u32;
        for p in self.pose.iter().take(count) {
            let bx = libm::floorf(p[0] * inv_xy) as i32 as u32;
            let by = libm::floorf(p[1] * inv_xy) as i32 as u32;
            let bt = libm::floorf((p[2] + core::f32::consts::PI) * inv_t) as i32 as u32;
            // Bit 30 clear: the word is never a NaN's or an infinity's bit
            // pattern, so it passes through the f32 slot unchanged on every
            // target; bit 0 set: never the empty slot's 0.
            let key = ((bx.wrapping_mul(0x9E37_79B1) ^ by.wrapping_mul(0x85EB_CA77) ^ bt.wrapping_mul(0xC2B2_AE3D))
                & 0xBFFF_FFFF)
                | 1;
            let mut h = (key.wrapping_mul(0x2545_F491) >> 7) as usize % cap;
            loop {
                match self.weight.get(h).map(|w| w.to_bits()) {
                    Some(0) => {
                        if let Some(s) = self.weight.get_mut(h) {
                            *s = f32::from_bits(key);
                        }
                        bins += 1;
                        break;
                    }
                    Some(k) if k == key => break,
                    Some(_) => h = (h + 1) % cap,
                    None => break,
                }
            }
            if bins as usize >= cap / 2 {
                break;
            }
        }
        bins
    }
}
