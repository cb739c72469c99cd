//! Recovery of a lost filter (`referencing::recovery`) against independent
//! oracles (`common/referencing_oracle.rs`: f64 range models written from
//! their definitions; the pose arithmetic here, in f64):
//!
//! - a reading's Jacobian carried through odometry predicts, for a
//!   correction of the current pose, the range the reading would have had
//!   from the old pose that the same odometry takes to the corrected one;
//! - the search finds a planted correction among clutter, and finds
//!   nothing in clutter alone or when the estimate is already right;
//! - a confident filter knocked off its pose becomes lost, recovers to the
//!   truth and tracks again; without recovery it stays lost.

#![allow(clippy::needless_range_loop)]

#[path = "common/referencing_oracle.rs"]
mod oracle;

use echoloc::referencing::{compose, range_model, Ekf, EkfConfig, Motion, Recent, RecoveryConfig, Target, Update};
use oracle::*;

/// The pose that `steps` of odometry take to `to`: each step undone in f64
/// (φ first, then the step's translation in the frame it was driven in).
fn undo(to: [f64; 3], steps: &[Motion]) -> [f64; 3] {
    let mut p = to;
    for u in steps.iter().rev() {
        let phi = p[2] - u.dphi as f64;
        let (s, c) = phi.sin_cos();
        let (dx, dy) = (u.dx as f64, u.dy as f64);
        p = [p[0] - (c * dx - s * dy), p[1] - (s * dx + c * dy), phi];
    }
    p
}

fn random_target(rng: &mut Rng, near: [f64; 3]) -> Target {
    if rng.range(0.0, 1.0) < 0.5 {
        let a = rng.range(-3.2, 3.2);
        let d = rng.range(1.0, 4.0);
        let p = [near[0] + d * a.cos(), near[1] + d * a.sin()];
        let n = [-(a.cos()), -(a.sin())];
        Target::Plane { point: [p[0] as f32, p[1] as f32], normal: [n[0] as f32, n[1] as f32] }
    } else {
        let a = rng.range(-3.2, 3.2);
        let d = rng.range(1.0, 4.0);
        Target::Point { point: [(near[0] + d * a.cos()) as f32, (near[1] + d * a.sin()) as f32] }
    }
}

/// 1 000 random readings, each carried through 1–20 random odometry steps
/// (up to 4 m and 3 rad in all): the residual the carried Jacobian predicts
/// for a correction δ (up to 5 cm and 0.6°) of the current pose matches the
/// oracle's range from the corrected old pose within 2 mm (the linear
/// model's second-order error), and the uncorrected residual does not.
#[test]
fn a_carried_jacobian_predicts_the_range_from_the_corrected_old_pose() {
    let mut rng = Rng::new(11);
    let ring = pioneer_m();
    // A tolerance of 2 mm: k σ with σ² = r.
    let cfg = RecoveryConfig { k_sigma: 1.0, ..RecoveryConfig::DEFAULT };
    let r = 0.002f32 * 0.002;
    let (mut checked, mut discriminated) = (0, 0);
    for case in 0..1000 {
        let x0 = [rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-3.1, 3.1)];
        let m = ring[case % ring.len()];
        let t = random_target(&mut rng, x0);
        let x0f = [x0[0] as f32, x0[1] as f32, x0[2] as f32];
        let Some((h0, hj)) = range_model(&x0f, mount32(m), &t) else { continue };
        // The odometry after the reading.
        let n = 1 + (rng.next_u64() % 20) as usize;
        let steps: Vec<Motion> = (0..n)
            .map(|_| Motion {
                dx: rng.range(-0.05, 0.2) as f32,
                dy: rng.range(-0.01, 0.01) as f32,
                dphi: rng.range(-0.15, 0.15) as f32,
            })
            .collect();
        // The filter's own compose drives the estimate and gives the
        // Jacobian columns the carry takes.
        let mut x = x0f;
        let mut columns = Vec::new();
        for u in &steps {
            let (next, f, _) = compose(&x, u);
            columns.push((f[0][2], f[1][2]));
            x = next;
        }
        // δ, and the reading the oracle says the corrected old pose gives.
        let d = [rng.range(-0.05, 0.05), rng.range(-0.05, 0.05), rng.range(-0.01, 0.01)];
        let xk = x64(&x);
        let old = undo([xk[0] + d[0], xk[1] + d[1], xk[2] + d[2]], &steps);
        let z = h64(&old, m, &T64::of(&t));
        let mut recent = Recent::new();
        recent.push(hj, (z - h0 as f64) as f32, r);
        for (a, b) in columns {
            recent.carry(a, b);
        }
        let df = [d[0] as f32, d[1] as f32, d[2] as f32];
        assert_eq!(recent.agreeing(df, &cfg), 1, "case {case}: the carried model misses δ {d:?}");
        checked += 1;
        if (z - h0 as f64).abs() > 0.004 {
            assert_eq!(recent.agreeing([0.0; 3], &cfg), 0, "case {case}");
            discriminated += 1;
        }
    }
    assert!(checked > 900 && discriminated > 500, "{checked} checked, {discriminated} discriminating");
}

