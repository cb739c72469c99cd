//! The living places and the sequential test between them and the null
//! (DESIGN §4.8, issue #48): a fixed bank of [`Place`]s, each tracking
//! itself, each with its evidence over the null hypothesis since it was
//! born, and every pair's evidence when the younger was born. The
//! localizer's judge (`localizer/judge.rs`) holds one while searching,
//! and with rivals while tracking too, the tracked pose among them
//! ([`Places::anchor`]).
//!
//! - **Proposals** (the particles' cluster, the sweep's places) join the
//!   bank at the null's level (evidence 0: before it was born, the place
//!   was part of "none of these"), unless a living place stands within
//!   a metre and 20° of it (that place
//!   already follows it); a full bank gives the slot of its weakest place
//!   only if that one trails the null.
//! - **Every cycle** each place scores the readings and corrects itself
//!   ([`Place::cycle`]); two that converged (within [`MERGE_M`] and
//!   [`MERGE_RAD`]) become one, the longer record kept; a place the bound
//!   behind the null, or behind another over the cycles both lived, is
//!   dropped. (Dropped on the whole record, the truth proposed after an
//!   alias had led the null for a while joined 150 nats behind it and
//!   went at once: the wrong hand-offs of docs/localization.md.)
//! - **The test**: a place leads when it is the bound ahead of the null and
//!   of every other living place ([`Standing::Leads`]): of a contender (a
//!   place itself the bound ahead of the null) over the cycles both lived,
//!   of a lesser one by their evidence. Otherwise the answer is
//!   *searching*, for as long as it takes. The bound is the summed,
//!   clipped log-ratio a wrong place never reached over the truth and the
//!   null on the simulator (docs/localization.md: 150 nats).
//!
//! ```
//! use echoloc::localize::places::{standing, Standing};
//!
//! // Three places born together (each had nothing at the others' birth),
//! // their evidence over the null, the bound 150 nats.
//! let together = [[0.0f32; 3]; 3];
//! assert_eq!(standing(&[420.0, 180.0, -30.0], &together, 150.0), Standing::Leads { index: 0, margin: 240.0 });
//! // Ahead of the null but not of its rival by the bound: searching.
//! assert_eq!(standing(&[420.0, 300.0], &together, 150.0), Standing::Searching);
//! // Ahead of every rival but not of the null: searching.
//! assert_eq!(standing(&[120.0, -200.0], &together, 150.0), Standing::Searching);
//! // The second place was born when the first had 700: since then it has
//! // gained 160 to the first's 100. A contender, and ahead: searching.
//! let late = [[0.0f32, 0.0], [700.0, 0.0]];
//! assert_eq!(standing(&[800.0, 160.0], &late, 150.0), Standing::Searching);
//! // Had it gained 100, not yet the bound past the null: judged by the
//! // evidence, 700 behind.
//! assert_eq!(standing(&[800.0, 100.0], &late, 150.0), Standing::Leads { index: 0, margin: 700.0 });
//! ```

use heapless::Vec;

use super::measure::Sensed;
use super::place::{Place, PlaceError, Tracking};
use super::{dist2, within, SAME_PLACE_M, SAME_PLACE_RAD};
use crate::referencing::Motion;

/// Two places within this distance (m) ...
pub const MERGE_M: f32 = 0.25;
/// ... and this angle (rad, 5°) have converged: they are one.
pub const MERGE_RAD: f32 = 5.0 * core::f32::consts::PI / 180.0;

/// What the test says.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Standing {
    /// No place leads the null and every other by the bound.
    Searching,
    /// The place at `index` does, by `margin` nats (its lead over the
    /// null or the next place, whichever is less).
    Leads {
        /// Its index among the living places.
        index: usize,
        /// Its smallest lead, nats.
        margin: f32,
    },
}

/// Place `a`'s lead over place `b` over the cycles both lived (nats):
/// `evidence` is each place's over the null, `since[x][y]` is `y`'s
/// evidence when the later of `x` and `y` was born. A place born late is
/// judged on what both heard, not on the cycles before it was proposed:
/// else the truth, proposed after an alias has led the null for a while,
/// joins the bound behind it and is dropped at once.
fn lead<R: AsRef<[f32]>>(evidence: &[f32], since: &[R], a: usize, b: usize) -> f32 {
    let at = |x: usize, y: usize| since.get(x).and_then(|r| r.as_ref().get(y)).copied().unwrap_or(0.0);
    let (ea, eb) = (evidence.get(a).copied().unwrap_or(f32::NAN), evidence.get(b).copied().unwrap_or(f32::NAN));
    (ea - at(b, a)) - (eb - at(a, b))
}

