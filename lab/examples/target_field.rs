//! Issue #36 item 3, a design measured before it is built: a field that
//! stores at each coarse node and heading *which surface* a transducer
//! there hears (its edge's line for Case I, the echo point otherwise: the
//! EKF's [`Target`]) instead of the range, the range then computed at the
//! transducer's own position (the perpendicular distance to the line, or the
//! distance to the point). A range field at a coarse node errs wherever the
//! range changes between nodes; a target field errs only where the surface
//! heard changes.
//!
//! At `robots` free poses (the map's own field's draws, as `map
//! field-check` makes them) the Pioneer ring's 16 transducers are predicted
//! exactly and looked up in a target field of `node_mm` and `dirs` built on
//! demand (the nearest node, the nearest heading), and the agreement is
//! printed in `map field-check`'s terms beside the number of distinct
//! targets seen (what an entry must index). With `AUDIBLE=1` an entry
//! whose surface the transducer cannot hear from where it stands (the echo
//! point outside the beam's half angle, off the edge, or out of the
//! window's ranges) reads as nothing: a check a lookup could make.
//!
//! ```text
//! cargo run --release -p echoloc-lab --example target_field -- target/loc-maps/depot.map 500 32
//! ```
use std::collections::{HashMap, HashSet};

use echoloc::credence::net::CredenceNet;
use echoloc::localize::{FieldLookup, ParticleSet, Rng};
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{predict, predict_mount, Pose, PredictParams, Prediction, PIONEER16};
use echoloc::referencing::model::{range_model, MountM, Target};
use echoloc::window::{Window, WindowParams};

/// What a node hears at a heading: the target and the surface's id
/// (piece, edge, Case I).
type Heard = (Target, (u16, u8, bool));

/// The predictor's answer at a transducer standing at `(x, y)` mm facing `th`.
fn predict_at(
    map: &MapView<'_>,
    params: &PredictParams,
    net: &CredenceNet,
    x: f32,
    y: f32,
    th: f32,
) -> Option<Prediction> {
    let apex = echoloc::geometry::Point { x: x.round() as i32, y: y.round() as i32 };
    let w = Window::place_for(&params.window, apex, th, params.strategy).ok()?;
    predict(map, &w, params, net).ok().and_then(|(p, _)| p)
}

