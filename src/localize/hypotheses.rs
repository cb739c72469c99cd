//! The hypothesis bank (issue #36): every place still plausible besides the
//! particles' heaviest cluster, each with the cluster's lead over it summed
//! over every cycle since it was proposed, and the hand-off's test on those
//! sums (Jensfelt and Kristensen's multiple-hypothesis localization: decide
//! only when one place has won over the whole time since they split).
//!
//! Pure bookkeeping: the localizer scores the poses and says how far the
//! cluster led each one on a cycle ([`Bank::observe`]); the bank keeps the
//! sums, takes proposals, merges duplicates, drops the refuted and says
//! whether the cluster leads every member by the margin.
//!
//! The margin grows with how alike two places have looked: a lead summed
//! over `n` cycles whose per-cycle leads `dₜ` are noise about zero wanders
//! by about `√Σdₜ²`, so the hand-off counts `lead − z·√Σdₜ²`
//! ([`Hypothesis::margin_lead`]). A place that keeps losing by a steady
//! amount falls behind by `n·μ` against a margin that grows as `√n`; two
//! places that stay level never pass it.
//!
//! ```
//! use echoloc::localize::hypotheses::{Bank, Hypothesis, BANK};
//!
//! let near = |a: &[f32; 3], b: &[f32; 3]| (a[0] - b[0]).abs() < 1.0 && (a[1] - b[1]).abs() < 1.0;
//! let mut bank = Bank::new();
//! bank.propose(Hypothesis::new([5.0, 0.0, 0.0], 10.0, 36.0, 1), BANK, near);
//! // Two places as alike as can be: the cluster's lead goes +6, −6, ...
//! for t in 0..100 {
//!     bank.observe(0, if t % 2 == 0 { 6.0 } else { -6.0 });
//! }
//! // ... so after 101 cycles it still leads by 10 nats, within the noise.
//! assert!(bank.margin_lead(1.0) < 0.0);
//! // Another that the cluster out-fits by 5 nats every cycle is beaten.
//! let mut beaten = Bank::new();
//! beaten.propose(Hypothesis::new([5.0, 0.0, 0.0], 5.0, 25.0, 1), BANK, near);
//! for _ in 0..20 {
//!     beaten.observe(0, 5.0);
//! }
//! // 105 nats less √525 ≈ 23 of spread: ahead by more than the hand-off's 25.
//! assert!(beaten.margin_lead(1.0) > 80.0);
//! ```

use heapless::Vec;

use crate::f32math::sqrt;

/// How many places the bank keeps besides the cluster.
pub const BANK: usize = 8;

/// A place besides the cluster.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Hypothesis {
    /// The pose (x m, y m, φ rad), in the current cycle's start frame.
    pub pose: [f32; 3],
    /// The cluster's lead over it, summed over every cycle since it was
    /// proposed, nats (negative: it fits better than the cluster).
    pub lead: f32,
    /// The sum of the squares of those cycles' leads, nats².
    pub spread2: f32,
    /// The cycles summed.
    pub cycles: u16,
}

impl Hypothesis {
    /// A place with the cluster's lead over it so far, the sum of its
    /// cycles' leads' squares and their number.
    pub const fn new(pose: [f32; 3], lead: f32, spread2: f32, cycles: u16) -> Self {
        Self { pose, lead, spread2, cycles }
    }

    /// The cluster led it by `d` nats on one more cycle.
    fn add(&mut self, d: f32) {
        self.lead += d;
        self.spread2 += d * d;
        self.cycles = self.cycles.saturating_add(1);
    }

    /// The lead less `z` times its per-cycle spread: what the hand-off
    /// counts (NaN counts as level: `−∞`).
    pub fn margin_lead(&self, z: f32) -> f32 {
        let m = self.lead - z * sqrt(self.spread2.max(0.0));
        if m.is_nan() {
            f32::NEG_INFINITY
        } else {
            m
        }
    }
}