/// Place `i`'s smallest lead: over the null (its evidence) and over every
/// other place. A rival that has itself passed the null by the bound is a
/// contender and is compared over the cycles both lived; a lesser one by
/// its evidence (before it was born it was part of the null, which the
/// place already leads). Without that distinction every young place is
/// level with the leader on the few cycles they share, and with proposals
/// coming every cycle no place ever led (measured: docs/localization.md).
/// NaN for a place whose evidence is NaN; a rival whose evidence is NaN is
/// passed over.
fn margin<R: AsRef<[f32]>>(evidence: &[f32], since: &[R], i: usize, bound: f32) -> f32 {
    let e = evidence.get(i).copied().unwrap_or(f32::NAN);
    if e.is_nan() {
        return f32::NAN;
    }
    // Indices by a bounded range, not `enumerate`: its counter carries an
    // overflow check the optimiser cannot remove (scripts/panic-never.sh).
    (0..evidence.len())
        .zip(evidence.iter())
        .filter(|&(j, x)| j != i && !x.is_nan())
        .map(|(j, &x)| if x >= bound { lead(evidence, since, i, j) } else { e - x })
        .fold(e, f32::min)
}

/// The test on the living places (`evidence` each over the null, which
/// stands at 0; `since` as [`Places`] keeps it: `since[x][y]` is `y`'s
/// evidence when the later of `x` and `y` was born): the place at least
/// `bound` ahead of the null and of every other (of a contender, one
/// itself `bound` ahead of the null, over the cycles both lived), if one
/// is. At most one can be.
/// A NaN evidence never leads.
pub fn standing<R: AsRef<[f32]>>(evidence: &[f32], since: &[R], bound: f32) -> Standing {
    (0..evidence.len())
        .map(|i| (i, margin(evidence, since, i, bound)))
        .find(|&(_, m)| m >= bound)
        .map_or(Standing::Searching, |(index, margin)| Standing::Leads { index, margin })
}

/// What became of a proposal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Proposal {
    /// It joined the bank at this index.
    Joined(usize),
    /// A living place (this index) already stands there.
    Held(usize),
    /// The bank is full and none of its places trails the null.
    Refused,
}

/// Why a bank was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlacesError {
    /// The bound is not a finite positive number of nats.
    Bound,
}

/// Up to `K` living places, where each pair's common cycles began, and
/// the test's bound.
#[derive(Clone, Debug)]
pub struct Places<const K: usize> {
    living: Vec<Place, K>,
    /// `since[x][y]`: place `y`'s evidence when the later of `x` and `y`
    /// was born (its own, as proposed, when that was `y`); rows and
    /// columns follow `living`.
    since: [[f32; K]; K],
    bound: f32,
}

impl<const K: usize> Places<K> {
    /// An empty bank deciding at `bound` nats.
    pub fn new(bound: f32) -> Result<Self, PlacesError> {
        if !(bound.is_finite() && bound > 0.0) {
            return Err(PlacesError::Bound);
        }
        Ok(Self { living: Vec::new(), since: [[0.0; K]; K], bound })
    }

    /// The living places.
    pub fn living(&self) -> &[Place] {
        &self.living
    }

    /// Place `a`'s lead over place `b` over the cycles both lived (nats;
    /// NaN when either is not living).
    pub fn lead(&self, a: usize, b: usize) -> f32 {
        self.with_evidence(|e| lead(e, &self.since, a, b))
    }

    /// What the test says now.
    pub fn standing(&self) -> Standing {
        self.with_evidence(|e| standing(e, &self.since, self.bound))
    }

    /// Living place `i`'s smallest lead, over the null and every other as
    /// the test counts it (nats; NaN when `i` is not living). For a viewer:
    /// the test's own [`Places::standing`] reads the same.
    pub fn margin_of(&self, i: usize) -> f32 {
        if i >= self.living.len() {
            return f32::NAN;
        }
        self.with_evidence(|e| margin(e, &self.since, i, self.bound))
    }

