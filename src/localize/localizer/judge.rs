//! The hand-off decided by the sequential test (issue #48, DESIGN §4.8):
//! the particles' heaviest cluster and the sweep's best places are only
//! proposals; each joins a bank of places that track themselves
//! ([`Places`]), and the search hands off to the one that leads the null
//! and every other by the test's bound.

use heapless::Vec;

use super::super::beam::BeamModel;
use super::super::expect::FieldLookup;
use super::super::measure::Sensed;
use super::super::null::NullModel;
use super::super::particles::Cluster;
use super::super::place::{Place, PlaceError, Tracking};
use super::super::places::{Places, Standing};
use super::super::scan::Candidate;
use super::config::{PlaceTest, MAX_SENSED, PLACES};
use super::error::LocalizeError;
use crate::referencing::{EkfConfig, Motion};

/// The test's state: the living places and the null.
#[derive(Clone, Debug)]
pub(super) struct Judge {
    pub(super) places: Places<PLACES>,
    null: NullModel,
}

impl Judge {
    /// An empty bank and a null that has heard nothing, for `test` over
    /// `beam`'s window. Refused ([`LocalizeError::PlaceTest`]): a bound
    /// that is not a finite positive number, a null memory the null
    /// refuses.
    pub(super) fn new(test: &PlaceTest, beam: &BeamModel) -> Result<Self, LocalizeError> {
        let places = Places::new(test.bound).map_err(|_| LocalizeError::PlaceTest)?;
        let null =
            NullModel::new(beam.r_min_mm, beam.r_max_mm, test.null_memory).map_err(|_| LocalizeError::PlaceTest)?;
        Ok(Self { places, null })
    }

    /// One ring cycle (`sensed` relative to the cycle's start, `offset`
    /// its odometry): the cluster (at the cycle's start) and the sweep's
    /// best `candidates` proposed, then every place corrected, scored,
    /// merged or dropped and carried to the next cycle's start. The
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
        cluster: Option<&Cluster>,
        candidates: &[Candidate],
        lookup: &FieldLookup<'_, '_>,
        beam: &BeamModel,
        ekf: &EkfConfig,
    ) -> Result<Standing, LocalizeError> {
        // The null scores each reading before the places do.
        let mut nulls: Vec<f32, MAX_SENSED> = Vec::new();
        for s in sensed {
            // `sensed` holds at most MAX_SENSED: this never refuses.
            let _ = nulls.push(self.null.log_likelihood(s.reading));
        }
        if let Some(c) = cluster.filter(|c| c.weight >= test.cluster_weight) {
            let p = &c.covariance;
            let mut sigma = [0.0f32; 3];
            for (i, (s, f)) in (0..3).zip(sigma.iter_mut().zip(test.floor)) {
                let v = p.get(i).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
                *s = crate::f32math::sqrt(v.max(f * f));
            }
            if let Ok(place) = Place::new(c.mean, sigma, ekf) {
                self.places.propose(place);
            }
        }
        for cand in candidates.iter().take(usize::from(test.proposals)) {
            if let Ok(place) = Place::new(cand.pose, test.sweep_sigma, ekf) {
                self.places.propose(place);
            }
        }
        let t = Tracking { lookup, beam, ekf, clip: test.clip, hit_share: test.hit_share };
        self.places.cycle(sensed, &nulls, offset, &t).map_err(|e| match e {
            PlaceError::Filter(e) => LocalizeError::Ekf(e),
            // One null score a reading, by construction above.
            PlaceError::Mismatch => LocalizeError::PlaceTest,
        })
    }

    /// Forgets every place (the null keeps what it heard: the readings'
    /// mix does not depend on where the robot is thought to be).
    pub(super) fn clear(&mut self) {
        self.places.clear();
    }
}
