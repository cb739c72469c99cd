//! Finding itself (DESIGN §4.8): Monte Carlo localization in fixed memory,
//! for a robot that starts anywhere, was carried, or followed clutter away,
//! and the localizer that hands off between the particles and the EKF.
//!
//! | module | what it does |
//! |---|---|
//! | [`localizer`] | [`Localizer`]: *searching*, *tracking*, *lost*; the hand-off to the EKF and the particles' wake-up |
//! | [`particles`] | [`ParticleSet`]: `N` particles, weighing, low-variance resampling in place, KLD sampling, augmented MCL, the heaviest cluster |
//! | [`beam`] | [`BeamModel`]: the sonar's measurement model (hit, short, miss, random) |
//! | [`expect`] | [`FieldLookup`]: what a transducer anywhere should hear, from the compiled map's field |
//! | [`measure`] | [`Measure`]: how well a cycle's readings ([`Sensed`]) fit a pose, the beam model on the field: what the particles, the history and the fit monitor score by |
//! | [`scan`] | [`Sweep`]: the search's proposals, every heading of a sweep of free nodes scored cheaply against the cycle's readings |
//! | [`history`] | [`History`]: the last cycles' readings in the current frame, to verify the search's proposals on |
//! | [`hypotheses`] | [`Bank`]: the places still plausible besides the cluster, each with the cluster's lead over it summed since it was proposed; the hand-off's margin |
//! | [`place`] | [`Place`]: a place that tracks itself, its own Kalman filter corrected by the field's plane ranges and gradients, with its evidence over the null since it was born |
//! | [`places`] | [`Places`]: the living places and the sequential test between them and the null: proposals, merges, drops, the leader |
//! | [`null`] | [`NullModel`]: the null hypothesis, "none of these places": the readings scored by their own recent mix |
//! | [`sprt`] | [`Sprt`]: Wald's sequential test on the evidence between two hypotheses, each reading's share clipped |
//! | [`rng`] | [`Rng`]: xoshiro128++, uniform and approximately normal draws |
//!
//! Everything is `f32`, allocation-free, and held by the caller: a
//! `Localizer<1024>` is about 22 KiB (`docs/localization.md`).
//!
//! ```
//! use echoloc::localize::{Localizer, LocalizerConfig, Mode, Start};
//! use echoloc::map::FieldView;
//! use echoloc::referencing::{EkfConfig, VerdictConfig};
//!
//! // Without a field there is no free space to search: a known start only.
//! let field = FieldView::EMPTY;
//! let start = Start::Known { pose: [1.0, 2.0, 0.0], sigma: [0.05, 0.05, 0.02] };
//! let mut loc: Localizer<64> = Localizer::new(LocalizerConfig::DEFAULT, EkfConfig::DEFAULT, VerdictConfig::POLAROID, 1);
//! loc.start(start, &field).unwrap();
//! assert_eq!(loc.mode(), Mode::Tracking);
//! assert_eq!(loc.start(Start::Unknown, &field), Err(echoloc::localize::LocalizeError::NoFreeSpace));
//! ```

pub mod beam;
pub mod expect;
pub mod history;
pub mod hypotheses;
pub mod localizer;
pub mod measure;
pub mod null;
pub mod particles;
pub mod place;
pub mod places;
pub mod rng;
pub mod scan;
pub mod sprt;

/// Two poses are one hypothesis within a metre and 20° of each other: the
/// sweep keeps its spread proposals this far apart, the verification calls
/// a pose this far from the cluster a rival.
pub(crate) const SAME_PLACE_M: f32 = 1.0;
pub(crate) const SAME_PLACE_DEG: f32 = 20.0;
pub(crate) const SAME_PLACE_RAD: f32 = SAME_PLACE_DEG * core::f32::consts::PI / 180.0;

/// Whether poses `a` and `b` stand within `m` metres and `rad` radians of
/// each other (false for a NaN).
#[inline(always)]
pub(crate) fn within(a: &[f32; 3], b: &[f32; 3], m: f32, rad: f32) -> bool {
    dist2(a, b) <= m * m && libm::fabsf(crate::referencing::wrap(a[2] - b[2])) <= rad
}

/// The squared distance between two poses' positions, m².
#[inline(always)]
pub(crate) fn dist2(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
    dx * dx + dy * dy
}

pub use beam::BeamModel;
pub use expect::FieldLookup;
pub use history::History;
pub use hypotheses::{Bank, Hypothesis, Proposal, BANK};
pub use localizer::{
    CycleReport, LocalizeError, Localizer, LocalizerConfig, LocalizerCounts, Mode, PlaceTest, Start, MAX_SENSED, PLACES,
};
pub use measure::{Measure, Sensed};
pub use null::{NullError, NullModel};
pub use particles::{kld_bound, Cluster, McConfig, MotionNoise, ParticleError, ParticleSet, Weighed};
pub use place::{Place, PlaceCycle, PlaceError, Tracking};
pub use places::{Places, PlacesError, Proposal as PlaceProposal, Standing};
pub use rng::Rng;
pub use scan::{Candidate, ScanConfig, Sweep};
pub use sprt::{Decision, Sprt, SprtError};