    /// The best place's smallest lead, over the null and every other as
    /// the test counts it (nats; at least the bound when one leads); 0 with
    /// no place living, the null alone. Places whose evidence is NaN are
    /// passed over.
    pub fn best_margin(&self) -> f32 {
        self.with_evidence(|e| {
            (0..e.len())
                .map(|i| margin(e, &self.since, i, self.bound))
                .filter(|m| !m.is_nan())
                .fold(None, |b: Option<f32>, m| Some(b.map_or(m, |b| b.max(m))))
                .unwrap_or(0.0)
        })
    }

    fn with_evidence<T>(&self, f: impl FnOnce(&[f32]) -> T) -> T {
        let mut evidence = [0.0f32; K];
        for (e, p) in evidence.iter_mut().zip(&self.living) {
            *e = p.evidence();
        }
        f(evidence.get(..self.living.len()).unwrap_or(&[]))
    }

    /// Forgets every place.
    pub fn clear(&mut self) {
        self.living.clear();
    }

    /// The newcomer in slot `i`: its common cycles with every other start
    /// now, at their evidence and its own.
    fn born(&mut self, i: usize) {
        let own = self.living.get(i).map_or(0.0, Place::evidence);
        let mut row = [0.0f32; K];
        for (j, (r, p)) in (0..K).zip(row.iter_mut().zip(&self.living)) {
            *r = if j == i { own } else { p.evidence() };
        }
        if let Some(r) = self.since.get_mut(i) {
            *r = row;
        }
        for r in &mut self.since {
            if let Some(x) = r.get_mut(i) {
                *x = own;
            }
        }
    }

    /// Keeps the places `keep` says, in order, with their rows and columns.
    fn keep(&mut self, keep: &[bool; K]) {
        let n = self.living.len();
        // Most cycles keep every place: nothing to move.
        if keep.iter().take(n).all(|&k| k) {
            return;
        }
        // Pushed one by one: `collect` into a `heapless::Vec` panics on
        // overflow (it cannot overflow here, `n` ≤ K, but the core has no
        // panic path).
        let mut kept: Vec<usize, K> = Vec::new();
        for i in (0..n).filter(|&i| keep.get(i).copied().unwrap_or(true)) {
            let _ = kept.push(i);
        }
        let mut since = [[0.0f32; K]; K];
        for (row, &x) in since.iter_mut().zip(&kept) {
            for (v, &y) in row.iter_mut().zip(&kept) {
                *v = self.since.get(x).and_then(|r| r.get(y)).copied().unwrap_or(0.0);
            }
        }
        self.since = since;
        // Compacted in place, the write slots from a bounded range: neither
        // `Vec::retain` nor a counter, whose arithmetic keeps overflow
        // checks the optimiser cannot remove (scripts/panic-never.sh).
        let mut slots = 0..K;
        for (r, &k) in (0..n).zip(keep.iter()) {
            if !k {
                continue;
            }
            if let (Some(p), Some(w)) = (self.living.get(r).copied(), slots.next()) {
                if let Some(dst) = self.living.get_mut(w) {
                    *dst = p;
                }
            }
        }
        self.living.truncate(slots.start);
    }

    /// The living place nearest `p` within a metre and 20°, if one is.
    fn nearest(&self, p: &[f32; 3]) -> Option<usize> {
        (0..K)
            .zip(self.living.iter())
            .filter(|(_, q)| within(&q.pose(), p, SAME_PLACE_M, SAME_PLACE_RAD))
            .min_by(|a, b| dist2(&a.1.pose(), p).total_cmp(&dist2(&b.1.pose(), p)))
            .map(|(i, _)| i)
    }

    /// `place` joins: pushed, or in a full bank in the weakest's slot (not
    /// `spare`'s) if `beats` says it may take it. Its index.
    fn join(&mut self, place: Place, spare: Option<usize>, beats: impl Fn(f32) -> bool) -> Option<usize> {
        let i = if self.living.push(place).is_ok() {
            self.living.len().checked_sub(1)?
        } else {
            let (i, q) = (0..K)
                .zip(self.living.iter())
                .filter(|&(i, _)| Some(i) != spare)
                .min_by(|a, b| a.1.evidence().total_cmp(&b.1.evidence()))?;
            if !beats(q.evidence()) {
                return None;
            }
            *self.living.get_mut(i)? = place;
            i
        };
        self.born(i);
        Some(i)
    }

