//! Foxglove's well-known messages built from the lab's poses, ellipses and
//! sensor windows (metres, radians, nanoseconds).

use foxglove::messages::{
    ArrowPrimitive, Color, FrameTransform, KeyValuePair, LinePrimitive, Point3, Pose, PoseInFrame, Quaternion,
    SceneEntity, SceneEntityDeletion, SceneUpdate, SpherePrimitive, Timestamp, Vector3,
};

/// A time as Foxglove's timestamp (saturating past 2106).
pub fn stamp(t_ns: u64) -> Timestamp {
    let sec = u32::try_from(t_ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new(sec, (t_ns % 1_000_000_000) as u32)
}

/// A yaw as a quaternion about z.
pub fn quat(yaw: f64) -> Quaternion {
    Quaternion { x: 0.0, y: 0.0, z: (yaw / 2.0).sin(), w: (yaw / 2.0).cos() }
}

/// A planar pose (x m, y m, φ rad).
pub fn pose(p: [f64; 3]) -> Pose {
    Pose { position: Some(Vector3 { x: p[0], y: p[1], z: 0.0 }), orientation: Some(quat(p[2])) }
}

/// A pose in `map` at `t`.
pub fn pose_in_map(t: u64, p: [f64; 3]) -> PoseInFrame {
    PoseInFrame { timestamp: Some(stamp(t)), frame_id: "map".into(), pose: Some(pose(p)) }
}

/// `map` → `child` at `t`.
pub fn transform(t: u64, child: &str, p: [f64; 3]) -> FrameTransform {
    FrameTransform {
        timestamp: Some(stamp(t)),
        parent_frame_id: "map".into(),
        child_frame_id: child.into(),
        translation: Some(Vector3 { x: p[0], y: p[1], z: 0.0 }),
        rotation: Some(quat(p[2])),
    }
}

/// RGBA, 0–1.
pub fn color(c: [f64; 4]) -> Color {
    Color { r: c[0], g: c[1], b: c[2], a: c[3] }
}

/// `LinePrimitive.type`.
pub const LINE_STRIP: i32 = 0;
pub const LINE_LOOP: i32 = 1;
pub const LINE_LIST: i32 = 2;

/// A line primitive in its entity's frame (identity pose), `thickness` in pixels.
pub fn line(kind: i32, points: &[(f64, f64)], thickness: f64, c: [f64; 4]) -> LinePrimitive {
    LinePrimitive {
        r#type: kind,
        pose: Some(pose([0.0; 3])),
        thickness,
        scale_invariant: true,
        points: points.iter().map(|&(x, y)| Point3 { x, y, z: 0.0 }).collect(),
        color: Some(color(c)),
        colors: Vec::new(),
        indices: Vec::new(),
    }
}

/// A flat arrow at `p` along its heading, `length` m long.
pub fn arrow(p: [f64; 3], length: f64, c: [f64; 4]) -> ArrowPrimitive {
    ArrowPrimitive {
        pose: Some(pose(p)),
        shaft_length: length * 0.7,
        shaft_diameter: length * 0.08,
        head_length: length * 0.3,
        head_diameter: length * 0.2,
        color: Some(color(c)),
    }
}

/// An entity in `map` at `t` with lines (and arrows) and metadata.
pub fn entity(t: u64, id: &str, lines: Vec<LinePrimitive>, metadata: Vec<(&str, String)>) -> SceneEntity {
    SceneEntity {
        timestamp: Some(stamp(t)),
        frame_id: "map".into(),
        id: id.into(),
        lifetime: None,
        frame_locked: false,
        metadata: metadata.into_iter().map(|(k, v)| KeyValuePair { key: k.into(), value: v }).collect(),
        lines,
        ..Default::default()
    }
}

/// A scene update adding or replacing `entities`.
pub fn scene(entities: Vec<SceneEntity>) -> SceneUpdate {
    SceneUpdate { deletions: Vec::new(), entities }
}

/// A scene update removing every entity of the channel at `t`, then adding `entities`.
pub fn scene_replacing_all(t: u64, entities: Vec<SceneEntity>) -> SceneUpdate {
    // SceneEntityDeletion.type: 0 matching id, 1 all.
    SceneUpdate {
        deletions: vec![SceneEntityDeletion { timestamp: Some(stamp(t)), r#type: 1, id: String::new() }],
        entities,
    }
}

/// An arc at range `r` (m) about `(x, y)` from heading `a - h` to `a + h` (rad).
pub fn arc(x: f64, y: f64, a: f64, h: f64, r: f64) -> Vec<(f64, f64)> {
    (0..=16).map(|k| a - h + 2.0 * h * f64::from(k) / 16.0).map(|b| (x + r * b.cos(), y + r * b.sin())).collect()
}

/// The `k`σ ellipse of a position covariance `[σ²x, σxy, σ²y]`: its half
/// axes (major first) and the major axis' heading (rad), and σx, σy.
pub fn ellipse_axes(cov: [f64; 3], k: f64) -> ([f64; 2], f64, [f64; 2]) {
    let [a, b, c] = cov;
    let d = ((a - c) * (a - c) / 4.0 + b * b).sqrt();
    let (l1, l2) = ((a + c) / 2.0 + d, ((a + c) / 2.0 - d).max(0.0));
    let th = 0.5 * (2.0 * b).atan2(a - c);
    ([k * l1.max(0.0).sqrt(), k * l2.sqrt()], th, [a.max(0.0).sqrt(), c.max(0.0).sqrt()])
}

/// The `k`σ ellipse (32 points) of a position covariance about `(x, y)`,
/// and σx, σy.
pub fn ellipse(x: f64, y: f64, cov: [f64; 3], k: f64) -> (Vec<(f64, f64)>, [f64; 2]) {
    let ([r1, r2], th, sd) = ellipse_axes(cov, k);
    let pts = (0..32)
        .map(|i| {
            let u = std::f64::consts::TAU * f64::from(i) / 32.0;
            let (ex, ey) = (r1 * u.cos(), r2 * u.sin());
            (x + ex * th.cos() - ey * th.sin(), y + ex * th.sin() + ey * th.cos())
        })
        .collect();
    (pts, sd)
}

/// The `k`σ ellipse as a flat sphere (a disc 5 mm thick) about `(x, y)`:
/// a fixed-size message however fine the ellipse is drawn.
pub fn ellipse_disc(x: f64, y: f64, cov: [f64; 3], k: f64, c: [f64; 4]) -> (SpherePrimitive, [f64; 2]) {
    let ([r1, r2], th, sd) = ellipse_axes(cov, k);
    let disc = SpherePrimitive {
        pose: Some(pose([x, y, th])),
        size: Some(Vector3 { x: 2.0 * r1, y: 2.0 * r2, z: 0.005 }),
        color: Some(color(c)),
    };
    (disc, sd)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ellipse_of_a_diagonal_covariance_has_its_sigmas_as_half_axes() {
        // σx = 0.3, σy = 0.1: the 2σ ellipse reaches 0.6 along x and 0.2 along y.
        let (pts, s) = ellipse(1.0, 2.0, [0.09, 0.0, 0.01], 2.0);
        assert!((s[0] - 0.3).abs() < 1e-12 && (s[1] - 0.1).abs() < 1e-12);
        let max_x = pts.iter().map(|p| (p.0 - 1.0).abs()).fold(0.0, f64::max);
        let max_y = pts.iter().map(|p| (p.1 - 2.0).abs()).fold(0.0, f64::max);
        assert!((max_x - 0.6).abs() < 1e-9 && (max_y - 0.2).abs() < 1e-9, "{max_x} {max_y}");
        // The disc: 1.2 m by 0.4 m, its major axis along x.
        let (d, _) = ellipse_disc(1.0, 2.0, [0.09, 0.0, 0.01], 2.0, [0.0; 4]);
        let size = d.size.unwrap();
        assert!((size.x - 1.2).abs() < 1e-12 && (size.y - 0.4).abs() < 1e-12);
    }

    #[test]
    fn a_tilted_ellipse_has_its_major_axis_along_the_covariances_eigenvector() {
        // Σ = R(30°) diag(4, 1) R(30°)ᵀ: half axes 2kσ... with k = 1: 2 and 1, at 30°.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let cov = [4.0 * c * c + s * s, 3.0 * c * s, 4.0 * s * s + c * c];
        let ([a, b], th, _) = ellipse_axes(cov, 1.0);
        assert!((a - 2.0).abs() < 1e-12 && (b - 1.0).abs() < 1e-12 && (th - 30f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn a_stamp_splits_nanoseconds() {
        let s = stamp(3_000_000_007);
        assert_eq!((s.sec(), s.nsec()), (3, 7));
    }
}
