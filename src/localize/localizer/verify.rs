//! The search's proposals verified: each candidate of the sweep, and every
//! place of the hypothesis bank, scored against the heaviest cluster on
//! the history's readings; the lead the hand-off waits for.

use super::super::expect::FieldLookup;
use super::super::history::HISTORY_CYCLES;
use super::super::hypotheses::{Bank, Hypothesis, Proposal, BANK};
use super::super::measure::Measure;
use super::super::particles::Cluster;
use super::super::scan::{Candidate, SCAN_KEEP};
use super::super::{dist2, within, SAME_PLACE_M, SAME_PLACE_RAD};
use super::Localizer;
use crate::referencing::wrap;

impl<const N: usize> Localizer<N> {
    /// Scores the scan's candidates and the heaviest cluster's mean on the
    /// history and this cycle: a candidate ahead by the margin becomes
    /// `verified_share` of the set.
    /// The bank's places (at the cycle's start) are refined and take this
    /// cycle's readings' say; the best candidate elsewhere (more than a
    /// metre or 20° from the cluster) is proposed to it with its lead on
    /// the history. Returns the lead the hand-off counts: the smallest of
    /// every place's [`Hypothesis::margin_lead`], nats (`+∞` with none,
    /// `−∞` with no cluster). The place the cluster leads by the least, if
    /// it leads the cluster by the margin, goes into the set like a
    /// verified candidate.
    pub(super) fn verify(
        &mut self,
        candidates: &mut heapless::Vec<Candidate, SCAN_KEEP>,
        cluster: Option<&Cluster>,
        lookup: &FieldLookup<'_, '_>,
    ) -> f32 {
        let mut bank = core::mem::take(&mut self.bank);
        if cluster.is_none() {
            // With no cluster there is nothing to lead, and no place to keep.
            bank.clear();
        }
        let lead = self.verify_with(&mut bank, candidates, cluster, lookup);
        self.bank = bank;
        lead
    }