/// Whether a transducer at `(x, y)` mm facing `th` can hear `t` (heard
/// from the node as the surface `id`): the echo point (the perpendicular's
/// foot on the edge, or the point) within the beam's half angle, on the
/// edge, and within the window's ranges.
fn audible(map: &MapView<'_>, w: &WindowParams, t: &Target, id: (u16, u8, bool), x: f32, y: f32, th: f32) -> bool {
    let (px, py) = (x / 1e3, y / 1e3);
    let (fx, fy) = match *t {
        Target::Plane { point, normal } => {
            let d = (px - point[0]) * normal[0] + (py - point[1]) * normal[1];
            let (fx, fy) = (px - d * normal[0], py - d * normal[1]);
            // On the edge: the foot between its ends.
            let Some(piece) = map.piece(id.0) else { return false };
            let (a, b) = piece.shape.edge(usize::from(id.1));
            let (ax, ay, bx, by) = (a.x as f32 / 1e3, a.y as f32 / 1e3, b.x as f32 / 1e3, b.y as f32 / 1e3);
            let (ex, ey) = (bx - ax, by - ay);
            let u = ((fx - ax) * ex + (fy - ay) * ey) / (ex * ex + ey * ey).max(1e-12);
            if !(0.0..=1.0).contains(&u) {
                return false;
            }
            (fx, fy)
        }
        Target::Point { point } => (point[0], point[1]),
    };
    let r = (fx - px).hypot(fy - py) * 1e3;
    let off =
        ((fy - py).atan2(fx - px) - th + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
    off.abs() <= w.half_angle_deg.to_radians() && r >= w.r_min_mm as f32 && r <= w.r_max_mm as f32
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: target_field MAP.map NODE_MM DIRS [ROBOTS]");
        std::process::exit(2);
    }
    let path = std::path::Path::new(&args[1]);
    let node_mm: f32 = args[2].parse().expect("NODE_MM");
    let dirs: u32 = args[3].parse().expect("DIRS");
    let robots: usize = args.get(4).map_or(2000, |r| r.parse().expect("ROBOTS"));
    let audible_only = std::env::var("AUDIBLE").is_ok_and(|v| v == "1");
    let a = echoloc_lab::map::read_compiled(path).expect("a compiled map");
    let map = echoloc_lab::map::view_of(&a, path).expect("a valid map");
    let lookup = FieldLookup::new(map.field());
    let params = PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::POLAROID_6500 });
    let net = CredenceNet::shipped();
    let mut rng = Rng::new(1);
    let mut cells: HashMap<(i32, i32, u32), Option<Heard>> = HashMap::new();
    let mut ids = HashSet::new();
    let (mut samples, mut both_nothing, mut both_echo, mut missed, mut invented) =
        (0usize, 0usize, 0usize, 0usize, 0usize);
    let (mut tol, mut same_target) = (0usize, 0usize);
    let mut errors = Vec::new();
    for _ in 0..robots {
        let p = ParticleSet::<0>::free_pose(&mut rng, &lookup).expect("free space");
        let pose = Pose { x_mm: p[0] * 1e3, y_mm: p[1] * 1e3, heading_rad: p[2] };
        for m in &PIONEER16 {
            let (exact, _) = predict_mount(&map, &pose, m, &params, &net).expect("prediction");
            let (s, c) = (p[2].sin(), p[2].cos());
            let (mx, my) = (m.x_mm as f32, m.y_mm as f32);
            let (tx, ty) = (pose.x_mm + c * mx - s * my, pose.y_mm + s * mx + c * my);
            let th = p[2] + (m.heading_mdeg as f32 / 1000.0).to_radians();
            let (col, row) = ((tx / node_mm).round() as i32, (ty / node_mm).round() as i32);
            let bin =
                ((th.rem_euclid(std::f32::consts::TAU)) * dirs as f32 / std::f32::consts::TAU).round() as u32 % dirs;
            let entry = *cells.entry((col, row, bin)).or_insert_with(|| {
                let b = bin as f32 * std::f32::consts::TAU / dirs as f32;
                predict_at(&map, &params, &net, col as f32 * node_mm, row as f32 * node_mm, b).and_then(|q| {
                    let id = (q.piece, q.edge, q.case == echoloc::predict::Case::I);
                    Target::of(&map, &q).map(|t| (t, id))
                })
            });
            samples += 1;
            // `AUDIBLE=1`: an entry the transducer cannot hear from where it stands says nothing.
            let entry = entry.filter(|&(t, id)| !audible_only || audible(&map, &params.window, &t, id, tx, ty, th));
            match (exact, entry) {
                (None, None) => both_nothing += 1,
                (Some(_), None) => missed += 1,
                (None, Some(_)) => invented += 1,
                (Some(e), Some((t, id))) => {
                    both_echo += 1;
                    ids.insert(id);
                    // The EKF's own range model, the transducer standing at (tx, ty).
                    let at = [tx / 1e3, ty / 1e3, 0.0];
                    let r = range_model(&at, MountM { x: 0.0, y: 0.0 }, &t).map_or(0.0, |(h, _)| h * 1e3);
                    let err = (r - e.range_mm as f32).abs();
                    errors.push(err);
                    tol += usize::from(err <= e.tolerance_mm as f32);
                    same_target += usize::from(id == (e.piece, e.edge, e.case == echoloc::predict::Case::I));
                }
            }
        }
    }
    errors.sort_by(f32::total_cmp);
    let q = |f: f64| {
        errors.get(((errors.len() as f64 * f) as usize).min(errors.len().saturating_sub(1))).copied().unwrap_or(0.0)
    };
    let share = |n: usize| (n as f64 / samples.max(1) as f64 * 1e4).round() / 1e4;
    println!(
        "{}",
        serde_json::json!({
            "node_mm": node_mm, "dirs": dirs, "samples": samples,
            "both_nothing": share(both_nothing), "both_echo": share(both_echo),
            "class_agreement": share(both_nothing + both_echo),
            "field_missed": share(missed), "field_invented": share(invented),
            "echo_error_mm": {"p50": q(0.5).round(), "p90": q(0.9).round(), "p99": q(0.99).round()},
            "echo_within_tolerance": (tol as f64 / both_echo.max(1) as f64 * 1e4).round() / 1e4,
            "same_surface": (same_target as f64 / both_echo.max(1) as f64 * 1e4).round() / 1e4,
            "distinct_targets_seen": ids.len(),
            "node_headings_built": cells.len(),
        })
    );
}
