//! One reading at a time through prediction, verdict and the EKF.

use super::ekf::{CycleUpdates, Ekf, EkfError, Update};
use super::model::{Motion, MountM, Target};
use super::verdict::{judge, Reading, Verdict, VerdictConfig, VerdictCounts};
use crate::credence::Credence;
use crate::map::MapSource;
use crate::predict::{predict_mount, Mount, Pose, PredictError, PredictParams, Prediction};

/// Why a reading could not be processed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReferencerError {
    /// The prediction failed (window placement, beacon capacity).
    Predict(PredictError),
    /// The filter refused an input (non-finite odometry).
    Ekf(EkfError),
}

impl From<PredictError> for ReferencerError {
    fn from(e: PredictError) -> Self {
        Self::Predict(e)
    }
}

impl From<EkfError> for ReferencerError {
    fn from(e: EkfError) -> Self {
        Self::Ekf(e)
    }
}

/// What became of one reading.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReadingReport {
    /// The prediction at the pose the reading was judged from.
    pub prediction: Option<Prediction>,
    /// The verdict.
    pub verdict: Verdict,
    /// The target the prediction stands for (plane or point), if any.
    pub target: Option<Target>,
    /// What the filter did with it (`None`: no echo or nothing predicted).
    pub update: Option<Update>,
}

/// Predicts `mount` at `pose`, judges `reading`, and names the target.
#[allow(clippy::too_many_arguments)]
pub fn observe<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    pose: &Pose,
    mount: &Mount,
    params: &PredictParams,
    credence: &K,
    reading: Reading,
    verdicts: &VerdictConfig,
) -> Result<ReadingReport, PredictError> {
    let (prediction, _) = predict_mount(map, pose, mount, params, credence)?;
    let verdict = judge(reading, prediction.as_ref(), verdicts);
    let target = prediction.as_ref().and_then(|p| Target::of(map, p));
    Ok(ReadingReport { prediction, verdict, target, update: None })
}

/// The EKF's pose as the predictor takes it (mm).
pub fn pose_mm(x: [f32; 3]) -> Pose {
    Pose { x_mm: x[0] * 1000.0, y_mm: x[1] * 1000.0, heading_rad: x[2] }
}

/// The EKF driven by readings: each transducer is predicted at the current
/// estimate, its reading judged, and an echo with a target fed to the
/// filter. Verdicts are counted per ring cycle and over the run.
#[derive(Clone, Debug)]
pub struct Referencer {
    /// The filter.
    pub ekf: Ekf,
    /// How readings are judged.
    pub verdicts: VerdictConfig,
    cycle: VerdictCounts,
    total: VerdictCounts,
}

impl Referencer {
    /// Around a filter.
    pub fn new(ekf: Ekf, verdicts: VerdictConfig) -> Self {
        Self { ekf, verdicts, cycle: VerdictCounts::default(), total: VerdictCounts::default() }
    }

    /// Odometry since the last call.
    pub fn odometry(&mut self, u: &Motion) -> Result<(), ReferencerError> {
        Ok(self.ekf.predict(u)?)
    }

    /// One transducer's reading.
    pub fn reading<M: MapSource + ?Sized, K: Credence + ?Sized>(
        &mut self,
        map: &M,
        mount: &Mount,
        params: &PredictParams,
        credence: &K,
        reading: Reading,
    ) -> Result<ReadingReport, ReferencerError> {
        let pose = pose_mm(self.ekf.state());
        let mut r = observe(map, &pose, mount, params, credence, reading, &self.verdicts)?;
        self.cycle.add(r.verdict);
        if let (Reading::Echo { range_mm }, Some(p), Some(t)) = (reading, r.prediction.as_ref(), r.target.as_ref()) {
            if r.verdict != Verdict::Inconclusive {
                let z = range_mm as f32 / 1000.0;
                let (kappa, mount) = (p.kappa.to_num::<f32>(), MountM::from(mount));
                r.update = Some(if r.verdict == Verdict::Confirmed {
                    self.ekf.update(z, kappa, mount, t)
                } else {
                    self.ekf.update_unconfirmed(z, kappa, mount, t)
                });
            }
        }
        Ok(r)
    }

    /// Ends a ring cycle: its verdict counts and gate counts (the lost
    /// monitor runs on the latter).
    pub fn end_cycle(&mut self) -> (VerdictCounts, CycleUpdates) {
        let v = self.cycle;
        self.total += v;
        self.cycle = VerdictCounts::default();
        (v, self.ekf.end_cycle())
    }

    /// Verdicts of every finished cycle.
    pub fn totals(&self) -> VerdictCounts {
        self.total
    }
}