/// A room's walls, a pillar and two corners.
fn room() -> [Target; 7] {
    [
        Target::Plane { point: [3.0, 0.0], normal: [-1.0, 0.0] },
        Target::Plane { point: [-3.0, 0.0], normal: [1.0, 0.0] },
        Target::Plane { point: [0.0, 3.0], normal: [0.0, -1.0] },
        Target::Plane { point: [0.0, -3.0], normal: [0.0, 1.0] },
        Target::Point { point: [2.0, 3.0] },
        Target::Point { point: [-2.5, -3.0] },
        Target::Point { point: [0.5, 1.5] },
    ]
}

/// The robot drives `steps` (odometry without error) from an estimate
/// `e0`, while truly it drives them from the pose that ends `d` away from
/// the estimate's end; at each step it reads four targets of the room. The
/// readings go into `recent` (Jacobians at the estimate, carried through
/// the odometry); `clutter` of them (every `clutter`-th) are uniform
/// ranges instead.
fn drive(rng: &mut Rng, e0: [f32; 3], d: [f64; 3], steps: &[Motion], clutter: usize, recent: &mut Recent) {
    let mut e = vec![e0];
    for u in steps {
        let last = *e.last().unwrap();
        e.push(compose(&last, u).0);
    }
    let end = x64(e.last().unwrap());
    let t0 = undo([end[0] + d[0], end[1] + d[1], end[2] + d[2]], steps);
    let ring = pioneer_m();
    let targets = room();
    let mut truth = t0;
    let mut n = 0usize;
    for (k, ek) in e.iter().enumerate() {
        for j in 0..4 {
            let m = ring[(k * 5 + j * 4) % ring.len()];
            let t = targets[(k + j * 2) % targets.len()];
            let Some((h, hj)) = range_model(ek, mount32(m), &t) else { continue };
            n += 1;
            let z = if clutter > 0 && n.is_multiple_of(clutter) {
                rng.range(0.3, 5.0)
            } else {
                h64(&truth, m, &T64::of(&t)) + 0.005 * rng.normal()
            };
            recent.push(hj, (z - h as f64) as f32, 0.015 * 0.015);
        }
        if let Some(u) = steps.get(k) {
            let f = compose(ek, u).1;
            recent.carry(f[0][2], f[1][2]);
            let (s, c) = (truth[2]).sin_cos();
            let (dx, dy) = (u.dx as f64, u.dy as f64);
            truth = [truth[0] + c * dx - s * dy, truth[1] + s * dx + c * dy, truth[2] + u.dphi as f64];
        }
    }
}

/// 15 steps of 0.15 m with turns, four readings a step (64), every third a
/// clutter range: the search finds a planted correction of 0.15–0.57 m and
/// up to 4° within 2.5 cm and 0.75° (the linear model's error on the
/// pillar and the corners), with at least half the readings agreeing; the
/// same readings all clutter find nothing, and an estimate that is right
/// is not moved.
#[test]
fn the_search_finds_a_planted_correction_among_clutter_and_nothing_else() {
    let mut rng = Rng::new(5);
    let cfg = RecoveryConfig::DEFAULT;
    let steps: Vec<Motion> =
        (0..15).map(|k| Motion { dx: 0.15, dy: 0.0, dphi: if k % 5 == 4 { 0.3 } else { 0.0 } }).collect();
    for case in 0..40 {
        let e0 = [rng.range(-1.2, -0.8) as f32, rng.range(-0.2, 0.2) as f32, rng.range(-0.2, 0.2) as f32];
        let d = [rng.range(-0.4, 0.4), rng.range(-0.4, 0.4), rng.range(-4.0, 4.0).to_radians()];
        if d[0].hypot(d[1]) < 0.15 {
            continue;
        }
        let mut recent = Recent::new();
        drive(&mut rng, e0, d, &steps, 3, &mut recent);
        assert_eq!(recent.len(), 64);
        let f = recent.search(&cfg).unwrap_or_else(|| panic!("case {case}: nothing found for δ {d:?}"));
        let err = [f.dx[0] as f64 - d[0], f.dx[1] as f64 - d[1], f.dx[2] as f64 - d[2]];
        assert!(
            err[0].abs() < 0.025 && err[1].abs() < 0.025 && err[2].abs() < 0.75f64.to_radians(),
            "case {case}: found {:?} for δ {d:?}",
            f.dx
        );
        assert!(f.inliers >= 32, "case {case}: {} agree", f.inliers);
        let mut clutter = Recent::new();
        drive(&mut rng, e0, d, &steps, 1, &mut clutter);
        assert_eq!(clutter.search(&cfg), None, "case {case}: clutter alone");
        let mut right = Recent::new();
        drive(&mut rng, e0, [0.0; 3], &steps, 3, &mut right);
        assert_eq!(right.search(&cfg), None, "case {case}: a right estimate moved");
    }
}

