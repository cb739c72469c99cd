//! Foxglove recordings out (#28 item 2), read back by an independent reader:
//! `scripts/mcap-check.py` opens the MCAP with PyPI's `mcap` and checks every
//! channel's Foxglove schema, the message counts against the run's JSON, the
//! timestamps, and the first and last EKF poses against the JSON's.

mod common;

use std::path::Path;
use std::process::Command;

use common::{lab, root, run_json, s, shared_map, tmp};
use serde_json::Value;

/// Runs the reader on `mcap` against `report`; its summary, or its failure.
fn check(mcap: &Path, report: &Value) -> Result<Value, String> {
    let json = mcap.with_extension("json");
    std::fs::write(&json, report.to_string()).unwrap();
    let o = Command::new("python3").arg(root().join("scripts/mcap-check.py")).arg(mcap).arg(&json).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!err.contains("needs PyPI's mcap"), "{err} (`bash scripts/setup.sh` installs it)");
    if o.status.success() {
        Ok(serde_json::from_slice(&o.stdout).unwrap())
    } else {
        Err(err)
    }
}

#[test]
fn a_simulated_run_reads_back_with_every_channel_and_count() {
    let out = tmp("fox", "sim.mcap");
    let map = shared_map("depot.yaml");
    let v = run_json(&["simulate", "--json", "--map", s(&map), "--seed", "3", "--distance-m", "20", "--mcap", s(&out)]);
    let sum = check(&out, &v).unwrap();
    let ch = &sum["channels"];
    let n = v["readings"].as_u64().unwrap();
    assert!(n > 1000);
    for (topic, schema) in [
        ("/map", "foxglove.SceneUpdate"),
        ("/tf", "foxglove.FrameTransforms"),
        ("/pose/ekf", "foxglove.PoseInFrame"),
        ("/pose/truth", "foxglove.PoseInFrame"),
        ("/ekf/covariance", "foxglove.SceneUpdate"),
        ("/sonar", "foxglove.SceneUpdate"),
        ("/state", "foxglove.Log"),
    ] {
        assert_eq!(ch[topic]["schema"], schema, "{topic}: {sum}");
    }
    assert_eq!(ch["/sonar"]["count"], n);
    assert_eq!(sum["ekf"]["final_pose"], v["ekf"]["final_pose"]);
    // The reader is a real check: a report whose last EKF pose differs by a
    // millimetre, or whose readings are one more, is refused.
    let mut wrong = v.clone();
    wrong["ekf"]["final_pose"][0] = serde_json::json!(v["ekf"]["final_pose"][0].as_f64().unwrap() + 0.001);
    assert!(check(&out, &wrong).unwrap_err().contains("EKF final_pose"));
    let mut wrong = v.clone();
    wrong["readings"] = serde_json::json!(n + 1);
    assert!(check(&out, &wrong).unwrap_err().contains(&format!("/sonar: {n} messages, the run has {}", n + 1)));
}

#[test]
fn a_run_that_gets_lost_logs_each_change() {
    let out = tmp("fox", "lost.mcap");
    let map = shared_map("depot.yaml");
    let v = run_json(&[
        "simulate",
        "--json",
        "--map",
        s(&map),
        "--seed",
        "3",
        "--distance-m",
        "40",
        "--inconsistent",
        "0.8",
        "--mcap",
        s(&out),
    ]);
    assert!(v["lost"]["raised"].as_u64().unwrap() >= 2, "{v}");
    let sum = check(&out, &v).unwrap();
    // One log line at the start and one per change of the localizer's mode.
    let changes = 1 + v["localization"]["mode_changes"].as_u64().unwrap();
    assert!(changes >= 3, "{v}");
    assert_eq!(sum["channels"]["/state"]["count"], changes);
}

#[test]
fn a_replayed_log_reads_back_and_a_bad_path_writes_nothing() {
    let out = tmp("fox", "hand.mcap");
    let log = root().join("lab/tests/data/depot-hand.csv");
    let map = root().join("boards/qemu-mps2-an386/depot.map");
    let plot = tmp("fox", "hand.png");
    let v = run_json(&["replay", "--json", "--map", s(&map), "--log", s(&log), "--mcap", s(&out), "--plot", s(&plot)]);
    let sum = check(&out, &v).unwrap();
    assert_eq!(sum["channels"]["/pose/truth"]["count"], v["log"]["reference_rows"]);
    // The MCAP in a folder that does not exist: refused before anything is written.
    let (plot2, bad) = (tmp("fox", "hand2.png"), tmp("fox", "no/such/dir/x.mcap"));
    let o = lab()
        .args(["replay", "--map", s(&map), "--log", s(&log), "--mcap", s(&bad), "--plot", s(&plot2)])
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("does not exist"));
    assert!(!plot2.exists());
}
