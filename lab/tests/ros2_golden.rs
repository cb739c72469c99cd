//! Golden bytes for `link --ros2` (#50): every message the node publishes,
//! made by the node's own bridge from a controller's messages (and a
//! replay's particles) and encoded
//! by echoloc, is byte-identical to the same message built from its fields
//! as Humble's, Jazzy's and Kilted's type and serialized by PyPI's `rosbags`
//! (`scripts/ros2-golden.py`), an independent CDR serializer with each
//! distribution's message definitions. Range's `variance` is the layout
//! that differs: present after Humble.

mod common;

use common::root;
use echoloc::link::{CycleReport, FromController, ReadingReport, WireMode, WireOutcome, WireUpdate, WireVerdict};
use echoloc::predict::Mount;
use echoloc_lab::bag::msgs::encode;
use echoloc_lab::ros2::bridge::{particle_cloud, Bridge, Out};
use echoloc_lab::ros2::msgs::{planar_covariance, Distro, PoseWithCovarianceStamped};
use std::io::Write;

fn reading(time_us: u32, transducer: u8, outcome: WireOutcome, mode: WireMode) -> FromController {
    FromController::Reading(ReadingReport {
        time_us,
        cycle: 3,
        transducer,
        outcome,
        predicted_mm: Some(1500),
        kappa: 0.8,
        verdict: WireVerdict::Confirmed,
        update: WireUpdate::Accepted,
        pose: [12.25, -3.5, 2.9],
        covariance: [0.0123, -0.0004, 0.0007, 0.0211, -0.0002, 0.0031],
        mode,
    })
}

#[test]
fn every_published_message_is_byte_identical_to_rosbags_for_each_distro() {
    let mounts = [
        Mount { x_mm: 115, y_mm: 0, heading_mdeg: 0 },
        Mount { x_mm: 100, y_mm: 60, heading_mdeg: 30_000 },
        Mount { x_mm: -100, y_mm: -60, heading_mdeg: -150_000 },
    ];
    let odometry = [(0, 0.0, 0.0, 0.0), (400_000, 0.2, 0.01, 0.05), (800_000, 0.4, 0.03, 0.1)];
    let mut lines = Vec::new();
    let mut push = |ty: &str, distro: Distro, v: serde_json::Value, cdr: Vec<u8>| {
        let hex: String = cdr.iter().map(|b| format!("{b:02x}")).collect();
        let d = format!("{distro:?}").to_lowercase();
        lines.push(serde_json::json!({"type": ty, "distro": d, "msg": v, "cdr": hex}).to_string());
    };
    for distro in [Distro::Humble, Distro::Jazzy, Distro::Kilted] {
        let mut b = Bridge::new(distro, &mounts, &odometry);
        let tf = b.static_tf(1_700_000_000_123_456_789);
        push("tf2_msgs/msg/TFMessage", distro, serde_json::to_value(&tf).unwrap(), encode(&tf).unwrap());
        // The Hello: the link's own status on /diagnostics, the clocks' anchor.
        let mut outs = b.push(
            &FromController::Hello { protocol: 3, transducers: 3, map_crc: 7, time_us: 0 },
            1_700_000_000_000_000_000,
        );
        outs.extend(b.push(&reading(250_000, 1, WireOutcome::Range(1734), WireMode::Tracking), 0));
        outs.extend(b.push(&reading(300_000, 2, WireOutcome::NoEcho, WireMode::Searching), 0));
        let cycle = CycleReport {
            cycle: 3,
            verdicts: [5, 1, 0, 2, 0, 8],
            gate: [7, 5],
            mode: WireMode::Searching,
            particles: 1024,
            handoff: false,
            hypotheses: 5,
            lead: 37.25,
            behind: 0.5,
        };
        outs.extend(b.push(&FromController::Cycle(cycle), 0));
        // A replay's particles (`replay --ros2`; the link carries none).
        outs.push(Out::Particles(particle_cloud(1_700_000_000_300_000_000, &[[1.0, 2.0, 0.5], [-3.25, 4.0, -2.0]])));
        let mut kinds = Vec::new();
        for o in outs {
            let (ty, v, cdr) = match &o {
                Out::Pose(p) => ("geometry_msgs/msg/PoseWithCovarianceStamped", serde_json::to_value(p), encode(p)),
                Out::Tf(t) => ("tf2_msgs/msg/TFMessage", serde_json::to_value(t), encode(t)),
                Out::Range(_, r) => ("sensor_msgs/msg/Range", serde_json::to_value(r), encode(r)),
                Out::Diagnostics(d) => ("diagnostic_msgs/msg/DiagnosticArray", serde_json::to_value(d), encode(d)),
                Out::Particles(p) => ("geometry_msgs/msg/PoseArray", serde_json::to_value(p), encode(p)),
            };
            kinds.push(ty);
            push(ty, distro, v.unwrap(), cdr.unwrap());
        }
        for ty in ["geometry_msgs/msg/PoseWithCovarianceStamped", "tf2_msgs/msg/TFMessage", "sensor_msgs/msg/Range"] {
            assert_eq!(kinds.iter().filter(|k| **k == ty).count(), 2, "{ty}: {kinds:?}");
        }
        assert_eq!(kinds.iter().filter(|k| **k == "diagnostic_msgs/msg/DiagnosticArray").count(), 2, "{kinds:?}");
        // What /initialpose carries, decoded by the node as it encodes /amcl_pose.
        let initial = PoseWithCovarianceStamped {
            header: echoloc_lab::bag::msgs::header(42, "map"),
            pose: echoloc_lab::bag::msgs::PoseWithCovariance {
                pose: echoloc_lab::bag::msgs::pose([1.0, 2.0, -0.7]),
                covariance: planar_covariance([0.25, 0.01, 0.0, 0.25, 0.0, 0.0685]),
            },
        };
        push(
            "geometry_msgs/msg/PoseWithCovarianceStamped",
            distro,
            serde_json::to_value(&initial).unwrap(),
            encode(&initial).unwrap(),
        );
    }
    let mut c = std::process::Command::new("python3")
        .arg(root().join("scripts/ros2-golden.py"))
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    c.stdin.take().unwrap().write_all(lines.join("\n").as_bytes()).unwrap();
    let o = c.wait_with_output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "ros2-golden: {out} {}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["checked"].as_u64().unwrap() as usize, lines.len());
    assert_eq!(lines.len(), 3 * 11);
}
