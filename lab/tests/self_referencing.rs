//! Self-referencing in the simulator, end to end (issue #10's figures, in
//! CI): the EKF holds the pose on the real depot map over a 200 m route
//! while dead reckoning drifts past a metre; the predictor's agreement with
//! the independent simulated sonar is measured; the verdicts find the
//! clutter. The bounds are the targets where they are met, and
//! floors under today's measurement where they are not (those are stated
//! as such; docs/self-referencing.md has the figures and the commands).

mod common;

use common::{num, shared_map, simulate};

/// depot, seed 3, 200 m, half the readings inconsistent with the map: the
/// issue's targets (EKF position RMSE ≤ 5 cm, heading RMSE ≤ 1°) while dead
/// reckoning drifts past 1 m.
#[test]
fn ekf_holds_the_pose_on_depot_while_dead_reckoning_drifts() {
    let depot = shared_map("depot.yaml");
    let v = simulate(&["--map", depot.to_str().unwrap(), "--seed", "3"]);
    assert!(num(&v, "distance_m") >= 199.0, "{v}");
    let (p, h) = (num(&v, "ekf.position_rmse_m"), num(&v, "ekf.heading_rmse_deg"));
    assert!(p <= 0.05 && h <= 1.0, "EKF position RMSE {p} m, heading RMSE {h}°");
    assert!(num(&v, "ekf.max_position_error_m") < 0.5, "{v}");
    assert!(num(&v, "dead_reckoning.max_position_error_m") > 1.0, "{v}");
    // The threshold method is the paper's baseline: measured, not bounded,
    // but it must at least have acted.
    assert!(num(&v, "threshold.corrections") > 0.0);
    assert!((num(&v, "inconsistent_fraction") - 0.5).abs() <= 0.05, "{v}");
}

/// tb3_sandbox, three seeds, 60 m: position within the target on each.
#[test]
fn ekf_holds_the_pose_on_tb3_sandbox() {
    let map = shared_map("tb3_sandbox.yaml");
    for seed in ["1", "2", "3"] {
        let v = simulate(&["--map", map.to_str().unwrap(), "--seed", seed, "--distance-m", "60"]);
        let p = num(&v, "ekf.position_rmse_m");
        assert!(p <= 0.05, "seed {seed}: EKF position RMSE {p} m");
        assert!(num(&v, "ekf.max_position_error_m") < 0.2, "seed {seed}: {v}");
        assert_eq!(num(&v, "lost.raised"), 0.0, "seed {seed}: lost in a tracking run");
    }
}

/// tb3_sandbox, seed 2, 200 m: the seed whose heading RMSE was 1.55° before
/// the EKF learned its odometry's systematic errors. The heading target,
/// and the learned errors against the ones the simulator drew (its wheel
/// radii and wheelbase put through the odometry's kinematics,
/// `OdometryErrors::heading_bias`): a turn error of 1.25 % and a drift of
/// 0.22°/m, which learning nothing would miss by all of that.
#[test]
fn ekf_learns_the_odometry_errors_the_simulator_drew() {
    let map = shared_map("tb3_sandbox.yaml");
    let v = simulate(&["--map", map.to_str().unwrap(), "--seed", "2"]);
    let (p, h) = (num(&v, "ekf.position_rmse_m"), num(&v, "ekf.heading_rmse_deg"));
    assert!(p <= 0.05 && h <= 1.0, "EKF position RMSE {p} m, heading RMSE {h}°");
    let (turn, drift) =
        (num(&v, "odometry_errors.heading_bias.per_rad"), num(&v, "odometry_errors.heading_bias.per_m"));
    assert!(turn.abs() > 0.01 && drift.abs() > 0.003, "the seed's errors are no longer large: {v}");
    let (l_turn, l_drift) = (num(&v, "ekf.odometry_calibration.per_rad"), num(&v, "ekf.odometry_calibration.per_m"));
    assert!((l_turn - turn).abs() <= 0.2 * turn.abs(), "turn error learned {l_turn}, drawn {turn}");
    assert!((l_drift - drift).abs() <= 0.2 * drift.abs(), "drift learned {l_drift} rad/m, drawn {drift}");
    // Without the calibration the same run's heading is worse.
    let off = simulate(&["--map", map.to_str().unwrap(), "--seed", "2", "--no-calibration"]);
    assert!(off["ekf"]["odometry_calibration"].is_null(), "{off}");
    assert_eq!(off["dead_reckoning"], v["dead_reckoning"]);
    assert!(num(&off, "ekf.heading_rmse_deg") > h, "{off}");
}