    /// A proposed place (its evidence is taken as it is: a new one's is 0,
    /// the null's level), unless a living place stands within a metre and
    /// 20° of it. A full bank gives it the slot of its weakest place, if
    /// that one trails it.
    pub fn propose(&mut self, place: Place) -> Proposal {
        self.propose_sparing(place, None)
    }

    /// [`Places::propose`], the place at `spare` never giving its slot
    /// (the tracked place: always weighed, its record kept).
    pub fn propose_sparing(&mut self, place: Place, spare: Option<usize>) -> Proposal {
        if let Some(i) = self.nearest(&place.pose()) {
            return Proposal::Held(i);
        }
        let e = place.evidence();
        self.join(place, spare, |weakest| weakest < e).map_or(Proposal::Refused, Proposal::Joined)
    }

    /// [`Places::propose_sparing`], but a proposal beside a living place
    /// (not `spare`), within a metre and 20° of it yet farther than a
    /// merge, that scores `sensed` better than it (both scored from where
    /// they stand, on copies: [`Place::cycle`] without motion) joins as a
    /// place of its own instead of being held: a place strayed beside the
    /// truth no longer keeps the truth out, and the newcomer is weighed
    /// against every other over the cycles both live.
    pub fn propose_beside(
        &mut self,
        place: Place,
        spare: Option<usize>,
        sensed: &[Sensed],
        null: &[f32],
        t: &Tracking<'_>,
    ) -> Proposal {
        let Some(i) = self.nearest(&place.pose()) else { return self.propose_sparing(place, spare) };
        let Some(q) = self.living.get(i).copied() else { return Proposal::Held(i) };
        if Some(i) == spare || within(&q.pose(), &place.pose(), MERGE_M, MERGE_RAD) {
            return Proposal::Held(i);
        }
        let still = Motion { dx: 0.0, dy: 0.0, dphi: 0.0 };
        let score = |mut p: Place| p.cycle(sensed, null, &still, t).map_or(f32::NEG_INFINITY, |c| c.evidence);
        if score(place) <= score(q) {
            return Proposal::Held(i);
        }
        let e = place.evidence();
        self.join(place, spare, |weakest| weakest < e).map_or(Proposal::Refused, Proposal::Joined)
    }

    /// The tracked place (issue #48 item 4): the living place nearest
    /// `place` within a metre and 20° follows it (its pose and covariance,
    /// its own evidence and record kept); with none, `place` joins, in the
    /// weakest's slot when the bank is full whatever that one's evidence
    /// (the tracked pose is always weighed). Its index.
    pub fn anchor(&mut self, place: &Place) -> Option<usize> {
        if let Some(i) = self.nearest(&place.pose()) {
            self.living.get_mut(i)?.moved_to(place);
            return Some(i);
        }
        self.join(*place, None, |_| true)
    }

