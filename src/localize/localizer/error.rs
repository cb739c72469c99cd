//! Why the localizer refused.

use super::super::particles::ParticleError;
use crate::referencing::{EkfError, ReferencerError};

/// Why the localizer refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LocalizeError {
    /// A search was asked of a localizer with no particles (`N = 0`).
    NoCapacity,
    /// The map's field has no free space to draw particles from (a map
    /// compiled without a field, or one with no room for the robot).
    NoFreeSpace,
    /// The start pose is not in the map's free space.
    OutsideMap,
    /// A non-finite pose, σ or odometry.
    NotFinite,
    /// A transducer stands farther from the robot's centre than the
    /// field reaches (`reach_mm`): the map must be compiled with more reach.
    RingBeyondField {
        /// The transducer.
        transducer: u8,
    },
    /// The place test's settings were refused ([`super::PlaceTest`]): a
    /// bound or clip that is not a finite positive number of nats, a
    /// `calm_behind` not in `0..bound`, a hit share not in `(0, 1)`, a
    /// cluster weight not in `[0, 1]`, a proposal's σ or floor negative or
    /// not finite, or a null memory shorter than the null's bins
    /// ([`crate::localize::NullModel::new`]).
    PlaceTest,
    /// The EKF refused.
    Ekf(EkfError),
    /// Prediction or the EKF refused a reading.
    Referencer(ReferencerError),
}

impl From<EkfError> for LocalizeError {
    fn from(e: EkfError) -> Self {
        Self::Ekf(e)
    }
}

impl From<ReferencerError> for LocalizeError {
    fn from(e: ReferencerError) -> Self {
        Self::Referencer(e)
    }
}

impl From<ParticleError> for LocalizeError {
    fn from(e: ParticleError) -> Self {
        match e {
            ParticleError::NoCapacity => Self::NoCapacity,
            ParticleError::NoFreeSpace => Self::NoFreeSpace,
            ParticleError::NotFinite => Self::NotFinite,
        }
    }
}

impl core::fmt::Display for LocalizeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NoCapacity => f.write_str("no particles to search with (capacity 0)"),
            Self::NoFreeSpace => f.write_str("the map's field has no free space (compile the map with a field)"),
            Self::OutsideMap => f.write_str("the start pose is not in the map's free space"),
            Self::NotFinite => f.write_str("a non-finite pose, standard deviation or odometry"),
            Self::RingBeyondField { transducer } => {
                write!(f, "transducer {transducer} stands beyond the field's reach (compile the map with more reach)")
            }
            Self::PlaceTest => f.write_str("a place test setting out of its range (see PlaceTest's fields)"),
            Self::Ekf(e) => write!(f, "EKF: {e:?}"),
            Self::Referencer(e) => write!(f, "{e:?}"),
        }
    }
}

impl core::error::Error for LocalizeError {}
