//! Finding itself through the command line (issue #27): `simulate --start
//! unknown --kidnap … --trace`, `replay --initial-pose unknown`, the
//! `localization` report against the trace a user would check it with, and
//! bad input that fails clearly without writing.

mod common;

use std::path::{Path, PathBuf};

use common::{lab, root, run_json, s};

fn depot() -> PathBuf {
    root().join("boards/qemu-mps2-an386/depot.map")
}

fn scratch(test: &str) -> PathBuf {
    let d = common::tmp("localize-test", test);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `simulate --json` on the depot from no pose: seed, distance, then `more`.
fn find_on_depot(seed: &str, distance_m: &str, more: &[&str]) -> serde_json::Value {
    let depot = depot();
    let mut args = vec!["simulate", "--json", "--map", s(&depot), "--seed", seed, "--distance-m", distance_m];
    args.extend(["--start", "unknown"]);
    args.extend(more);
    run_json(&args)
}

/// The trace's rows: (time, mode, x, y, θ, σx, σy, σθ, ref x, ref y, ref θ).
fn rows(csv: &Path) -> (String, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    (header, lines.map(|l| l.split(',').map(str::to_string).collect()).collect())
}

/// The depot run the board's firmware also replays (`depot-find.scn`): no
/// start pose, a kidnap at 75 s. The report's figures are recomputed from
/// the trace (an independent reading of the same run).
#[test]
fn a_run_from_no_pose_with_a_kidnap_finds_itself_and_the_trace_agrees() {
    let dir = scratch("find");
    let trace = dir.join("trace.csv");
    let v = find_on_depot("6", "70", &["--kidnap", "75:-4,2,-90", "--trace", s(&trace)]);
    let l = &v["localization"];
    let (header, rows) = rows(&trace);
    assert_eq!(
        header,
        "time_s,mode,x_m,y_m,theta_rad,sigma_x_m,sigma_y_m,sigma_theta_rad,ref_x_m,ref_y_m,ref_theta_rad,particles,lead_nats,cluster_weight,behind_nats"
    );
    assert_eq!(rows.len() as u64, l["cycles"].as_u64().unwrap());
    // The modes, counted from the trace.
    for mode in ["searching", "tracking", "lost"] {
        let n = rows.iter().filter(|r| r[1] == mode).count() as u64;
        assert_eq!(n, l["modes"][mode].as_u64().unwrap(), "{mode}");
    }
    // It starts searching, ends tracking within 0.3 m of the truth.
    assert_eq!(rows[0][1], "searching");
    // The first hand-off's cycle passed the hand-off's own test: the
    // cluster's weight and its lead over the best place elsewhere.
    let first = rows.iter().position(|r| r[1] == "tracking").unwrap();
    let handoff = &rows[first - 1];
    let cfg = echoloc::localize::LocalizerConfig::DEFAULT;
    assert!(handoff[12].parse::<f32>().unwrap() >= cfg.handoff_lead, "{handoff:?}");
    assert!(handoff[13].parse::<f32>().unwrap() >= cfg.handoff_weight, "{handoff:?}");
    // Neither is written while tracking; without the place test, nothing
    // trails the null.
    assert!(rows.iter().filter(|r| r[1] == "tracking").all(|r| r[12].is_empty() && r[13].is_empty()));
    assert!(rows.iter().all(|r| r[14] == "0.0"));
    let err = |r: &Vec<String>| {
        let p = |i: usize| r[i].parse::<f64>().unwrap();
        (p(2) - p(8)).hypot(p(3) - p(9))
    };
    let last = rows.last().unwrap();
    assert_eq!(last[1], "tracking");
    assert!(err(last) < 0.3, "{}", err(last));
    // The cycles more than 0.5 m off, from the trace.
    let off = rows.iter().filter(|r| err(r) > 0.5).count() as u64;
    assert_eq!(off, l["off_cycles"].as_u64().unwrap());
    // The kidnap: noticed within 5 s, found again within 30 m.
    let k = &l["kidnaps"][0];
    assert!(k["detected_after_s"].as_f64().unwrap() <= 5.0, "{k}");
    assert!(k["recovered_after_m"].as_f64().unwrap() <= 30.0, "{k}");
    assert!(l["handoffs"].as_u64().unwrap() >= 2, "{l}");
    assert_eq!(l["wrong_handoffs"], serde_json::json!([]));
    // The places weighed: the cluster and the default bank of one (#27's
    // kept rival); more than one only while searching.
    let alive = &l["hypotheses_alive"];
    assert!((1..=2).contains(&alive["max"].as_u64().unwrap()), "{alive}");
    assert_eq!(alive["final"], 0, "tracking at the end: {alive}");
    assert!(
        alive["cycles_searching_with_more_than_one"].as_u64().unwrap() <= l["modes"]["searching"].as_u64().unwrap()
    );
    // Before the first convergence the trace says searching, never tracking.
    let first = l["first_convergence"]["time_s"].as_f64().unwrap() + rows[0][0].parse::<f64>().unwrap() - 0.7;
    assert!(rows.iter().filter(|r| r[0].parse::<f64>().unwrap() < first).all(|r| r[1] != "tracking"));
}

/// `--bank N` reaches the localizer: with 8 places kept the search weighs
/// more than the default's two (the cluster and #27's kept rival), never
/// more than the cluster and 8.
#[test]
fn a_larger_bank_weighs_more_places() {
    let alive = |bank: &str| {
        let v = find_on_depot("1", "30", &["--bank", bank]);
        v["localization"]["hypotheses_alive"]["max"].as_u64().unwrap()
    };
    assert_eq!(alive("0"), 1);
    assert_eq!(alive("1"), 2);
    let eight = alive("8");
    assert!((3..=9).contains(&eight), "{eight}");
}

/// A log of a simulated run replayed with no start pose finds itself, and
/// gives the very localization report the simulated run gave. (Seed 2 is
/// one the simulation finds early; not every seed is found within 30 m:
/// the rate is in `docs/localization.md`.)
#[test]
fn replay_finds_itself_in_a_log() {
    let dir = scratch("replay");
    let log = dir.join("run.csv");
    let sim = run_json(&[
        "simulate",
        "--json",
        "--map",
        s(&depot()),
        "--seed",
        "2",
        "--distance-m",
        "40",
        "--start",
        "unknown",
        "--log",
        s(&log),
    ]);
    let trace = dir.join("trace.csv");
    let v = run_json(&[
        "replay",
        "--json",
        "--map",
        s(&depot()),
        "--log",
        s(&log),
        "--initial-pose",
        "unknown",
        "--seed",
        "2",
        "--trace",
        s(&trace),
    ]);
    let l = &v["localization"];
    assert_eq!(l, &sim["localization"]);
    assert!(l["first_convergence"]["distance_m"].as_f64().unwrap() <= 30.0, "{l}");
    let (_, rows) = rows(&trace);
    assert_eq!(rows.len() as u64, l["cycles"].as_u64().unwrap());
    assert_eq!(rows[0][1], "searching");
    // The log's reference is in the trace.
    assert!(rows.iter().all(|r| !r[8].is_empty()));
}

#[test]
fn bad_starts_and_kidnaps_fail_clearly_and_write_nothing() {
    let dir = scratch("bad");
    let trace = dir.join("trace.csv");
    let cases: [(&[&str], &str); 10] = [
        (&["--start", "500,-40,0,0.5,10"], "not in the map's free space"),
        (&["--start", "somewhere"], "--start \"somewhere\": expected unknown"),
        (&["--start", "1,2,3,-1,10"], "σ_m must be within"),
        (&["--kidnap", "10:400,0,0"], "not in the free space the route drives in"),
        (&["--kidnap", "30:1,2"], "expected T_s:dx_m,dy_m,dθ_deg"),
        (&["--bank", "9"], "9 is not in 0..=8"),
        (&["--handoff-z=nan"], "\"nan\" is not a finite number ≥ 0"),
        (&["--handoff-z=-0.5"], "\"-0.5\" is not a finite number ≥ 0"),
        (&["--unconfirmed-variance-scale=0.5"], "\"0.5\" is not a finite number ≥ 1"),
        (&["--unconfirmed-variance-scale=inf"], "\"inf\" is not a finite number ≥ 1"),
    ];
    let map = depot();
    for (extra, message) in cases {
        let mut args = vec!["simulate", "--json", "--map", s(&map), "--distance-m", "10", "--trace", s(&trace)];
        args.extend_from_slice(extra);
        let o = lab().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(message), "{extra:?}: expected {message:?}, got {err}");
        assert!(!trace.exists(), "{extra:?} wrote the trace");
    }
    // A map compiled without a field cannot search.
    let bare = dir.join("bare.map");
    let o = lab()
        .args(["map", "import", "--no-field"])
        .arg(root().join("maps/office.geojson"))
        .arg("-o")
        .arg(&bare)
        .output()
        .unwrap();
    assert!(o.status.success());
    let o = lab()
        .args(["simulate", "--json", "--map", s(&bare), "--distance-m", "10", "--start", "unknown"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("no free space"), "{err}");
}

/// Two rooms, each the half-turn of the other, joined by a corridor with a
/// niche at one end (`data/two-rooms.geojson`): only driving through the
/// corridor tells them apart. The localizer finds the robot within 60 m,
/// never reports tracking at the other room's pose (every cycle it spends
/// more than 0.5 m off is reported searching or lost) and no hand-off is
/// wrong. Seeds 1–3 were fixed before the test was run; over seeds 1–20 the
/// rate is in `docs/localization.md` (not every seed is solved).
#[test]
fn a_symmetric_map_is_solved_by_driving_through_the_corridor() {
    let map = root().join("lab/tests/data/two-rooms.geojson");
    for seed in ["1", "2", "3"] {
        let v = run_json(&[
            "simulate",
            "--json",
            "--map",
            s(&map),
            "--seed",
            seed,
            "--distance-m",
            "60",
            "--inconsistent",
            "0",
            "--start",
            "unknown",
        ]);
        let l = &v["localization"];
        assert_eq!(l["wrong_handoffs"], serde_json::json!([]), "seed {seed}: {l}");
        // Solved: the niche, seen from the corridor, settles it.
        assert!(!l["first_convergence"].is_null(), "seed {seed}: {l}");
        if l["off_cycles"].as_u64().unwrap() > 0 {
            assert_eq!(l["off_cycles_known"].as_f64().unwrap(), 1.0, "seed {seed}: {l}");
        }
    }
}
