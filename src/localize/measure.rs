//! The measurement model on the field: how well a cycle's readings fit a
//! pose. Each reading is scored by the beam model against what the field
//! says a transducer standing there should hear. The particles weigh by
//! it, the history verifies the search's proposals by it, and the fit
//! monitor watches the EKF's pose by it: one model, one place to change it.
//!
//! ```
//! use echoloc::localize::measure::{Measure, Sensed};
//! use echoloc::localize::{BeamModel, FieldLookup};
//! use echoloc::map::FieldView;
//! use echoloc::referencing::Reading;
//!
//! // No field: every pose is off it, and a reading scores as the beam
//! // model's off-field term says.
//! let field = FieldView::EMPTY;
//! let lookup = FieldLookup::new(&field);
//! let beam = BeamModel::DEFAULT;
//! let m = Measure::new(&lookup, &beam, 0.0);
//! let sensed = [Sensed { pose: [0.2, 0.0, 0.0], reading: Reading::Echo { range_mm: 1500 } }];
//! let ll = m.log_likelihood(&[1.0, 2.0, 0.0], &sensed);
//! assert!(ll.is_finite() && ll < 0.0);
//! // Invalid readings say nothing.
//! let none = [Sensed { pose: [0.2, 0.0, 0.0], reading: Reading::Invalid }];
//! assert!(m.log_likelihood(&[1.0, 2.0, 0.0], &none) > ll);
//! ```

use super::beam::BeamModel;
use super::expect::FieldLookup;
use crate::f32math::{ln_fast, sin_cos};
use crate::referencing::Reading;

/// A reading as the particles take it: the transducer's pose in the frame
/// of the cycle's start (x m, y m, heading rad) and what it read.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sensed {
    /// The transducer's pose at its firing, in the robot's frame at the
    /// cycle's start.
    pub pose: [f32; 3],
    /// The reading.
    pub reading: Reading,
}

impl Sensed {
    /// How many of `sensed` are usable readings (not `Invalid`). A fold
    /// that saturates, where `count` would carry an overflow check.
    pub(crate) fn usable(sensed: &[Sensed]) -> usize {
        sensed.iter().filter(|r| r.reading != Reading::Invalid).fold(0usize, |n, _| n.saturating_add(1))
    }
}

/// The field's lookup, the beam model and the variance a hit's σ grows by
/// (in quadrature, mm²: what the particles' spread or a coarse placement
/// costs): everything scoring a pose takes.
#[derive(Clone, Copy, Debug)]
pub struct Measure<'m> {
    lookup: &'m FieldLookup<'m, 'm>,
    beam: &'m BeamModel,
    extra_var_mm2: f32,
}

impl<'m> Measure<'m> {
    /// The model on `lookup`'s field, with `beam`, hits widened by
    /// `extra_var_mm2`.
    pub fn new(lookup: &'m FieldLookup<'m, 'm>, beam: &'m BeamModel, extra_var_mm2: f32) -> Self {
        Self { lookup, beam, extra_var_mm2 }
    }

    /// The sum of the log-likelihoods of `sensed` at pose `p` (x m, y m,
    /// φ rad; the readings' frame), with the off-field term when the pose
    /// stands where the field has no free node.
    // Out of line: its callers (weighing, injection, the history, the
    // kept places' cycle, the fit monitor) would each inline a copy
    // (flash: issue #27's budget).
    #[inline(never)]
    pub fn log_likelihood(&self, p: &[f32; 3], sensed: &[Sensed]) -> f32 {
        // Read once into locals: through `self` the loop reloaded them.
        let Self { lookup, beam, extra_var_mm2 } = *self;
        let (s, c) = sin_cos(p[2]);
        let mut ll = 0.0;
        if !lookup.is_free(p[0] * 1e3, p[1] * 1e3) {
            ll += ln_fast(beam.off_field);
        }
        for r in sensed {
            if r.reading == Reading::Invalid {
                continue;
            }
            let tx = p[0] + c * r.pose[0] - s * r.pose[1];
            let ty = p[1] + s * r.pose[0] + c * r.pose[1];
            let e = lookup.expected(tx * 1e3, ty * 1e3, p[2] + r.pose[2]);
            ll += ln_fast(beam.likelihood_with(r.reading, e, extra_var_mm2));
        }
        ll
    }
}