    /// One ring cycle for every place ([`Place::cycle`]); then the
    /// converged are merged (the longer record kept) and those `bound`
    /// behind the null, or behind another over the cycles both lived,
    /// dropped. A place the odometry would carry out of range is dropped
    /// too. Refused, nothing changed, when `null` is not one score a
    /// reading.
    pub fn cycle(
        &mut self,
        sensed: &[Sensed],
        null: &[f32],
        offset: &Motion,
        t: &Tracking<'_>,
    ) -> Result<Standing, PlaceError> {
        if null.len() != sensed.len() {
            return Err(PlaceError::Mismatch);
        }
        let mut keep = [true; K];
        for (k, p) in keep.iter_mut().zip(self.living.iter_mut()) {
            *k = p.cycle(sensed, null, offset, t).is_ok();
        }
        self.keep(&keep);
        // Merge: of two converged places the one with fewer cycles goes
        // (of two as old, the later one).
        let mut keep = [true; K];
        for (i, (k, a)) in (0..K).zip(keep.iter_mut().zip(&self.living)) {
            *k = !(0..K).zip(self.living.iter()).any(|(j, b)| {
                j != i
                    && within(&a.pose(), &b.pose(), MERGE_M, MERGE_RAD)
                    && (b.cycles() > a.cycles() || (b.cycles() == a.cycles() && j < i))
            });
        }
        self.keep(&keep);
        // The null stands at 0: a place the bound behind it, or behind
        // another over their common cycles, is dropped.
        let bound = self.bound;
        let mut keep = [true; K];
        self.with_evidence(|e| {
            for (i, k) in (0..e.len()).zip(keep.iter_mut()) {
                let behind = e.get(i).is_some_and(|&x| x <= -bound)
                    || (0..e.len()).any(|j| j != i && lead(e, &self.since, j, i) >= bound);
                *k = !behind;
            }
        });
        self.keep(&keep);
        Ok(self.standing())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::localize::{BeamModel, FieldLookup};
    use crate::map::FieldView;
    use crate::referencing::{EkfConfig, Reading};

    fn place(x: f32, y: f32, phi: f32) -> Place {
        Place::new([x, y, phi], [0.1, 0.1, 0.05], &EkfConfig::DEFAULT).unwrap()
    }

    /// The test by hand: the leader against the null (0) and the next.
    #[test]
    fn standing_by_hand() {
        let z = [[0.0f32; 3]; 3];
        assert_eq!(standing(&[], &z, 150.0), Standing::Searching);
        assert_eq!(standing(&[150.0], &z, 150.0), Standing::Leads { index: 0, margin: 150.0 });
        assert_eq!(standing(&[149.9], &z, 150.0), Standing::Searching);
        assert_eq!(standing(&[-10.0, 200.0, 40.0], &z, 150.0), Standing::Leads { index: 1, margin: 160.0 });
        assert_eq!(standing(&[200.0, 200.0], &z, 150.0), Standing::Searching);
        assert_eq!(standing(&[f32::NAN, 160.0], &z, 150.0), Standing::Leads { index: 1, margin: 160.0 });
        assert_eq!(standing(&[f32::NAN], &z, 1.0), Standing::Searching);
    }

    /// The leads over the cycles both lived, by hand: place 1 was born
    /// when place 0 had 500, place 2 when 0 had 600 and 1 had 40.
    #[test]
    fn leads_over_the_common_cycles_by_hand() {
        let since = [[0.0f32, 0.0, 0.0], [500.0, 0.0, 0.0], [600.0, 40.0, 0.0]];
        let e = [700.0, 250.0, 30.0];
        // 0 over 1 since 1's birth: (700 − 500) − 250; and the other way.
        assert_eq!(lead(&e, &since, 0, 1), -50.0);
        assert_eq!(lead(&e, &since, 1, 0), 50.0);
        // 1 over 2 since 2's birth: (250 − 40) − 30.
        assert_eq!(lead(&e, &since, 1, 2), 180.0);
        assert_eq!(lead(&e, &since, 0, 2), 70.0);
        // Place 1 is a contender (250 ≥ 150) and level-ish with 0 since its
        // birth: nobody leads, though 0 has 450 more evidence.
        assert_eq!(standing(&e, &since, 150.0), Standing::Searching);
        // At bound 300, 1 is not a contender: 0 leads it by 450 in evidence
        // and the lesser 2 by 670, the null by 700; 450 is the margin.
        assert_eq!(standing(&e, &since, 300.0), Standing::Leads { index: 0, margin: 450.0 });
    }

    #[test]
    fn a_bad_bound_is_refused() {
        for b in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert_eq!(Places::<4>::new(b).err(), Some(PlacesError::Bound), "{b}");
        }
    }

    /// Without a field every place stands off it: each echo costs it the
    /// clip (2 nats: ln 0.01 against the null's −1 is −3.6, clipped), so
    /// its evidence is known by hand.
    #[test]
    fn proposals_held_joined_and_replaced_and_drops_at_the_bound() {
        let field = FieldView::EMPTY;
        let lookup = FieldLookup::new(&field);
        let cfg = EkfConfig::DEFAULT;
        let t = Tracking { lookup: &lookup, beam: &BeamModel::DEFAULT, ekf: &cfg, clip: 2.0, hit_share: 0.5 };
        let echo = Sensed { pose: [0.0; 3], reading: Reading::Echo { range_mm: 1500 } };
        let mut bank = Places::<2>::new(5.0).unwrap();
        assert_eq!(bank.propose(place(0.0, 0.0, 0.0)), Proposal::Joined(0));
        assert_eq!(bank.propose(place(0.5, 0.5, 0.2)), Proposal::Held(0));
        assert_eq!(bank.propose(place(5.0, 0.0, 0.0)), Proposal::Joined(1));
        // Full, and no place trails the null: refused.
        assert_eq!(bank.propose(place(9.0, 0.0, 0.0)), Proposal::Refused);
        // One echo: both at −2, within the bound 5 of the null: kept.
        let s = bank.cycle(&[echo], &[-1.0], &Motion::default(), &t).unwrap();
        assert_eq!(s, Standing::Searching);
        assert_eq!(bank.living().iter().map(Place::evidence).collect::<heapless::Vec<f32, 2>>(), [-2.0, -2.0]);
        // Now a new place (at the null's level) takes the weakest's slot.
        assert_eq!(bank.propose(place(9.0, 0.0, 0.0)), Proposal::Joined(0));
        assert_eq!(bank.living()[0].pose(), [9.0, 0.0, 0.0]);
        // Two more echoes: the old place at −6, 6 behind the null: dropped;
        // the new one at −4 stays.
        bank.cycle(&[echo, echo], &[-1.0, -1.0], &Motion::default(), &t).unwrap();
        assert_eq!(bank.living().len(), 1);
        assert_eq!((bank.living()[0].pose(), bank.living()[0].evidence()), ([9.0, 0.0, 0.0], -4.0));
        // Null scores not one a reading: refused, nothing changed.
        assert_eq!(bank.cycle(&[echo], &[], &Motion::default(), &t), Err(PlaceError::Mismatch));
        assert_eq!(bank.living()[0].evidence(), -4.0);
    }

