//! The referencing models against an independent f64 oracle
//! (`common/referencing_oracle.rs`, written from DESIGN §4.6's definitions):
//! `range_model`'s h and Jacobian for plane and point targets (central
//! differences in f64), `compose`'s F and G, `wrap`, and `Motion::between`.
//!
//! Tolerances are in units of `f32::EPSILON` (ε ≈ 1.2e-7) times the size of
//! the numbers the f32 code works with: poses and targets up to 10 m, so the
//! transducer-to-target differences are formed from numbers up to ~21 m and
//! carry an absolute rounding error of a few ε·21 m; a normalised direction
//! d/|d| then carries that error divided by |d|. The numerical derivatives
//! (step 1e-6 in f64) are good to ~1e-9, far below any of these.

// Matrices and 3-vectors read best indexed.
#![allow(clippy::needless_range_loop)]

#[path = "common/referencing_oracle.rs"]
mod oracle;

use std::f32::consts::PI as PI32;
use std::f64::consts::PI;

use echoloc::predict::PIONEER16;
use echoloc::referencing::{compose, range_model, sensor_position, wrap, Motion, MountM, Target};
use oracle::*;
use proptest::prelude::*;

const STEP: f64 = 1e-6;

fn pose() -> impl Strategy<Value = [f32; 3]> {
    (-10.0f32..10.0, -10.0f32..10.0, -4.0f32..4.0).prop_map(|(x, y, p)| [x, y, p])
}

/// A Pioneer ring mount, or a random one within 0.3 m of the centre.
fn mount() -> impl Strategy<Value = (f64, f64)> {
    let ring = pioneer_m();
    prop_oneof![
        (0usize..16).prop_map(move |i| ring[i]),
        (-0.3f32..0.3, -0.3f32..0.3).prop_map(|(x, y)| (x as f64, y as f64)),
    ]
}

fn plane() -> impl Strategy<Value = Target> {
    (-10.0f32..10.0, -10.0f32..10.0, -PI..PI)
        .prop_map(|(px, py, a)| Target::Plane { point: [px, py], normal: [a.cos() as f32, a.sin() as f32] })
}

fn point() -> impl Strategy<Value = Target> {
    (-10.0f32..10.0, -10.0f32..10.0).prop_map(|(px, py)| Target::Point { point: [px, py] })
}

