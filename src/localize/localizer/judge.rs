//! The hand-off decided by the sequential test (issue #48, DESIGN §4.8):
//! the particles' heaviest cluster and the sweep's best places are only
//! proposals; each joins a bank of places that track themselves
//! ([`Places`]), and the search hands off to the one that leads the null
//! and every other by the test's bound.
//!
//! While tracking, the tracked pose is judged against the null as a place
//! (item 4): each cycle a place at the EKF's pose and covariance (at the
//! cycle's start) scores the cycle's readings, and Page's CUSUM of the
//! null's lead over it, `behind = max(0, behind − evidence)`, says *lost*
//! when it reaches the bound. A sum since the hand-off would not do: a
//! long right track banks thousands of nats that a kidnap would have to
//! spend before the test noticed; the CUSUM is Wald's test restarted
//! whenever the tracked place is ahead (Page 1954), so it notices a
//! change after the bound's worth of evidence whenever it comes. After a
//! wake-up (by the CUSUM, the EKF's gate or the fit monitor) the EKF goes
//! on beside the search: its pose is proposed as a place every cycle, the
//! CUSUM goes on, and the search ends without a hand-off (a calm) only
//! while the EKF is not behind the null.
//!
//! With rivals (`PlaceTest::rival_nodes`) the places go on while tracking
//! and through a wake-up, the EKF's own place among them (anchored to it):
//! a slow sweep proposes more, and a place away from the EKF that leads
//! it, the null and every other by the bound takes over.

use heapless::Vec;

use super::super::beam::BeamModel;
use super::super::expect::FieldLookup;
use super::super::measure::Sensed;
use super::super::null::NullModel;
use super::super::particles::Cluster;
use super::super::place::{Place, PlaceError, Tracking};
use super::super::places::{Places, Standing};
use super::super::scan::Candidate;
use super::super::{within, SAME_PLACE_M, SAME_PLACE_RAD};
use super::config::{PlaceTest, MAX_SENSED, PLACES};
use super::error::LocalizeError;
use super::monitor::back_to_start;
use crate::referencing::{Ekf, EkfConfig, Motion};

/// A cycle's readings, the null's score of each and the shared model: what
/// a proposal is scored on before it joins beside a place.
type Scored<'a> = (&'a [Sensed], &'a [f32], Tracking<'a>);

/// A place's refusal as the localizer's.
fn place_error(e: PlaceError) -> LocalizeError {
    match e {
        PlaceError::Filter(e) => LocalizeError::Ekf(e),
        // One null score a reading, by construction in the judge.
        PlaceError::Mismatch => LocalizeError::PlaceTest,
    }
}

/// What the test says of the tracked pose at a tracking cycle's end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Judged {
    /// It holds: not the bound behind the null, and no rival leads.
    Holds,
    /// The null leads it by the bound: *lost*.
    Lost,
    /// A rival leads it, the null and every other by the bound: the EKF
    /// starts there (its pose and covariance at the next cycle's start).
    Overtaken([f32; 3], [[f32; 3]; 3]),
}

/// The test's state: the living places, the null, and how far the tracked
/// pose trails the null.
#[derive(Clone, Debug)]
pub(super) struct Judge {
    pub(super) places: Places<PLACES>,
    null: NullModel,
    /// While tracking: the null's CUSUM lead over the tracked pose, nats
    /// (at least 0; *lost* at the bound).
    pub(super) behind: f32,
}

impl Judge {
    /// An empty bank and a null that has heard nothing, for `test` over
    /// `beam`'s window. Refused ([`LocalizeError::PlaceTest`]): a bound
    /// that is not a finite positive number, a calm's `calm_behind` not in
    /// `0..bound`, a hit share not in `(0, 1)`, a clip that is not a finite
    /// positive number, a cluster weight not in `[0, 1]`, a proposal's σ
    /// or floor that is negative or not finite, a null memory the null
    /// refuses.
    pub(super) fn new(test: &PlaceTest, beam: &BeamModel) -> Result<Self, LocalizeError> {
        // Each comparison is also false for NaN. Left through, a NaN σ
        // would never propose a place (no hand-off, ever) and a hit share
        // of 1 would let a missed echo correct a place.
        let fine = test.calm_behind >= 0.0
            && test.calm_behind < test.bound
            && test.hit_share > 0.0
            && test.hit_share < 1.0
            && test.clip > 0.0
            && test.clip.is_finite()
            && test.cluster_weight >= 0.0
            && test.cluster_weight <= 1.0
            && test.sweep_sigma.iter().chain(&test.floor).all(|s| *s >= 0.0 && s.is_finite());
        if !fine {
            return Err(LocalizeError::PlaceTest);
        }
        let places = Places::new(test.bound).map_err(|_| LocalizeError::PlaceTest)?;
        let null =
            NullModel::new(beam.r_min_mm, beam.r_max_mm, test.null_memory).map_err(|_| LocalizeError::PlaceTest)?;
        Ok(Self { places, null, behind: 0.0 })
    }