/// What became of a proposal ([`Bank::propose`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Proposal {
    /// It joined the bank (maybe in the place of a weaker member).
    Joined,
    /// It is a member already: it stood near one, whose record stands.
    Member,
    /// No room for it (or none kept, or its lead is NaN): not kept, but the
    /// hand-off may still have to beat it this cycle.
    Refused,
}

/// The places kept besides the cluster, at most [`BANK`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bank {
    members: Vec<Hypothesis, BANK>,
}

impl Bank {
    /// An empty bank.
    pub const fn new() -> Self {
        Self { members: Vec::new() }
    }

    /// Forgets every place.
    pub fn clear(&mut self) {
        self.members.clear();
    }

    /// The places kept.
    pub fn members(&self) -> &[Hypothesis] {
        &self.members
    }

    /// Each place's pose, to carry.
    pub fn poses_mut(&mut self) -> impl Iterator<Item = &mut [f32; 3]> {
        self.members.iter_mut().map(|h| &mut h.pose)
    }

    /// One more cycle for every place: `f` may move its pose (refine it)
    /// and says by how much the cluster led it, nats ([`Bank::observe`]).
    pub fn observe_each(&mut self, mut f: impl FnMut(&mut [f32; 3]) -> f32) {
        for h in self.members.iter_mut() {
            let d = f(&mut h.pose);
            h.add(d);
        }
    }

    /// How many places are kept.
    pub fn len(&self) -> usize {
        self.members.len()
    }

    /// Whether none is.
    pub fn is_empty(&self) -> bool {
        self.members.is_empty()
    }

    /// The cluster led member `i` by `d` nats on one more cycle.
    pub fn observe(&mut self, i: usize, d: f32) {
        if let Some(h) = self.members.get_mut(i) {
            h.add(d);
        }
    }

    /// A place the search proposes. One `near` a member is that member (it
    /// keeps its longer record); else it joins, and with `keep` members
    /// (at most [`BANK`]) it takes the place of the member the cluster
    /// leads by the most, if the cluster leads it by less.
    pub fn propose(&mut self, h: Hypothesis, keep: usize, near: impl Fn(&[f32; 3], &[f32; 3]) -> bool) -> Proposal {
        if self.members.iter().any(|m| near(&m.pose, &h.pose)) {
            return Proposal::Member;
        }
        if h.lead.is_nan() || keep == 0 {
            return Proposal::Refused;
        }
        if self.members.len() < keep && self.members.push(h).is_ok() {
            return Proposal::Joined;
        }
        let weakest = self.members.iter_mut().max_by(|a, b| a.lead.total_cmp(&b.lead));
        match weakest {
            Some(w) if h.lead < w.lead => {
                *w = h;
                Proposal::Joined
            }
            _ => Proposal::Refused,
        }
    }

    /// Drops every member `keep` refuses, and of two members `near` each
    /// other (refined onto one place) the one the cluster leads by more.
    pub fn retain(&mut self, keep: impl Fn(&Hypothesis) -> bool, near: impl Fn(&[f32; 3], &[f32; 3]) -> bool) {
        // One loop, no `Vec::retain`: its index arithmetic keeps overflow
        // checks the optimiser cannot remove (scripts/panic-never.sh).
        let mut i = 0;
        while i < self.members.len() {
            let Some(a) = self.members.get(i) else { break };
            let gone = !keep(a)
                || self.members.iter().enumerate().any(|(j, m)| {
                    j != i && keep(m) && near(&a.pose, &m.pose) && (m.lead < a.lead || (m.lead == a.lead && j < i))
                });
            if gone {
                self.members.remove(i);
            } else {
                i += 1;
            }
        }
    }

    /// The smallest [`Hypothesis::margin_lead`] (`+∞` with none): the
    /// cluster leads every member by at least this.
    pub fn margin_lead(&self, z: f32) -> f32 {
        self.members.iter().map(|h| h.margin_lead(z)).fold(f32::INFINITY, f32::min)
    }