/// The size of the numbers the f32 code combines, m.
fn scale(x: &[f32; 3], m: (f64, f64), t: &Target) -> f64 {
    let p = match *t {
        Target::Plane { point, .. } | Target::Point { point } => point,
    };
    1.0 + x[0].abs().max(x[1].abs()) as f64 + p[0].abs().max(p[1].abs()) as f64 + m.0.hypot(m.1)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    /// Plane: h = |n·(s − p)| / |n|, its gradient by central differences.
    #[test]
    fn plane_h_and_jacobian(x in pose(), m in mount(), t in plane()) {
        let x6 = x64(&x);
        let t6 = T64::of(&t);
        let h_ref = h64(&x6, m, &t6);
        // Away from the line (the Jacobian jumps there), well beyond the step.
        prop_assume!(h_ref > 1e-3);
        let sc = scale(&x, m, &t);
        let (h, j) = range_model(&x, mount32(m), &t).expect("a plane always has a range");
        prop_assert!((h as f64 - h_ref).abs() <= 16.0 * EPS32 * sc, "h {h} vs {h_ref}");
        let g = grad(|y| h64(y, m, &t6), &x6, STEP);
        for i in 0..3 {
            // ±n exactly up to its own rounding; n·ds with |ds| = |m| ≤ 0.3.
            prop_assert!((j[i] as f64 - g[i]).abs() <= 2e-6, "J[{i}] {j:?} vs {g:?}");
        }
    }

    /// Point: h = |s − p|, its gradient by central differences.
    #[test]
    fn point_h_and_jacobian(x in pose(), m in mount(), t in point()) {
        let x6 = x64(&x);
        let t6 = T64::of(&t);
        let h_ref = h64(&x6, m, &t6);
        prop_assume!(h_ref > 0.05);
        let sc = scale(&x, m, &t);
        let (h, j) = range_model(&x, mount32(m), &t).expect("the transducer is off the point");
        prop_assert!((h as f64 - h_ref).abs() <= 16.0 * EPS32 * sc, "h {h} vs {h_ref}");
        let g = grad(|y| h64(y, m, &t6), &x6, STEP);
        let tol = 2e-6 + 16.0 * EPS32 * sc / h_ref;
        for i in 0..3 {
            prop_assert!((j[i] as f64 - g[i]).abs() <= tol, "J[{i}] {j:?} vs {g:?} (tol {tol})");
        }
    }

    /// A point target a fraction of a millimetre to a centimetre from the
    /// transducer: still a range, a unit direction, and the heading term
    /// consistent with it.
    #[test]
    fn point_nearly_on_the_transducer(x in pose(), m in mount(), r in 1e-4f64..1e-2, a in -PI..PI) {
        let x6 = x64(&x);
        let s = sensor64(&x6, m);
        let t = Target::Point { point: [(s[0] + r * a.cos()) as f32, (s[1] + r * a.sin()) as f32] };
        let t6 = T64::of(&t);
        let h_ref = h64(&x6, m, &t6);
        let sc = scale(&x, m, &t);
        let err = 16.0 * EPS32 * sc;
        prop_assume!(h_ref > 4.0 * err);
        let (h, j) = range_model(&x, mount32(m), &t).expect("off the point");
        prop_assert!((h as f64 - h_ref).abs() <= err, "h {h} vs {h_ref}");
        let n = (j[0] as f64).hypot(j[1] as f64);
        prop_assert!((n - 1.0).abs() < 1e-5, "|∂h/∂(x,y)| = {n}");
        let g = grad(|y| h64(y, m, &t6), &x6, 1e-3 * h_ref);
        // The direction is known to err/h; the step error is (step/h)² ~ 1e-6.
        let tol = 1e-5 + 2.0 * err / h_ref;
        for i in 0..3 {
            prop_assert!((j[i] as f64 - g[i]).abs() <= tol * (1.0 + m.0.hypot(m.1)), "J {j:?} vs {g:?}");
        }
    }

    /// The transducer position and its φ-derivative.
    #[test]
    fn sensor_position_and_derivative(x in pose(), m in mount()) {
        let x6 = x64(&x);
        let (p, dp) = sensor_position(&x, mount32(m));
        let s = sensor64(&x6, m);
        let sc = 1.0 + x[0].abs().max(x[1].abs()) as f64;
        for i in 0..2 {
            prop_assert!((p[i] as f64 - s[i]).abs() <= 4.0 * EPS32 * sc);
            let d = (sensor64(&[x6[0], x6[1], x6[2] + STEP], m)[i] - sensor64(&[x6[0], x6[1], x6[2] - STEP], m)[i])
                / (2.0 * STEP);
            prop_assert!((dp[i] as f64 - d).abs() <= 1e-6, "dp {dp:?}");
        }
    }

    /// `compose`: next against the f64 composition, F = ∂next/∂x and
    /// G = ∂next/∂u against central differences (heading differences taken
    /// on the circle).
    #[test]
    fn compose_and_its_jacobians(x in pose(), dx in -5.0f32..5.0, dy in -5.0f32..5.0, dphi in -10.0f32..10.0) {
        let u = Motion { dx, dy, dphi };
        let (next, f, g) = compose(&x, &u);
        let x6 = x64(&x);
        let u6 = [dx as f64, dy as f64, dphi as f64];
        let r = compose64(&x6, &u6);
        let sc = 1.0 + x[0].abs().max(x[1].abs()) as f64 + dx.abs().max(dy.abs()) as f64;
        prop_assert!((next[0] as f64 - r[0]).abs() <= 16.0 * EPS32 * sc);
        prop_assert!((next[1] as f64 - r[1]).abs() <= 16.0 * EPS32 * sc);
        prop_assert!(next[2] > -PI32 && next[2] <= PI32, "heading {} not wrapped", next[2]);
        prop_assert!(angle_diff(next[2] as f64, r[2]).abs() <= 8.0 * EPS32 * (1.0 + (x6[2] + u6[2]).abs()));
        let d = |v: [f64; 3], w: [f64; 3]| [v[0] - w[0], v[1] - w[1], angle_diff(v[2], w[2])];
        let tol = 8.0 * EPS32 * (1.0 + sc);
        for k in 0..3 {
            let (mut a, mut b) = (x6, x6);
            a[k] += STEP;
            b[k] -= STEP;
            let nf = d(compose64(&a, &u6), compose64(&b, &u6));
            let (mut a, mut b) = (u6, u6);
            a[k] += STEP;
            b[k] -= STEP;
            let ng = d(compose64(&x6, &a), compose64(&x6, &b));
            for i in 0..3 {
                prop_assert!((f[i][k] as f64 - nf[i] / (2.0 * STEP)).abs() <= tol, "F {f:?} at ({i},{k})");
                prop_assert!((g[i][k] as f64 - ng[i] / (2.0 * STEP)).abs() <= tol, "G {g:?} at ({i},{k})");
            }
        }
    }

    /// `wrap` of any angle up to cumulative headings of 10⁴ rad: the same
    /// angle on the circle (to a few ε of |a|: the f32 2π itself is off by
    /// 1.7e-7, times the number of turns removed), and unchanged inside
    /// (−π, π].
    #[test]
    fn wrap_is_the_same_angle(a in prop_oneof![-4.0f32..4.0, -20.0f32..20.0, -1e4f32..1e4]) {
        let w = wrap(a);
        let e = angle_diff(w as f64, a as f64);
        prop_assert!(e.abs() <= 4e-7 + 4.0 * EPS32 * (a.abs() as f64), "wrap({a}) = {w}, off by {e}");
        prop_assert!(angle_diff(w as f64, wrap64(a as f64)).abs() <= 4e-7 + 4.0 * EPS32 * (a.abs() as f64));
        if a > -PI32 && a <= PI32 {
            prop_assert_eq!(w.to_bits(), a.to_bits());
        }
        prop_assert!(w.abs() <= PI32 + 1e-5);
        prop_assert_eq!(wrap(w).to_bits(), w.to_bits());
    }

    /// `Motion::between` against its f64 formula (the displacement rotated
    /// into `a`'s frame, the turn reduced to (−π, π]), for wrapped and for
    /// cumulative headings; and composing it back lands on `b`.
    #[test]
    fn between_against_f64(
        a in pose(),
        (bx, by) in (-10.0f32..10.0, -10.0f32..10.0),
        base in prop_oneof![Just(0.0f32), -50.0f32..50.0, -1e4f32..1e4],
        turn in prop_oneof![-0.5f32..0.5, -10.0f32..10.0, Just(0.0f32)],
    ) {
        // Cumulative odometry: both headings offset by the same number of
        // turns, b's heading `turn` after a's.
        let a = [a[0], a[1], base + a[2]];
        let b = [bx, by, a[2] + turn];
        let u = Motion::between(a, b);
        let (s, c) = (a[2] as f64).sin_cos();
        let (gx, gy) = (bx as f64 - a[0] as f64, by as f64 - a[1] as f64);
        let (dx, dy) = (c * gx + s * gy, -s * gx + c * gy);
        let tol = 1e-7 + 4.0 * EPS32 * (gx.abs() + gy.abs());
        prop_assert!((u.dx as f64 - dx).abs() <= tol, "dx {} vs {dx}", u.dx);
        prop_assert!((u.dy as f64 - dy).abs() <= tol, "dy {} vs {dy}", u.dy);
        let dphi = wrap64(b[2] as f64 - a[2] as f64);
        let big = (a[2].abs() + b[2].abs()) as f64;
        prop_assert!(angle_diff(u.dphi as f64, dphi).abs() <= 4e-7 + 2.0 * EPS32 * big, "dphi {} vs {dphi}", u.dphi);
        prop_assert!(u.dphi.abs() <= PI32 + 1e-5);
        // Round trip: a ⊕ between(a, b) = b (heading on the circle).
        let back = compose64(&x64(&a), &[u.dx as f64, u.dy as f64, u.dphi as f64]);
        prop_assert!((back[0] - bx as f64).abs() <= 2.0 * tol + 1e-6 && (back[1] - by as f64).abs() <= 2.0 * tol + 1e-6);
        prop_assert!(angle_diff(back[2], b[2] as f64).abs() <= 1e-6 + 4.0 * EPS32 * big);
    }
}