#[test]
fn recovery_off_and_degenerate_readings_find_nothing() {
    let mut recent = Recent::new();
    // Every reading the same wall: the heading and one axis are not fixed.
    for _ in 0..64 {
        recent.push([-1.0, 0.0, 0.0], -0.2, 1e-4);
    }
    assert_eq!(recent.search(&RecoveryConfig::DEFAULT), None);
    assert_eq!(recent.search(&RecoveryConfig::OFF), None);
    // Non-finite readings are not kept; the buffer holds at most RECENT.
    recent.push([f32::NAN, 0.0, 0.0], 0.0, 1e-4);
    recent.push([0.0, 1.0, 0.0], f32::INFINITY, 1e-4);
    recent.push([0.0, 1.0, 0.0], 0.0, 0.0);
    assert_eq!(recent.len(), echoloc::referencing::recovery::RECENT);
    recent.clear();
    assert!(recent.is_empty());
}

const CYCLE: [(usize, usize); 8] = [(0, 2), (3, 0), (4, 0), (7, 3), (8, 3), (11, 1), (12, 1), (15, 2)];

/// One cycle of readings from the truth: the eight wall readings and a
/// reading of each corner from the side transducers.
fn truth_cycle(ekf: &mut Ekf, truth: [f64; 3]) -> Vec<Update> {
    let ring = pioneer_m();
    let targets = room();
    let mut seen: Vec<(usize, usize)> = CYCLE.to_vec();
    seen.extend([(1, 4), (2, 4), (13, 5), (14, 5)]);
    seen.iter()
        .map(|&(i, t)| {
            let z = h64(&truth, ring[i], &T64::of(&targets[t]));
            ekf.update(z as f32, 1.0, mount32(ring[i]), &targets[t])
        })
        .collect()
}

/// A confident filter 0.3 m and 3° off the truth, driving 0.2 m and
/// turning 3° a cycle (exact odometry), gates every reading, becomes lost
/// at the fifth cycle, recovers there to within 2 cm and 0.5°, and tracks:
/// the next cycle accepts and clears lost. Without recovery the same filter
/// stays lost and where it was.
#[test]
fn a_lost_filter_recovers_its_pose_and_tracks_again() {
    let u = Motion { dx: 0.2, dy: 0.0, dphi: 3f32.to_radians() };
    let step = |x: [f64; 3]| {
        let (s, c) = x[2].sin_cos();
        [x[0] + c * u.dx as f64, x[1] + s * u.dx as f64, x[2] + u.dphi as f64]
    };
    for recover in [true, false] {
        let cfg = EkfConfig {
            recovery: if recover { RecoveryConfig::DEFAULT } else { RecoveryConfig::OFF },
            ..EkfConfig::DEFAULT
        };
        let start = [-1.0f32, -0.5, 0.0];
        let mut truth = [-0.7f64, -0.3, 0.05];
        let mut ekf = Ekf::new(start, [0.01, 0.01, 0.005], cfg).unwrap();
        let n = cfg.lost_cycles as u32;
        for c in 1..=n {
            ekf.predict(&u).unwrap();
            truth = step(truth);
            let ups = truth_cycle(&mut ekf, truth);
            assert!(ups.iter().all(|u| matches!(u, Update::Gated { .. })), "cycle {c}: {ups:?}");
            ekf.end_cycle();
        }
        assert_eq!(ekf.lost_count(), 1);
        if !recover {
            let before = ekf.state();
            truth_cycle(&mut ekf, truth);
            ekf.end_cycle();
            assert!(ekf.is_lost() && ekf.recoveries() == 0);
            assert_eq!(ekf.state(), before);
            continue;
        }
        assert_eq!(ekf.recoveries(), 1);
        let x = x64(&ekf.state());
        let err = [x[0] - truth[0], x[1] - truth[1], x[2] - truth[2]];
        assert!(err[0].abs() < 0.02 && err[1].abs() < 0.02 && err[2].abs() < 0.5f64.to_radians(), "{err:?}");
        assert!(ekf.last_recovery().unwrap().inliers >= 40);
        ekf.predict(&u).unwrap();
        truth = step(truth);
        let ups = truth_cycle(&mut ekf, truth);
        assert!(ups.iter().filter(|u| matches!(u, Update::Accepted { .. })).count() >= 10, "{ups:?}");
        ekf.end_cycle();
        assert!(!ekf.is_lost());
        let x = x64(&ekf.state());
        assert!((x[0] - truth[0]).abs() < 0.01 && (x[1] - truth[1]).abs() < 0.01, "{x:?} vs {truth:?}");
    }
}