    /// The member the cluster leads by the least (the strongest rival).
    pub fn strongest(&self) -> Option<&Hypothesis> {
        self.members.iter().min_by(|a, b| a.lead.total_cmp(&b.lead))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn near(a: &[f32; 3], b: &[f32; 3]) -> bool {
        (a[0] - b[0]).hypot(a[1] - b[1]) <= 1.0
    }

    fn at(x: f32, lead: f32) -> Hypothesis {
        Hypothesis::new([x, 0.0, 0.0], lead, lead * lead, 1)
    }

    #[test]
    fn a_proposal_near_a_member_is_that_member() {
        let mut b = Bank::new();
        assert_eq!(b.propose(at(0.0, 40.0), BANK, near), Proposal::Joined);
        b.observe(0, 30.0);
        // Proposed again nearby with a short record that looks closer: the
        // longer record stands.
        assert_eq!(b.propose(at(0.5, 5.0), BANK, near), Proposal::Member);
        assert_eq!(b.len(), 1);
        assert_eq!(b.members()[0].lead, 70.0);
        assert_eq!(b.members()[0].cycles, 2);
        assert_eq!(b.members()[0].spread2, 1600.0 + 900.0);
    }

    #[test]
    fn observe_each_moves_every_place_and_adds_its_lead() {
        let mut b = Bank::new();
        b.propose(at(0.0, 10.0), BANK, near);
        b.propose(at(5.0, 20.0), BANK, near);
        // Each place refined 0.25 m along x; the cluster led the first by 3
        // nats this cycle, the second by −4.
        b.observe_each(|p| {
            p[0] += 0.25;
            if p[0] < 1.0 {
                3.0
            } else {
                -4.0
            }
        });
        let m = b.members();
        assert_eq!((m[0].pose[0], m[0].lead, m[0].spread2, m[0].cycles), (0.25, 13.0, 100.0 + 9.0, 2));
        assert_eq!((m[1].pose[0], m[1].lead, m[1].spread2, m[1].cycles), (5.25, 16.0, 400.0 + 16.0, 2));
    }

    #[test]
    fn a_full_bank_gives_up_its_weakest_member_for_a_stronger_one_only() {
        let mut b = Bank::new();
        for i in 0..BANK {
            assert_eq!(b.propose(at(10.0 * i as f32, 10.0 + i as f32), BANK, near), Proposal::Joined);
        }
        // Weaker than every member: refused.
        assert_eq!(b.propose(at(500.0, 100.0), BANK, near), Proposal::Refused);
        assert_eq!(b.len(), BANK);
        // Stronger than the weakest (lead 17 at x = 70): takes its place.
        assert_eq!(b.propose(at(600.0, 12.5), BANK, near), Proposal::Joined);
        assert_eq!(b.len(), BANK);
        assert!(b.members().iter().all(|h| h.pose[0] != 70.0));
        assert!(b.members().iter().any(|h| h.pose[0] == 600.0));
        assert_eq!(b.strongest().map(|h| h.pose[0]), Some(0.0));
        // NaN is no proposal.
        assert_eq!(b.propose(at(700.0, f32::NAN), BANK, near), Proposal::Refused);
        // Near a member, NaN or not, it is that member.
        assert_eq!(b.propose(at(0.5, f32::NAN), BANK, near), Proposal::Member);
    }

    #[test]
    fn a_bank_of_one_is_the_kept_rival() {
        // #27's rule: one place kept; a proposal elsewhere takes its place
        // only if the cluster leads it by less, one nearby is it.
        let mut b = Bank::new();
        assert_eq!(b.propose(at(0.0, 30.0), 1, near), Proposal::Joined);
        assert_eq!(b.propose(at(10.0, 40.0), 1, near), Proposal::Refused);
        assert_eq!(b.propose(at(0.5, 5.0), 1, near), Proposal::Member);
        assert_eq!(b.members(), &[at(0.0, 30.0)]);
        assert_eq!(b.propose(at(10.0, 20.0), 1, near), Proposal::Joined);
        assert_eq!(b.members(), &[at(10.0, 20.0)]);
        // None kept: nothing joins.
        let mut none = Bank::new();
        assert_eq!(none.propose(at(0.0, 1.0), 0, near), Proposal::Refused);
        assert!(none.is_empty());
    }

    #[test]
    fn two_places_level_forever_never_pass_the_margin() {
        // Proposed 20 nats behind the cluster on the history; from then on
        // level: the cycles' leads repeat +9, −3, −6, +2, −2 (sum 0).
        let mut b = Bank::new();
        b.propose(Hypothesis::new([5.0, 0.0, 0.0], 20.0, 100.0, 8), BANK, near);
        let (mut raw, mut best) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
        for t in 0..10_000 {
            b.observe(0, [9.0, -3.0, -6.0, 2.0, -2.0][t % 5]);
            raw = raw.max(b.members()[0].lead);
            best = best.max(b.margin_lead(1.0));
        }
        // The raw sum passes a fixed 25 nats every fifth cycle ...
        assert_eq!(raw, 29.0);
        // ... the margin it is held to never lets it.
        assert!(best < 25.0, "{best}");
        assert!(b.margin_lead(1.0) < -400.0, "{}", b.margin_lead(1.0));
    }

    #[test]
    fn a_steady_lead_passes_the_margin_and_a_steady_loss_never_does() {
        for (d, passes) in [(4.0f32, true), (-4.0, false), (0.0, false)] {
            let mut b = Bank::new();
            b.propose(Hypothesis::new([5.0, 0.0, 0.0], 0.0, 0.0, 0), BANK, near);
            let mut first = None;
            for t in 0..400u32 {
                // Noise of ±10 about the steady lead d.
                b.observe(0, d + if t % 2 == 0 { 10.0 } else { -10.0 });
                if first.is_none() && b.margin_lead(1.0) >= 25.0 {
                    first = Some(t);
                }
            }
            assert_eq!(first.is_some(), passes, "d = {d}: {first:?}");
            // Brute force: the test is lead − √Σd² ≥ 25 with lead = n·d
            // (n even) and Σd² = n·(d² + 100).
            if let Some(t) = first {
                let n = (t + 1) as f32;
                let lead = n * d + if (t + 1) % 2 == 1 { 10.0 } else { 0.0 };
                let spread = (0..=t).map(|s| (d + if s % 2 == 0 { 10.0 } else { -10.0 }).powi(2)).sum::<f32>();
                assert!(lead - spread.sqrt() >= 25.0);
            }
        }
    }

    #[test]
    fn duplicates_merge_into_the_stronger_and_the_refuted_go() {
        let mut b = Bank::new();
        b.propose(at(0.0, 30.0), BANK, near);
        b.propose(at(5.0, 10.0), BANK, near);
        b.propose(at(20.0, 300.0), BANK, near);
        // The first refined onto the second.
        if let Some(p) = b.poses_mut().next() {
            p[0] = 5.5;
        }
        b.retain(|h| h.margin_lead(0.0) < 200.0, near);
        assert_eq!(b.members(), &[at(5.0, 10.0)]);
        // Two equal ones: one stays.
        let mut c = Bank::new();
        c.propose(at(0.0, 10.0), BANK, near);
        c.propose(at(5.0, 10.0), BANK, near);
        if let Some(p) = c.poses_mut().nth(1) {
            p[0] = 0.5;
        }
        c.retain(|_| true, near);
        assert_eq!(c.len(), 1);
    }

    #[test]
    fn an_empty_bank_is_led_by_everything() {
        let b = Bank::new();
        assert_eq!(b.margin_lead(1.0), f32::INFINITY);
        assert!(b.strongest().is_none());
        assert_eq!(Hypothesis::new([0.0; 3], f32::NAN, 0.0, 0).margin_lead(1.0), f32::NEG_INFINITY);
    }
}