/// Where the predictor is confident (κ ≥ 0.9, no nearer mapped surface a
/// sonar may hear in the beam) and the scene is clean, how often the
/// simulated sonar reads within the prediction's tolerance: the issue's
/// ≥ 95 % (measured on these runs: 97.9 % on depot, 99.3 % on
/// tb3_sandbox; 79 % and 86 % before the nearer-surface check). And the
/// check is informative, not a way to drop the hard cases: where it makes a
/// κ-confident prediction ambiguous, the reading is (nearly always) either
/// the prediction's or from the nearer surface's range on, and most
/// κ-confident predictions stay unambiguous.
#[test]
fn predictor_and_simulated_sonar_agree_where_the_predictor_is_confident() {
    for map in ["depot.yaml", "tb3_sandbox.yaml"] {
        let m = shared_map(map);
        let v = simulate(&["--map", m.to_str().unwrap(), "--seed", "1", "--inconsistent", "0", "--distance-m", "60"]);
        let a = &v["agreement"];
        let (n, within) = (num(a, "confident"), num(a, "within_tolerance"));
        let amb = num(a, "ambiguous.confident_but_nearer_surface");
        assert!(n > 400.0 && n + amb > 500.0, "{map}: too few confident predictions: {a}");
        assert!(within / n >= 0.95, "{map}: agreement {} below 0.95: {a}", within / n);
        let explained = num(a, "ambiguous.within_tolerance") + num(a, "ambiguous.from_the_nearer_surface");
        assert!(explained >= 0.9 * amb, "{map}: the nearer surfaces do not explain the short echoes: {a}");
        assert!(n > amb, "{map}: most confident predictions should stay unambiguous: {a}");
    }
}

/// With clutter, the verdicts flag unmapped objects: most unknown-obstacle
/// verdicts are real (precision) and echoes from unmapped objects are
/// flagged (recall). The nearer-surface check trades recall for precision:
/// an echo a nearer mapped surface may have returned is inconclusive, not
/// an unknown obstacle, which on this small arena (walls within a metre of
/// most beams) leaves undecided many echoes of people standing in front of
/// such a surface. Without the check, the same run: lower precision,
/// higher recall (measured: 0.71 / 0.26 with it, 0.69 / 0.42 without).
#[test]
fn verdicts_find_unmapped_objects() {
    let m = shared_map("tb3_sandbox.yaml");
    let args = ["--map", m.to_str().unwrap(), "--seed", "4", "--distance-m", "40", "--inconsistent", "0.4"];
    let v = simulate(&args);
    let d = &v["detection"]["unknown_obstacle"];
    assert!(num(d, "precision") > 0.65 && num(d, "recall") > 0.2, "{d}");
    assert!(num(&v, "verdicts.confirmed") > 0.0 && num(&v, "verdicts.unknown_obstacle") > 0.0, "{v}");
    let off = simulate(&[&args[..], &["--no-nearer-check"]].concat());
    let o = &off["detection"]["unknown_obstacle"];
    assert!(num(o, "precision") < num(d, "precision") && num(o, "recall") > num(d, "recall"), "with {d}, without {o}");
    assert_eq!(off["dead_reckoning"], v["dead_reckoning"]);
}

/// The QEMU board's scenario (`boards/qemu-mps2-an386/depot.scn`, replayed
/// by the README's main command through the real driver) is what the
/// simulator makes today, and `scenario replay` gives the simulate run's
/// figures for it.
#[test]
fn checked_in_board_scenario_is_fresh() {
    let out = common::tmp("self-ref", "depot.scn");
    let map = common::root().join("boards/qemu-mps2-an386/depot.map");
    let args =
        ["--map", map.to_str().unwrap(), "--seed", "1", "--distance-m", "40", "--scenario", out.to_str().unwrap()];
    let v = simulate(&args);
    common::assert_blob_fresh(
        &out,
        "boards/qemu-mps2-an386/depot.scn",
        "cargo run --release -p echoloc-lab -- simulate --map boards/qemu-mps2-an386/depot.map --seed 1 --distance-m 40 --scenario boards/qemu-mps2-an386/depot.scn",
    );
    let o = common::lab()
        .args(["scenario", "replay", "--json", "--map", map.to_str().unwrap()])
        .arg(common::root().join("boards/qemu-mps2-an386/depot.scn"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["ekf"], v["ekf"], "replay {r}\nsimulate {v}");
    // The board's bounds hold with room: a tracking run, not a marginal one.
    assert!(num(&v, "ekf.position_rmse_m") <= 0.03 && num(&v, "ekf.heading_rmse_deg") <= 0.7, "{v}");
}