    /// The truth proposed after an alias has led the null for 400 nats
    /// joins at the null's level: the bound (150) behind the alias on the
    /// whole record, level with it on the cycles both lived. It stays (on
    /// the whole record it was dropped at once), and the alias, ahead of a
    /// place not yet past the null, still leads; when the newcomer passes
    /// the null by the bound and stays level with the alias since its
    /// birth, nobody leads.
    #[test]
    fn a_place_proposed_late_is_judged_on_the_cycles_it_lived() {
        let field = FieldView::EMPTY;
        let lookup = FieldLookup::new(&field);
        let cfg = EkfConfig::DEFAULT;
        let t = Tracking { lookup: &lookup, beam: &BeamModel::DEFAULT, ekf: &cfg, clip: 2.0, hit_share: 0.5 };
        let mut bank = Places::<4>::new(150.0).unwrap();
        assert_eq!(bank.propose(place(0.0, 0.0, 0.0).with_evidence(400.0)), Proposal::Joined(0));
        assert_eq!(bank.propose(place(5.0, 0.0, 0.0)), Proposal::Joined(1));
        assert_eq!(bank.since[1][0], 400.0);
        assert_eq!(bank.lead(0, 1), 0.0);
        let s = bank.cycle(&[], &[], &Motion::default(), &t).unwrap();
        assert_eq!(bank.living().len(), 2);
        assert_eq!(s, Standing::Leads { index: 0, margin: 400.0 });
        // What a viewer is told of each, by hand: the leader's 400 over the
        // null and the newcomer; the newcomer level with it since its birth.
        assert_eq!((bank.margin_of(0), bank.margin_of(1)), (400.0, 0.0));
        assert!(bank.margin_of(2).is_nan());
        // Both gain the same 200 (set by hand): the newcomer is a
        // contender, level with the alias since its birth.
        bank.living[0] = bank.living[0].with_evidence(600.0);
        bank.living[1] = bank.living[1].with_evidence(200.0);
        assert_eq!(bank.standing(), Standing::Searching);
        assert_eq!((bank.margin_of(0), bank.margin_of(1), bank.best_margin()), (0.0, 0.0, 0.0));
        // A third, born now, records both.
        assert_eq!(bank.propose(place(9.0, 0.0, 0.0)), Proposal::Joined(2));
        assert_eq!(bank.since[2][..3], [600.0, 200.0, 0.0]);
        assert_eq!(bank.since[0][2], 0.0);
        // One proposed with evidence (taken as it is) gains from there.
        assert_eq!(bank.propose(place(20.0, 0.0, 0.0).with_evidence(50.0)), Proposal::Joined(3));
        assert_eq!((bank.since[0][3], bank.since[3][0]), (50.0, 600.0));
        bank.living[3] = bank.living[3].with_evidence(80.0);
        assert_eq!(bank.lead(3, 0), 30.0);
        // The first dropped: rows and columns follow (the second's record
        // of it goes; the third's of the second stays).
        bank.keep(&[false, true, true, true]);
        assert_eq!(bank.since[0][..2], [0.0, 0.0]);
        assert_eq!(bank.since[1][..2], [200.0, 0.0]);
    }

