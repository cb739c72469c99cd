//! Self-referencing (paper §5.5, DESIGN §4.6): each reading judged against
//! its prediction, and the pose corrected, by the paper's threshold method
//! (the baseline) or by an extended Kalman filter.
//!
//! | module | what it does |
//! |---|---|
//! | [`verdict`] | a reading against its prediction: confirmed, unknown obstacle, removed or missed, unpredicted echo, nothing as predicted |
//! | [`model`] | plane and point range models and the odometry motion model, with analytic Jacobians |
//! | [`ekf`] | the EKF over (x, y, φ): χ² gate, κ-weighted variance, Joseph form, lost state |
//! | [`gaussian`] | [`PoseGaussian`]: the pose's mean and covariance, and the filter's two steps on it (the EKF's, and each place's the localizer keeps) |
//! | [`calibration`] | the odometry's systematic heading errors (turn scale, drift per metre) learned from the filter's corrections and taken out of each step |
//! | [`recovery`] | a lost filter's way back: the last readings linearised, and the correction most of them agree on |
//! | [`threshold`] | the paper's threshold method |
//! | [`f32math`] | (re-exported from the crate root, where the window uses it too) sin, cos and √ in single precision |
//!
//! [`Referencer`] ties them to the predictor for one reading at a time, the
//! way the firmware runs: predict a transducer at the current estimate in
//! the gap before it fires, judge its reading, update.

pub mod calibration;
pub mod ekf;
pub mod gaussian;
pub use crate::f32math;
pub mod model;
pub mod recovery;
mod referencer;
pub mod threshold;
pub mod verdict;

pub use ekf::{CycleUpdates, Ekf, EkfConfig, EkfError, Update};
pub use gaussian::{Correction, PoseGaussian};
pub use model::{compose, range_model, sensor_position, wrap, Motion, MountM, Target};
pub use recovery::{Found, Recent, RecoveryConfig};
pub use referencer::{observe, pose_mm, ReadingReport, Referencer, ReferencerError};
pub use threshold::{Threshold, ThresholdConfig};
pub use verdict::{judge, Reading, Verdict, VerdictConfig, VerdictCounts};
