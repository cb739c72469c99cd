//! The living places and the sequential test between them and the null
//! (DESIGN §4.8, issue #48): a fixed bank of [`Place`]s, each tracking
//! itself, each with its evidence over the null hypothesis since it was
//! born. Not yet wired into the localizer.
//!
//! - **Proposals** (the particles' cluster, the sweep's places) join the
//!   bank at the null's level (evidence 0: before it was born, the place
//!   was part of "none of these"), unless a living place stands within
//!   a metre and 20° of it (that place
//!   already follows it); a full bank gives the slot of its weakest place
//!   only if that one trails the null.
//! - **Every cycle** each place scores the readings and corrects itself
//!   ([`Place::cycle`]); two that converged (within [`MERGE_M`] and
//!   [`MERGE_RAD`]) become one, the longer record kept; a place that
//!   trails the leader, or the null, by the bound is dropped.
//! - **The test**: a place leads when it is ahead of the null and of every
//!   other living place by the bound ([`Standing::Leads`]); otherwise the
//!   answer is *searching*, for as long as it takes. The bound is the
//!   summed, clipped log-ratio a wrong place never reached over the truth
//!   and the null on the simulator (docs/localization.md: 150 nats).
//!
//! ```
//! use echoloc::localize::places::{standing, Standing};
//!
//! // Evidence over the null of three living places, the bound 150 nats.
//! assert_eq!(standing(&[420.0, 180.0, -30.0], 150.0), Standing::Leads { index: 0, margin: 240.0 });
//! // Ahead of the null but not of its rival by the bound: searching.
//! assert_eq!(standing(&[420.0, 300.0], 150.0), Standing::Searching);
//! // Ahead of every rival but not of the null: searching.
//! assert_eq!(standing(&[120.0, -200.0], 150.0), Standing::Searching);
//! ```

use heapless::Vec;

use super::measure::Sensed;
use super::place::{Place, PlaceError, Tracking};
use super::{within, SAME_PLACE_M, SAME_PLACE_RAD};
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

/// The test on the living places' evidence (each over the null, which
/// stands at 0): the leader, if it is at least `bound` ahead of the null
/// and of every other place. A NaN evidence never leads.
pub fn standing(evidence: &[f32], bound: f32) -> Standing {
    let mut best: Option<(usize, f32)> = None;
    let mut second = 0.0f32; // the null
    for (i, &e) in evidence.iter().enumerate() {
        if e.is_nan() {
            continue;
        }
        match best {
            Some((_, b)) if e <= b => second = second.max(e),
            Some((_, b)) => {
                second = second.max(b);
                best = Some((i, e));
            }
            None => best = Some((i, e)),
        }
    }
    match best {
        Some((index, e)) if e - second >= bound => Standing::Leads { index, margin: e - second },
        _ => Standing::Searching,
    }
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

/// Up to `K` living places and the test's bound.
#[derive(Clone, Debug)]
pub struct Places<const K: usize> {
    living: Vec<Place, K>,
    bound: f32,
}

impl<const K: usize> Places<K> {
    /// An empty bank deciding at `bound` nats.
    pub fn new(bound: f32) -> Result<Self, PlacesError> {
        if !(bound.is_finite() && bound > 0.0) {
            return Err(PlacesError::Bound);
        }
        Ok(Self { living: Vec::new(), bound })
    }

    /// The living places.
    pub fn living(&self) -> &[Place] {
        &self.living
    }

    /// Forgets every place.
    pub fn clear(&mut self) {
        self.living.clear();
    }

    /// A proposed place (its evidence is taken as it is: a new one's is 0,
    /// the null's level).
    pub fn propose(&mut self, place: Place) -> Proposal {
        let p = place.pose();
        if let Some(i) = self.living.iter().position(|q| within(&q.pose(), &p, SAME_PLACE_M, SAME_PLACE_RAD)) {
            return Proposal::Held(i);
        }
        if self.living.push(place).is_ok() {
            return Proposal::Joined(self.living.len() - 1);
        }
        let weakest = self
            .living
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.evidence().total_cmp(&b.1.evidence()))
            .map(|(i, q)| (i, q.evidence()));
        match weakest {
            Some((i, e)) if e < place.evidence() => {
                if let Some(slot) = self.living.get_mut(i) {
                    *slot = place;
                }
                Proposal::Joined(i)
            }
            _ => Proposal::Refused,
        }
    }

    /// One ring cycle for every place ([`Place::cycle`]); then the
    /// converged are merged (the longer record kept) and those `bound`
    /// behind the leader or the null dropped. A place the odometry would
    /// carry out of range is dropped too. Refused, nothing changed, when
    /// `null` is not one score a reading.
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
        self.living.retain_mut(|p| p.cycle(sensed, null, offset, t).is_ok());
        // Merge: of two converged places the one with fewer cycles goes
        // (of two as old, the later one).
        let mut keep = [true; K];
        for (i, (k, a)) in keep.iter_mut().zip(&self.living).enumerate() {
            *k = !self.living.iter().enumerate().any(|(j, b)| {
                j != i
                    && within(&a.pose(), &b.pose(), MERGE_M, MERGE_RAD)
                    && (b.cycles() > a.cycles() || (b.cycles() == a.cycles() && j < i))
            });
        }
        let mut n = 0;
        self.living.retain(|_| {
            let k = keep.get(n).copied().unwrap_or(true);
            n += 1;
            k
        });
        // The null stands at 0: a place the bound behind the best of the
        // null and the others is dropped.
        let top = self.living.iter().map(Place::evidence).fold(0.0f32, f32::max);
        let bound = self.bound;
        self.living.retain(|p| p.evidence() > top - bound);
        let mut evidence = [0.0f32; K];
        for (e, p) in evidence.iter_mut().zip(&self.living) {
            *e = p.evidence();
        }
        Ok(standing(&evidence[..self.living.len()], bound))
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
        assert_eq!(standing(&[], 150.0), Standing::Searching);
        assert_eq!(standing(&[150.0], 150.0), Standing::Leads { index: 0, margin: 150.0 });
        assert_eq!(standing(&[149.9], 150.0), Standing::Searching);
        assert_eq!(standing(&[-10.0, 200.0, 40.0], 150.0), Standing::Leads { index: 1, margin: 160.0 });
        assert_eq!(standing(&[200.0, 200.0], 150.0), Standing::Searching);
        assert_eq!(standing(&[f32::NAN, 160.0], 150.0), Standing::Leads { index: 1, margin: 160.0 });
        assert_eq!(standing(&[f32::NAN], 1.0), Standing::Searching);
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
