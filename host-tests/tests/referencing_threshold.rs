//! The paper's threshold method (`referencing::threshold`) against the f64
//! oracle in `common/referencing_oracle.rs`: differences up to the threshold
//! and beyond the association window leave the pose alone; a difference
//! between them moves it by Δ = W∇h·ν / (∇hᵀW∇h), after which h (recomputed
//! in f64) equals the reading: exactly where h is linear along the step
//! (a transducer at the robot's centre), to within the Taylor remainder
//! ½·max‖∇²h‖·|Δ|² where the mount offset makes it curve.

// Matrices and 3-vectors read best indexed.
#![allow(clippy::needless_range_loop)]

#[path = "common/referencing_oracle.rs"]
mod oracle;

use std::f64::consts::PI;

use echoloc::referencing::{Motion, Target, Threshold, ThresholdConfig};
use oracle::*;
use proptest::prelude::*;

const CFG: ThresholdConfig = ThresholdConfig::DEFAULT;

fn pose() -> impl Strategy<Value = [f32; 3]> {
    (-10.0f32..10.0, -10.0f32..10.0, -3.1f32..3.1).prop_map(|(x, y, p)| [x, y, p])
}

fn mount() -> impl Strategy<Value = (f64, f64)> {
    let ring = pioneer_m();
    prop_oneof![
        (0usize..16).prop_map(move |i| ring[i]),
        (-0.3f32..0.3, -0.3f32..0.3).prop_map(|(x, y)| (x as f64, y as f64)),
    ]
}

fn target() -> impl Strategy<Value = Target> {
    prop_oneof![
        (-10.0f32..10.0, -10.0f32..10.0, -PI..PI)
            .prop_map(|(px, py, a)| Target::Plane { point: [px, py], normal: [a.cos() as f32, a.sin() as f32] }),
        (-10.0f32..10.0, -10.0f32..10.0).prop_map(|(px, py)| Target::Point { point: [px, py] }),
    ]
}

fn sign() -> impl Strategy<Value = f64> {
    prop_oneof![Just(1.0), Just(-1.0)]
}

fn scale(x: &[f32; 3], t: &Target) -> f64 {
    let p = match *t {
        Target::Plane { point, .. } | Target::Point { point } => point,
    };
    1.0 + x[0].abs().max(x[1].abs()) as f64 + p[0].abs().max(p[1].abs()) as f64
}

fn unchanged(t: &Threshold, x: &[f32; 3]) -> bool {
    let s = t.state();
    (0..3).all(|i| s[i].to_bits() == x[i].to_bits()) && t.corrections() == 0
}