    fn verify_with(
        &self,
        bank: &mut Bank,
        candidates: &mut heapless::Vec<Candidate, SCAN_KEEP>,
        cluster: Option<&Cluster>,
        lookup: &FieldLookup<'_, '_>,
    ) -> f32 {
        let c = &self.cfg;
        if candidates.is_empty() && bank.is_empty() {
            return if cluster.is_some() { f32::INFINITY } else { f32::NEG_INFINITY };
        }
        let m = Measure::new(lookup, &c.mcl.beam, c.verify_sigma_mm * c.verify_sigma_mm);
        // Every candidate scored on the history and this cycle; the best few
        // go on (best first), the first of them in number if it beats the
        // heaviest cluster by the margin.
        for cand in candidates.iter_mut() {
            cand.score = self.history.score(&cand.pose, &self.sensed, &m);
            cand.copies = 1;
        }
        // Best first: an insertion sort (at most SCAN_KEEP, and core's sorts
        // link a panic for orderings that are not total).
        for i in 1..candidates.len() {
            let mut j = i;
            while j > 0 {
                let (Some(a), Some(b)) = (candidates.get(j - 1), candidates.get(j)) else { break };
                if a.score.total_cmp(&b.score).is_ge() {
                    break;
                }
                candidates.swap(j - 1, j);
                j -= 1;
            }
        }
        candidates.truncate(usize::from(c.verify_keep).max(1));
        let score = |p: &[f32; 3]| self.history.score(p, &self.sensed, &m);
        // A pose's best score nearby: coordinate ascent in x, y and φ with
        // halving steps (0.12 m and 3° down to 0.03 m and 0.75°). The scan's proposals stand on the node grid and its
        // heading bins, the cluster's mean wherever its particles are: each
        // is refined the same way before they are compared, or the
        // incumbent would win by its finer placement alone (in a symmetric
        // map, against its alias). Kept places too, every cycle: with the
        // finest step only, they fell behind the cluster by their placement
        // and tb3_sandbox handed off wrongly more often (19 of 20 runs
        // against 17).
        let refine = |start: [f32; 3], s0: f32| {
            let (mut best, mut s) = (start, s0);
            for (step_m, step_rad) in [(0.12f32, 0.052f32), (0.06, 0.026), (0.03, 0.013)] {
                for axis in 0..3 {
                    let step = if axis == 2 { step_rad } else { step_m };
                    for sign in [-1.0f32, 1.0] {
                        let mut p = best;
                        if let Some(v) = p.get_mut(axis) {
                            *v += sign * step;
                        }
                        let v = score(&p);
                        if v > s {
                            (best, s) = (p, v);
                        }
                    }
                }
            }
            (best, s)
        };
        let (own_pose, own) = match cluster {
            Some(k) => refine(k.mean, score(&k.mean)),
            None => ([0.0; 3], f32::NEG_INFINITY),
        };
        let elsewhere = |p: &[f32; 3]| {
            cluster.is_none_or(|k| {
                dist2(p, &k.mean) > SAME_PLACE_M * SAME_PLACE_M || heading_apart(p, &k.mean) > SAME_PLACE_RAD
            })
        };
        // (Not `!elsewhere`: a NaN pose is neither near nor elsewhere.)
        let near = |a: &[f32; 3], b: &[f32; 3]| within(a, b, SAME_PLACE_M, SAME_PLACE_RAD);
        let z = c.handoff_z;
        let mut lead = if cluster.is_some() { f32::INFINITY } else { f32::NEG_INFINITY };
        if cluster.is_some() {
            // The kept places: this cycle's readings alone, at the refined
            // poses.
            let now = |q: &[f32; 3]| m.log_likelihood(q, &self.sensed);
            let own_now = now(&own_pose);
            bank.observe_each(|p| {
                (*p, _) = refine(*p, score(p));
                own_now - now(p)
            });
            bank.retain(|h| elsewhere(&h.pose) && h.margin_lead(z) < c.bank_refute, near);
            // The best candidate elsewhere, refined, with its lead and
            // spread on the history's cycles.
            if let Some(k) = candidates.iter_mut().find(|k| elsewhere(&k.pose)) {
                (k.pose, k.score) = refine(k.pose, k.score);
                // The spread only matters to a margin.
                let spread2: f32 = if z > 0.0 {
                    let ours = self.history.score_cycles(&own_pose, &self.sensed, &m);
                    let theirs = self.history.score_cycles(&k.pose, &self.sensed, &m);
                    ours.iter().zip(&theirs).map(|(a, b)| (a - b) * (a - b)).sum()
                } else {
                    0.0
                };
                let cycles = (self.history.len().min(HISTORY_CYCLES) as u16).saturating_add(1);
                let h = Hypothesis::new(k.pose, own - k.score, spread2, cycles);
                // A proposal the bank has no room for still counts.
                if bank.propose(h, usize::from(c.bank_keep).min(BANK), near) == Proposal::Refused {
                    lead = lead.min(h.margin_lead(z));
                }
            }
            lead = lead.min(bank.margin_lead(z));
        }
        if self.ekf_awake {
            // The EKF beside the particles is a hypothesis too: a cluster
            // elsewhere must lead it as well, by the larger margin (it
            // tracked until a moment ago).
            let x = self.ekf_at_cycle_start();
            if elsewhere(&x) {
                let ekf = self.history.score(&x, &self.sensed, &m);
                lead = lead.min(own - (ekf + c.handoff_lead_awake - c.handoff_lead));
            }
        }
        let share = ((c.verified_share * self.particles.len() as f32) as u16).max(1);
        if let Some(first) = candidates.first_mut() {
            if !self.history.is_empty() && first.score > own + c.verify_margin {
                first.copies = share;
            }
        }
        if let Some(h) = bank.strongest() {
            if h.lead < -c.verify_margin && candidates.first().is_none_or(|k| k.copies <= 1) {
                candidates.truncate(SCAN_KEEP - 1);
                let _ = candidates.insert(0, Candidate { pose: h.pose, score: own - h.lead, copies: share });
            }
        }
        lead
    }
}

/// The difference of two poses' headings, rad, in `[0, π]` (apart: the
/// callers look at it only when the positions are close, it costs a wrap).
#[inline(always)]
fn heading_apart(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    wrap(a[2] - b[2]).abs()
}