    /// The null's score of each reading of the cycle, in order (then
    /// counted by the null).
    fn nulls(&mut self, sensed: &[Sensed]) -> Vec<f32, MAX_SENSED> {
        let mut nulls: Vec<f32, MAX_SENSED> = Vec::new();
        for s in sensed {
            // `sensed` holds at most MAX_SENSED: this never refuses.
            let _ = nulls.push(self.null.log_likelihood(s.reading));
        }
        nulls
    }

    /// One tracking cycle: the tracked pose (`tracked`: the EKF and the
    /// odometry since the cycle's start, so its pose at the cycle's start
    /// with its covariance) scores `sensed` as a place would, and the
    /// null's CUSUM lead over it moves by the evidence: *lost* when it has
    /// reached the bound. With rivals (`test.rival_nodes`), the tracked
    /// pose is then one of the places ([`Places::anchor`]), the sweep's
    /// best `candidates` are proposed, every place takes the cycle, and a
    /// place away from the EKF (`offset` carries them to the next cycle's
    /// start, where the EKF is) that leads takes over. Kept out of line:
    /// its frame is the tracking cycle's end's alone.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn track(
        &mut self,
        test: &PlaceTest,
        sensed: &[Sensed],
        offset: &Motion,
        tracked: (&Ekf, &[f32; 3]),
        candidates: &[Candidate],
        lookup: &FieldLookup<'_, '_>,
        beam: &BeamModel,
    ) -> Result<Judged, LocalizeError> {
        let ekf = tracked.0.config();
        let standing = if test.rival_nodes == 0 {
            let nulls = self.nulls(sensed);
            let t = Tracking { lookup, beam, ekf, clip: test.clip, hit_share: test.hit_share };
            self.score_tracked(sensed, &nulls, tracked, &t);
            Standing::Searching
        } else {
            self.weigh(test, sensed, offset, Some(tracked), true, None, candidates, lookup, beam, ekf)?
        };
        if self.behind >= test.bound {
            return Ok(Judged::Lost);
        }
        let Standing::Leads { index, .. } = standing else { return Ok(Judged::Holds) };
        let Some(leader) = self.places.living().get(index) else { return Ok(Judged::Holds) };
        Ok(if within(&leader.pose(), &tracked.0.state(), SAME_PLACE_M, SAME_PLACE_RAD) {
            Judged::Holds
        } else {
            Judged::Overtaken(leader.pose(), leader.covariance())
        })
    }

    /// The sweep's best places proposed (σ `sweep_sigma`; one refused
    /// silently when not finite), none given the tracked place's slot,
    /// `spare`.
    fn propose_sweep(&mut self, test: &PlaceTest, candidates: &[Candidate], spare: Option<usize>, scored: &Scored<'_>) {
        for cand in candidates.iter().take(usize::from(test.proposals)) {
            if let Ok(place) = Place::new(cand.pose, test.sweep_sigma, scored.2.ekf) {
                self.propose(test, place, spare, scored);
            }
        }
    }

    /// `place` proposed; with `test.join_beside` it joins beside a living
    /// place it scores the cycle better than.
    fn propose(&mut self, test: &PlaceTest, place: Place, spare: Option<usize>, (sensed, nulls, t): &Scored<'_>) {
        if test.join_beside {
            self.places.propose_beside(place, spare, sensed, nulls, t);
        } else {
            self.places.propose_sparing(place, spare);
        }
    }

    /// The tracked pose scores the cycle as a place (a pose the place
    /// refuses, not finite or out of range, says nothing: the EKF refuses
    /// it on its own), and the CUSUM moves; the place itself, for the
    /// bank while the EKF runs beside the search.
    fn score_tracked(
        &mut self,
        sensed: &[Sensed],
        nulls: &[f32],
        (e, offset): (&Ekf, &[f32; 3]),
        t: &Tracking<'_>,
    ) -> Option<Place> {
        let place = Place::with_covariance(back_to_start(&e.state(), offset), e.covariance(), t.ekf).ok()?;
        let still = Motion { dx: 0.0, dy: 0.0, dphi: 0.0 };
        let mut scored = place;
        let evidence = scored.cycle(sensed, nulls, &still, t).map_or(0.0, |c| c.evidence);
        self.behind = (self.behind - evidence).max(0.0);
        Some(place)
    }

    /// One ring cycle (`sensed` relative to the cycle's start, `offset`
    /// its odometry): `awake` (the EKF and the odometry since the cycle's
    /// start, while it runs beside the search after a wake-up: its pose at
    /// the cycle's start with its covariance), the cluster (at the cycle's
    /// start) and the sweep's best `candidates` proposed, then every place
    /// corrected, scored, merged or dropped and carried to the next
    /// cycle's start. The
    /// proposals' σ are refused silently when not finite (nothing is
    /// proposed); a place the odometry carries out of range is dropped.
    /// Kept out of line: its frame is the searching cycle's alone.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn cycle(
        &mut self,
        test: &PlaceTest,
        sensed: &[Sensed],
        offset: &Motion,
        awake: Option<(&Ekf, &[f32; 3])>,
        cluster: Option<&Cluster>,
        candidates: &[Candidate],
        lookup: &FieldLookup<'_, '_>,
        beam: &BeamModel,
        ekf: &EkfConfig,
    ) -> Result<Standing, LocalizeError> {
        // With rivals the awake EKF's place follows it through the search
        // too: else it strays on its own from the pose the EKF keeps, and
        // its banked lead hands off to where it strayed.
        self.weigh(test, sensed, offset, awake, test.rival_nodes > 0, cluster, candidates, lookup, beam, ekf)
    }

    /// The cycle of [`Judge::cycle`]; with `anchored` (rivals: while
    /// tracking, or beside the search after a wake-up) the EKF's place is
    /// the tracked one, anchored to it and never giving its slot to a
    /// proposal.
    #[allow(clippy::too_many_arguments)]
    fn weigh(
        &mut self,
        test: &PlaceTest,
        sensed: &[Sensed],
        offset: &Motion,
        awake: Option<(&Ekf, &[f32; 3])>,
        anchored: bool,
        cluster: Option<&Cluster>,
        candidates: &[Candidate],
        lookup: &FieldLookup<'_, '_>,
        beam: &BeamModel,
        ekf: &EkfConfig,
    ) -> Result<Standing, LocalizeError> {
        // The null scores each reading before the places do.
        let nulls = self.nulls(sensed);
        let t = Tracking { lookup, beam, ekf, clip: test.clip, hit_share: test.hit_share };
        // The EKF (beside the search, or tracking) goes on being judged, and is a place.
        let mut spare = None;
        if let Some(place) = awake.and_then(|tracked| self.score_tracked(sensed, &nulls, tracked, &t)) {
            if anchored {
                spare = self.places.anchor(&place);
            } else {
                self.propose(test, place, None, &(sensed, &nulls, t));
            }
        }
        if let Some(c) = cluster.filter(|c| c.weight >= test.cluster_weight) {
            let p = &c.covariance;
            let mut sigma = [0.0f32; 3];
            for (i, (s, f)) in (0..3).zip(sigma.iter_mut().zip(test.floor)) {
                let v = p.get(i).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
                *s = crate::f32math::sqrt(v.max(f * f));
            }
            if let Ok(place) = Place::new(c.mean, sigma, ekf) {
                self.propose(test, place, spare, &(sensed, &nulls, t));
            }
        }
        self.propose_sweep(test, candidates, spare, &(sensed, &nulls, t));
        self.places.cycle(sensed, &nulls, offset, &t).map_err(place_error)
    }

    /// At a hand-off, a calm or a wake-up: forgets every place, unless
    /// they are rivals (`rival_nodes`), which go on through all three (the
    /// null keeps what it heard: the readings' mix does not depend on
    /// where the robot is thought to be; the CUSUM goes on judging the
    /// EKF, which a wake-up does not move).
    pub(super) fn clear(&mut self, test: &PlaceTest) {
        if test.rival_nodes == 0 {
            self.places.clear();
        }
    }
}
