//! What a controller sends over the link (`link --mcap`, `link --live`) as
//! Foxglove messages, one message at a time as it arrives: per reading its
//! pose (`/pose/controller`, `/tf` map → controller), covariance ellipse,
//! sensor window and verdict; the mode with the reason the cycle reports.
//! Stamped with the controller's clock (µs, unwrapped at 2³²). No map: the
//! controller holds it. No particles or hypotheses: the link carries each
//! cycle's particle count, not the cloud (1 024 particles are 12 KiB a
//! cycle, more than the link carries in a second).

use echoloc::link::{CycleReport, FromController, ReadingReport, WireMode, WireOutcome};
use echoloc::predict::Mount;
use foxglove::messages::{FrameTransforms, Log, PoseInFrame, SceneUpdate};

use super::run::{mode_message, reading_messages, window_of, At, Sonar, Window};
use super::scene;
use super::{Recording, RecordingError};
use crate::clock::Unwrap;

/// The link's messages, recorded as they come.
pub struct LinkRecorder<'a> {
    mounts: &'a [Mount],
    window: Window,
    clock: Unwrap,
    /// The last time written, ns.
    t: u64,
    mode: Option<WireMode>,
    /// The last cycle's report, for the reason of a change.
    cycle: Option<CycleReport>,
}

/// The mode's name.
fn name(m: WireMode) -> &'static str {
    match m {
        WireMode::Searching => "searching",
        WireMode::Tracking => "tracking",
        WireMode::Lost => "lost",
    }
}

impl<'a> LinkRecorder<'a> {
    /// For a controller with ring `mounts`.
    pub fn new(mounts: &'a [Mount]) -> Self {
        // The window's ranges and half-angle do not depend on the buffer.
        Self { mounts, window: window_of(0), clock: Unwrap::default(), t: 0, mode: None, cycle: None }
    }

    /// Advertises the channels to a live view before the first message.
    pub fn advertise(rec: &mut Recording) {
        rec.advertise::<FrameTransforms>("/tf");
        rec.advertise::<PoseInFrame>("/pose/controller");
        rec.advertise::<SceneUpdate>("/ekf/covariance");
        rec.advertise::<SceneUpdate>("/sonar");
        rec.advertise::<Log>("/localization/mode");
    }

    /// Records one message from the controller.
    pub fn push(&mut self, rec: &mut Recording, m: &FromController) {
        match m {
            FromController::Reading(r) => self.reading(rec, r),
            FromController::Cycle(c) => self.cycle = Some(*c),
            _ => {}
        }
    }

    fn reading(&mut self, rec: &mut Recording, r: &ReadingReport) {
        let t = self.clock.next(r.time_us) * 1000;
        self.t = t;
        let p = r.pose.map(f64::from);
        rec.write("/tf", t, &FrameTransforms { transforms: vec![scene::transform(t, "controller", p)] });
        rec.write("/pose/controller", t, &scene::pose_in_map(t, p));
        let c = r.covariance;
        let observed = match r.outcome {
            WireOutcome::Range(mm) => Some(mm),
            _ => None,
        };
        let at = At { t, pose: p, covariance: Some([c[0], c[1], c[3]]) };
        let sonar = Sonar {
            mount: self.mounts.get(usize::from(r.transducer)),
            transducer: r.transducer,
            verdict: Some(format!("{:?}", r.verdict)),
            predicted_mm: r.predicted_mm,
            observed_mm: observed,
        };
        reading_messages(rec, "controller", &at, &sonar, self.window);
        if self.mode != Some(r.mode) {
            let reason = match (self.mode, &self.cycle) {
                (None, _) => "at the start".to_string(),
                (_, Some(c)) if c.handoff && c.hypotheses > 0 => format!(
                    "the particles handed off to the EKF: the best of {} places led the null and the rest by {:.1} nats",
                    c.hypotheses, c.lead
                ),
                (_, Some(c)) if c.handoff => "the particles handed off to the EKF".to_string(),
                (_, Some(c)) if c.behind > 0.0 && r.mode != WireMode::Tracking => {
                    format!("the EKF's pose trailed the null by {:.1} nats", c.behind)
                }
                (_, Some(c)) if c.particles > 0 => format!("searching with {} particles", c.particles),
                _ => "the EKF's lost flag changed".to_string(),
            };
            self.mode = Some(r.mode);
            rec.write("/localization/mode", t, &mode_message(t, name(r.mode), &reason));
        }
    }
}

/// Records what a controller sent, after the run.
pub fn record_link(messages: &[FromController], mounts: &[Mount]) -> Result<Recording, RecordingError> {
    let mut rec = Recording::new()?;
    let mut l = LinkRecorder::new(mounts);
    for m in messages {
        l.push(&mut rec, m);
    }
    Ok(rec)
}