/// The ring's mounts convert to metres as the table says.
#[test]
fn mounts_in_metres() {
    for (m, r) in PIONEER16.iter().zip(pioneer_m()) {
        let mm = MountM::from(m);
        assert_eq!((mm.x, mm.y), (r.0 as f32, r.1 as f32));
    }
}

/// A point target exactly on the transducer has no Jacobian: `None`, not NaN.
#[test]
fn point_on_the_transducer_is_none() {
    let x = [1.25f32, -3.5, 0.0];
    assert_eq!(range_model(&x, MountM { x: 0.0, y: 0.0 }, &Target::Point { point: [1.25, -3.5] }), None);
    // φ = 0: the transducer is at (x + mx, y + my), formed the same way.
    let m = MountM { x: 0.17, y: -0.025 };
    let t = Target::Point { point: [x[0] + m.x, x[1] + m.y] };
    assert_eq!(range_model(&x, m, &t), None);
}

/// The next f32 up (`d` = 1) or down (−1), for finite non-zero `a`.
fn step_ulp(a: f32, d: i32) -> f32 {
    let away = (d > 0) == (a > 0.0);
    f32::from_bits(if away { a.to_bits() + 1 } else { a.to_bits() - 1 })
}

/// Every f32 within 64 ulps of an odd multiple of π up to |a| ≈ 3 000 rad
/// (cumulative headings after a few hundred turns): `wrap` lands in
/// (−π, π] and names the same angle.
fn near_odd_multiples_of_pi() -> Vec<f32> {
    let mut v = Vec::new();
    for k in -480i64..480 {
        let c = ((2 * k + 1) as f64 * PI) as f32;
        let mut a = c;
        for _ in 0..64 {
            a = step_ulp(a, -1);
        }
        for _ in 0..129 {
            v.push(a);
            a = step_ulp(a, 1);
        }
    }
    v
}

#[test]
fn wrap_near_odd_multiples_of_pi_names_the_same_angle() {
    for a in near_odd_multiples_of_pi() {
        let w = wrap(a);
        let e = angle_diff(w as f64, a as f64);
        assert!(e.abs() <= 4e-7 + 4.0 * EPS32 * a.abs() as f64, "wrap({a}) = {w}, off by {e}");
    }
}

#[test]
fn wrap_near_odd_multiples_of_pi_stays_in_range() {
    let bad: Vec<(f32, f32)> = near_odd_multiples_of_pi()
        .into_iter()
        .map(|a| (a, wrap(a)))
        .filter(|&(_, w)| !(w > -PI32 && w <= PI32))
        .collect();
    assert!(bad.is_empty(), "{} inputs wrap out of (−π, π], e.g. {:?}", bad.len(), &bad[..bad.len().min(5)]);
}
