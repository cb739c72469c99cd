//! The reference checked against a brute force: for a sample of windows,
//! the nearest point of every piece inside the cone within `R_max`, in
//! `f64` over all pieces (no grid, no echoloc geometry). Along one edge the
//! distance to the apex is convex, and the part of the edge inside the cone
//! is one interval, so the nearest point is the apex's projection clamped
//! to that interval: an end of the edge inside the cone, a crossing of a
//! boundary ray, or the foot of the perpendicular.

use serde_json::{json, Value};

use super::Win;

type P = (f64, f64);

fn inside_cone(o: P, axis: P, cos_h: f64, p: P) -> bool {
    let v = (p.0 - o.0, p.1 - o.1);
    let n = v.0.hypot(v.1);
    n == 0.0 || v.0 * axis.0 + v.1 * axis.1 >= n * cos_h - 1e-12
}

/// Where the ray `o + t·u` (t ≥ 0) crosses segment `a b`, if it does.
pub(crate) fn ray_cross(o: P, u: P, a: P, b: P) -> Option<P> {
    let e = (b.0 - a.0, b.1 - a.1);
    let den = u.0 * e.1 - u.1 * e.0;
    if den.abs() < 1e-15 {
        return None;
    }
    let w = (a.0 - o.0, a.1 - o.1);
    let t = (w.0 * e.1 - w.1 * e.0) / den;
    let s = (w.0 * u.1 - w.1 * u.0) / den;
    (t >= 0.0 && (0.0..=1.0).contains(&s)).then_some((o.0 + t * u.0, o.1 + t * u.1))
}

fn point_in_convex(p: P, pts: &[P]) -> bool {
    pts.len() >= 3
        && (0..pts.len()).all(|k| {
            let (a, b) = (pts[k], pts[(k + 1) % pts.len()]);
            (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0) >= 0.0
        })
}

/// The nearest obstacle point in the window, m, by brute force, and
/// whether it lies where an edge crosses a boundary ray of the cone.
pub fn nearest(outlines: &[Vec<P>], o: P, heading: f64, half: f64, r_max: f64) -> Option<(f64, bool)> {
    let axis = (heading.cos(), heading.sin());
    let cos_h = half.cos();
    let rays = [(heading - half).cos(), (heading + half).cos()]
        .into_iter()
        .zip([(heading - half).sin(), (heading + half).sin()]);
    let rays: Vec<P> = rays.collect();
    let mut best: Option<(f64, bool)> = None;
    for pts in outlines {
        if point_in_convex(o, pts) {
            return Some((0.0, false));
        }
        let n = pts.len();
        let edges = if n == 2 { 1 } else { n };
        for k in 0..edges {
            let (a, b) = (pts[k], pts[(k + 1) % n]);
            let mut cands = vec![(a, false), (b, false)];
            let e = (b.0 - a.0, b.1 - a.1);
            let ee = e.0 * e.0 + e.1 * e.1;
            if ee > 0.0 {
                let s = (((o.0 - a.0) * e.0 + (o.1 - a.1) * e.1) / ee).clamp(0.0, 1.0);
                cands.push(((a.0 + s * e.0, a.1 + s * e.1), false));
            }
            cands.extend(rays.iter().filter_map(|&u| ray_cross(o, u, a, b)).map(|p| (p, true)));
            for (p, on_boundary) in cands {
                if inside_cone(o, axis, cos_h, p) {
                    let d = (p.0 - o.0).hypot(p.1 - o.1);
                    if d <= r_max && best.is_none_or(|x| d < x.0) {
                        best = Some((d, on_boundary));
                    }
                }
            }
        }
    }
    best
}

/// Checks `reference` (one answer per window) against the brute force on
/// up to 500 windows spread through the list.
pub fn check(
    outlines: &[Vec<P>],
    wins: &[Win],
    reference: &[Option<f64>],
    half: f64,
    r_max: f64,
    half_deg: f64,
) -> Value {
    let step = (wins.len() / 500).max(1);
    let (mut n, mut agree, mut grazing, mut max_diff) = (0usize, 0usize, 0usize, 0f64);
    for (w, r) in wins.iter().zip(reference).step_by(step) {
        n += 1;
        let b = nearest(outlines, w.origin_m(), f64::from(w.heading), half, r_max);
        match (b, *r) {
            (None, None) => agree += 1,
            (Some((x, on_boundary)), Some(y)) => {
                let diff = (x - y).abs();
                if diff <= 0.001 {
                    agree += 1;
                    max_diff = max_diff.max(diff);
                } else if on_boundary && diff <= 0.05 {
                    // The window's boundary directions are integer vectors of
                    // length 2¹⁴ (≤ 6·10⁻⁵ rad off the f64 boundary): an edge
                    // crossing the boundary at a grazing angle moves its
                    // crossing point by r·δ / sin(angle), centimetres at most.
                    grazing += 1;
                } else if std::env::var_os("ECHOLOC_BENCH_DEBUG").is_some() {
                    eprintln!(
                        "disagree: apex {:?} heading {} half {half_deg}: brute {x} echoloc {y}",
                        w.apex, w.heading
                    );
                }
            }
            _ => {}
        }
    }
    json!({"half_angle_deg": half_deg, "sampled": n, "agree": agree, "boundary_grazing": grazing,
           "max_diff_mm": (max_diff * 1e4).round() / 10.0})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_derived_answers() {
        let half = 15f64.to_radians();
        // A wall across the axis 2 m ahead: the foot of the perpendicular.
        let wall = vec![vec![(2.0, -3.0), (2.0, 3.0)]];
        assert_eq!(nearest(&wall, (0.0, 0.0), 0.0, half, 5.5), Some((2.0, false)));
        // A wall beside the cone, seen only from its crossing with the left
        // boundary ray: y = 1 crosses the ray at angle 15° at r = 1 / sin 15°.
        let side = vec![vec![(0.0, 1.0), (10.0, 1.0)]];
        let (r, on_boundary) = nearest(&side, (0.0, 0.0), 0.0, half, 5.5).unwrap();
        assert!((r - 1.0 / half.sin()).abs() < 1e-9 && on_boundary);
        // Behind the sensor, or beyond R_max: nothing.
        assert_eq!(nearest(&wall, (0.0, 0.0), std::f64::consts::PI, half, 5.5), None);
        assert_eq!(nearest(&wall, (0.0, 0.0), 0.0, half, 1.9), None);
        // Inside a piece: 0.
        let square = vec![vec![(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]];
        assert_eq!(nearest(&square, (0.0, 0.0), 0.0, half, 5.5), Some((0.0, false)));
        // A corner pointing at the sensor: the vertex.
        let diamond = vec![vec![(3.0, 0.0), (4.0, -1.0), (5.0, 0.0), (4.0, 1.0)]];
        assert_eq!(nearest(&diamond, (0.0, 0.0), 0.0, half, 5.5), Some((3.0, false)));
    }
}
