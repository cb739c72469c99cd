//! `replay --ros2`: a recorded run watched in rviz without hardware. After
//! the replay, its estimate is published as `link --ros2` publishes a
//! controller's (`/amcl_pose`, `/tf` map → odom, `/sonar_<k>`,
//! `/diagnostics`, `/tf_static`), paced by `--speed`, and, what the link
//! cannot carry, the particles on `/particlecloud` at every searching
//! cycle's end. Stamped at the host's time at the start plus the run's
//! time since its first reading. A replay takes no commands: the run is done.

use std::time::{Duration, Instant};

use echoloc::link::CycleReport;
use echoloc::predict::Mount;
use echoloc::referencing::Reading;

use super::bridge::{map_to_odom, mode_diagnostics, particle_cloud, pose_message, range_message, Out};
use super::msgs::Distro;
use super::node::{now_ns, Ros2Counts, Ros2Node};
use super::Ros2Args;
use crate::map::LabError;
use crate::simulate::filters::{Step, Trace};

/// A replayed run: its ring, its steps, the cumulative odometry at each
/// step (m, m, rad), and what the filters made of it.
pub struct ReplayedRun<'a> {
    pub mounts: &'a [Mount],
    pub steps: &'a [Step],
    pub odometry: &'a [[f64; 3]],
    pub trace: &'a Trace,
}

/// Every message of the run with its time on the run's clock (s), in order:
/// per reading its pose, `map → odom` and Range; per ring cycle its
/// diagnostics and, when it ended with particles, the cloud.
pub fn outputs(distro: Distro, t0_ns: u64, run: &ReplayedRun<'_>) -> Vec<(f64, Out)> {
    let Some(first) = run.steps.first().map(|s| s.time_s) else { return Vec::new() };
    let ns = |t: f64| t0_ns.saturating_add(((t - first).max(0.0) * 1e9) as u64);
    let tr = run.trace;
    let mut out = Vec::new();
    for (i, s) in run.steps.iter().enumerate() {
        let (Some(&p), Some(&c)) = (tr.ekf.get(i), tr.covariance_after.get(i)) else { break };
        let n = ns(s.time_s);
        out.push((s.time_s, Out::Pose(Box::new(pose_message(n, p, c)))));
        if let Some(&o) = run.odometry.get(i) {
            out.push((s.time_s, Out::Tf(map_to_odom(n, p, o))));
        }
        let range = match s.reading {
            Reading::Echo { range_mm } => Some(range_mm as f32 / 1000.0),
            Reading::NoEcho => Some(f32::INFINITY),
            Reading::Invalid => None,
        };
        if let Some(range) = range {
            let k = usize::from(s.transducer);
            out.push((s.time_s, Out::Range(k, range_message(distro, n, k, range))));
        }
    }
    let mut clouds = tr.cycle_clouds.iter().peekable();
    let mut cycle_outs = Vec::new();
    for (k, row) in tr.cycles.iter().enumerate() {
        let n = ns(row.time_s);
        // What the link would carry of it: a replay keeps no gate counts or verdicts per cycle.
        let report = CycleReport {
            cycle: k as u32,
            verdicts: [0; 6],
            gate: [0, 0],
            mode: row.mode.into(),
            particles: row.particles,
            handoff: row.handoff,
            hypotheses: row.hypotheses,
            lead: row.lead,
            behind: row.behind,
        };
        cycle_outs.push((row.time_s, Out::Diagnostics(mode_diagnostics(n, &report))));
        while let Some(c) = clouds.next_if(|c| c.cycle <= k) {
            if c.cycle == k {
                cycle_outs.push((row.time_s, Out::Particles(particle_cloud(n, &c.poses))));
            }
        }
    }
    out.extend(cycle_outs);
    // Stable: a cycle's messages after the reading that ended it.
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// Publishes the run as a node `args` names, `speed` run seconds a second.
pub fn publish(args: &Ros2Args, run: &ReplayedRun<'_>, speed: f64) -> Result<Ros2Counts, LabError> {
    if args.ros2_odom {
        return Err(LabError("--ros2-odom: a replay has its odometry; /odom is for `link`".into()));
    }
    let (tx, _rx) = std::sync::mpsc::channel();
    let node = Ros2Node::start(args, run.mounts, &[], tx)?;
    let wait = Duration::from_secs_f64(args.ros2_wait_s.clamp(0.0, 3600.0));
    if !wait.is_zero() && !node.wait_for_subscribers(wait) {
        eprintln!("ros2: not every topic had a subscriber within --ros2-wait-s; running without");
    }
    let msgs = outputs(args.ros_distro, now_ns(), run);
    let (start, first) = (Instant::now(), msgs.first().map_or(0.0, |m| m.0));
    for (t, o) in msgs {
        let due = start + Duration::from_secs_f64(((t - first) / speed).clamp(0.0, 1e7));
        if let Some(d) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
        node.publish(o);
    }
    Ok(node.finish())
}