    /// The tracked place, by hand: the nearest living place within a
    /// metre and 20° follows the EKF (its evidence and record kept); with
    /// none it joins, in a full bank in the weakest's slot even when every
    /// place leads the null.
    #[test]
    fn the_tracked_place_follows_the_ekf_or_joins() {
        let mut bank = Places::<2>::new(150.0).unwrap();
        bank.living.push(place(0.0, 0.0, 0.0).with_evidence(40.0)).unwrap();
        bank.living.push(place(0.8, 0.0, 0.0).with_evidence(10.0)).unwrap();
        // 0.5 m from the first, 0.3 m from the second: the second follows.
        let ekf = Place::new([0.5, 0.0, 0.1], [0.02, 0.02, 0.01], &EkfConfig::DEFAULT).unwrap();
        assert_eq!(bank.anchor(&ekf), Some(1));
        let q = bank.living()[1];
        assert_eq!((q.pose(), q.covariance(), q.evidence()), (ekf.pose(), ekf.covariance(), 10.0));
        assert_eq!(bank.living()[0].pose(), [0.0, 0.0, 0.0]);
        // Far from both in a full bank where both lead the null: the weaker
        // one's slot, the newcomer at the null's level and born now.
        bank.living[0] = bank.living[0].with_evidence(60.0);
        let far = place(9.0, 0.0, 0.0);
        assert_eq!(bank.anchor(&far), Some(1));
        assert_eq!((bank.living()[1].pose(), bank.living()[1].evidence()), ([9.0, 0.0, 0.0], 0.0));
        assert_eq!((bank.since[1][0], bank.since[0][1]), (60.0, 0.0));
        // The tracked slot, the weakest, is spared by a proposal: refused
        // (the other leads it); not spared, the proposal takes it.
        let newcomer = place(20.0, 0.0, 0.0).with_evidence(5.0);
        assert_eq!(bank.propose_sparing(newcomer, Some(1)), Proposal::Refused);
        assert_eq!(bank.living()[1].pose(), [9.0, 0.0, 0.0]);
        assert_eq!(bank.propose(newcomer), Proposal::Joined(1));
        // Turned by 30° where it stands: not the same place, it joins.
        let mut bank = Places::<2>::new(150.0).unwrap();
        bank.living.push(place(0.0, 0.0, 0.0)).unwrap();
        assert_eq!(bank.anchor(&place(0.0, 0.0, 30f32.to_radians())), Some(1));
        assert_eq!(bank.living().len(), 2);
    }

    /// Two places that converged are one: the longer record stays, of two
    /// as long the first; places 0.3 m or 6° apart stay two.
    #[test]
    fn converged_places_merge_keeping_the_longer_record() {
        let field = FieldView::EMPTY;
        let lookup = FieldLookup::new(&field);
        let cfg = EkfConfig::DEFAULT;
        let t = Tracking { lookup: &lookup, beam: &BeamModel::DEFAULT, ekf: &cfg, clip: 2.0, hit_share: 0.5 };
        let still = Motion::default();
        let mut old = place(0.1, 0.0, 0.0);
        old.cycle(&[], &[], &still, &t).unwrap();
        let mut bank = Places::<4>::new(150.0).unwrap();
        // Placed directly: a proposal this near would be held.
        for p in [place(0.0, 0.0, 0.0), old, place(3.0, 0.0, 0.0), place(3.0, 0.3, 0.0)] {
            bank.living.push(p).unwrap();
        }
        bank.cycle(&[], &[], &still, &t).unwrap();
        let poses: heapless::Vec<[f32; 3], 4> = bank.living().iter().map(Place::pose).collect();
        assert_eq!(poses, [[0.1, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 0.3, 0.0]]);
        assert_eq!(bank.living()[0].cycles(), 2);
        // Same age, 4° apart: the first stays; 6° apart: both.
        let mut bank = Places::<4>::new(150.0).unwrap();
        for p in [
            place(0.0, 0.0, 0.0),
            place(0.0, 0.0, 4f32.to_radians()),
            place(5.0, 0.0, 0.0),
            place(5.0, 0.0, 6f32.to_radians()),
        ] {
            bank.living.push(p).unwrap();
        }
        bank.cycle(&[], &[], &still, &t).unwrap();
        let phis: heapless::Vec<f32, 4> = bank.living().iter().map(|p| p.pose()[2]).collect();
        assert_eq!(phis, [0.0, 0.0, 6f32.to_radians()]);
    }
}