/// Runs one reading `delta` beyond the f64 range at `x`; returns the filter
/// and whether it moved.
fn one(x: [f32; 3], m: (f64, f64), t: &Target, delta: f64, kappa: f32) -> (Threshold, bool, f32) {
    let h = h64(&x64(&x), m, &T64::of(t));
    let z = (h + delta) as f32;
    let mut th = Threshold::new(x, CFG);
    let moved = th.update(z, kappa, mount32(m), t);
    (th, moved, z)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn small_differences_do_nothing(x in pose(), m in mount(), t in target(), d in 0.0f64..0.045, s in sign()) {
        prop_assume!(h64(&x64(&x), m, &T64::of(&t)) > 0.3);
        let (th, moved, _) = one(x, m, &t, s * d, 1.0);
        prop_assert!(!moved && unchanged(&th, &x));
    }

    #[test]
    fn differences_beyond_the_window_do_nothing(x in pose(), m in mount(), t in target(), d in 0.31f64..5.0, s in sign()) {
        prop_assume!(h64(&x64(&x), m, &T64::of(&t)) > 0.3);
        let (th, moved, _) = one(x, m, &t, s * d, 1.0);
        prop_assert!(!moved && unchanged(&th, &x));
    }

    #[test]
    fn doubtful_readings_do_nothing(x in pose(), m in mount(), t in target(), d in 0.06f64..0.29, k in 0.0f32..0.49) {
        prop_assume!(h64(&x64(&x), m, &T64::of(&t)) > 0.3);
        let (th, moved, _) = one(x, m, &t, d, k);
        prop_assert!(!moved && unchanged(&th, &x));
    }

    /// Inside the window: the step is W∇h·ν/(∇hᵀW∇h) with ∇h by central
    /// differences, and h after it equals z up to the Taylor remainder.
    #[test]
    fn differences_inside_move_the_pose_onto_the_reading(
        x in pose(), m in mount(), t in target(), d in 0.055f64..0.295, s in sign(), k in 0.5f32..=1.0,
    ) {
        let x6 = x64(&x);
        let t6 = T64::of(&t);
        let h0 = h64(&x6, m, &t6);
        prop_assume!(h0 > 0.3);
        let (th, moved, z) = one(x, m, &t, s * d, k);
        prop_assert!(moved && th.corrections() == 1);
        let y = th.state();
        let step = [y[0] as f64 - x6[0], y[1] as f64 - x6[1], angle_diff(y[2] as f64, x6[2])];
        // The step against the oracle's.
        let g = grad(|p| h64(p, m, &t6), &x6, 1e-6);
        let w = [1.0, 1.0, 1.0 / (CFG.lever_m as f64).powi(2)];
        let den: f64 = (0..3).map(|i| w[i] * g[i] * g[i]).sum();
        let nu = z as f64 - h0;
        let sc = scale(&x, &t);
        let tol = 1e-5 + 16.0 * EPS32 * sc * (1.0 + 1.0 / h0);
        for i in 0..3 {
            let want = w[i] * g[i] * nu / den;
            prop_assert!((step[i] - want).abs() <= tol, "step {step:?}, want Δ[{i}] = {want}");
        }
        // h after the step: the reading, up to ½·M·|Δ|².
        let n2: f64 = step.iter().map(|v| v * v).sum();
        let lever = m.0.hypot(m.1);
        let big_m = match t6 {
            T64::Line { .. } => lever,
            T64::Point { .. } => {
                let h_min = h0 - n2.sqrt() * (1.0 + lever);
                prop_assume!(h_min > 0.1);
                (1.0 + lever * lever) / h_min + lever
            }
        };
        let h1 = h64(&x64(&y), m, &t6);
        let bound = 0.5 * big_m * n2 + 16.0 * EPS32 * sc;
        prop_assert!((h1 - z as f64).abs() <= bound, "h after {h1}, z {z}, bound {bound}");
        // And it is a real correction: most of the difference is gone.
        prop_assert!((h1 - z as f64).abs() <= 0.1 * nu.abs(), "h after {h1}, z {z}, ν {nu}");
    }

    /// A transducer at the robot's centre: h is linear along the step (a
    /// plane's distance along its normal, a point's along the ray), so the
    /// pose lands exactly on the reading, and the heading does not move.
    #[test]
    fn centred_transducer_lands_exactly(x in pose(), t in target(), d in 0.055f64..0.295, s in sign()) {
        let m = (0.0, 0.0);
        let t6 = T64::of(&t);
        prop_assume!(h64(&x64(&x), m, &t6) > 0.3);
        let (th, moved, z) = one(x, m, &t, s * d, 1.0);
        prop_assert!(moved);
        let y = th.state();
        prop_assert_eq!(y[2].to_bits(), x[2].to_bits());
        let h1 = h64(&x64(&y), m, &t6);
        prop_assert!((h1 - z as f64).abs() <= 16.0 * EPS32 * scale(&x, &t), "h after {h1}, z {z}");
    }

    /// Dead reckoning is the f64 composition; a non-finite motion is ignored.
    #[test]
    fn dead_reckoning_composes(x in pose(), dx in -2.0f32..2.0, dy in -0.5f32..0.5, dphi in -4.0f32..4.0) {
        let mut th = Threshold::new(x, CFG);
        th.predict(&Motion { dx, dy, dphi });
        let r = compose64(&x64(&x), &[dx as f64, dy as f64, dphi as f64]);
        let y = th.state();
        prop_assert!((y[0] as f64 - r[0]).abs() <= 32.0 * EPS32 * 12.0 && (y[1] as f64 - r[1]).abs() <= 32.0 * EPS32 * 12.0);
        prop_assert!(angle_diff(y[2] as f64, r[2]).abs() <= 1e-6);
        let before = th;
        th.predict(&Motion { dx: f32::NAN, dy: 0.0, dphi: 0.0 });
        th.predict(&Motion { dx: 0.0, dy: 0.0, dphi: f32::INFINITY });
        prop_assert_eq!(th, before);
    }
}

#[test]
fn non_finite_readings_do_nothing() {
    let x = [1.0f32, 0.5, 0.3];
    let wall = Target::Plane { point: [3.0, 0.0], normal: [-1.0, 0.0] };
    let mut th = Threshold::new(x, CFG);
    for (z, k) in [(f32::NAN, 1.0), (f32::INFINITY, 1.0), (f32::NEG_INFINITY, 1.0), (1.9, f32::NAN)] {
        assert!(!th.update(z, k, mount32((0.17, 0.025)), &wall), "z {z} κ {k}");
    }
    assert!(unchanged(&th, &x));
}

/// Corrections accumulate: repeated readings of two perpendicular walls from
/// a pose 0.2 m off put it back within the threshold of the truth.
#[test]
fn repeated_readings_walk_the_pose_back() {
    let ring = pioneer_m();
    let truth = [2.0f64, 1.0, 0.0];
    let walls = [
        Target::Plane { point: [5.0, 0.0], normal: [-1.0, 0.0] },
        Target::Plane { point: [0.0, 3.0], normal: [0.0, -1.0] },
    ];
    let mut th = Threshold::new([2.2, 0.8, 0.0], CFG);
    for _ in 0..10 {
        for (i, w) in [(3, 0), (4, 0), (0, 1), (15, 1)] {
            let z = h64(&truth, ring[i], &T64::of(&walls[w])) as f32;
            th.update(z, 1.0, mount32(ring[i]), &walls[w]);
        }
    }
    let y = th.state();
    assert!(th.corrections() >= 2);
    for (w, (i, _)) in walls.iter().zip([(3, 0), (0, 1)]) {
        let r = (h64(&x64(&y), ring[i], &T64::of(w)) - h64(&truth, ring[i], &T64::of(w))).abs();
        assert!(r <= CFG.threshold_m as f64 + 1e-6, "{y:?}: off by {r}");
    }
}
