//! Range prediction, by hand: Cases I–III, the subsurface search, and
//! occlusion (a nearer piece hiding a farther one, and one that does not).

use echoloc::credence::crisp::Crisp;
use echoloc::credence::{Credence, EchoGeometry, Kappa};
use echoloc::geometry::Point;
use echoloc::map::{Map, ObstacleKind};
use echoloc::predict::{predict, Case, PredictParams, Prediction};
use echoloc::window::{Strategy, Window, WindowParams};

type M = Map<64, 1024, 256, 1024>;

fn p(x: i32, y: i32) -> Point {
    Point::new(x, y)
}

/// Sensor at the origin looking along +x; θ_o 30°, 500–5000 mm, δ_max 15°.
fn params() -> PredictParams {
    PredictParams::new(WindowParams {
        r_min_mm: 500,
        r_max_mm: 5000,
        half_angle_deg: 30.0,
        delta_max_deg: 15.0,
        ds_min_mm: 300,
        tb_mm: 300,
    })
}

/// Crisp credence with the window's own θ_o: points clipped onto the cone
/// edge must still count (`Crisp::EDGE_TOLERANCE_MDEG`).
const CRISP: Crisp = Crisp { half_angle_mdeg: 30_000, delta_max_mdeg: 15_000 };

fn map_of(walls: &[[Point; 2]], solids: &[&[Point]]) -> Box<M> {
    let mut m: Box<M> = Box::default();
    for w in walls {
        m.add_obstacle(ObstacleKind::Wall, &[&w[..]]).unwrap();
    }
    for s in solids {
        m.add_obstacle(ObstacleKind::Solid, &[s]).unwrap();
    }
    m.finish(300, 1000).unwrap();
    m
}

fn run(m: &M, k: &impl Credence) -> Option<Prediction> {
    run_with(m, k, params())
}

/// With the window's δ_max (signature test 2) opened up to 45°.
fn run_wide(m: &M, k: &impl Credence) -> Option<Prediction> {
    let mut prm = params();
    prm.window.delta_max_deg = 45.0;
    run_with(m, k, prm)
}

fn run_with(m: &M, k: &impl Credence, prm: PredictParams) -> Option<Prediction> {
    let w = Window::place_for(&prm.window, p(0, 0), 0.0, Strategy::PseudoPaths).unwrap();
    let (a, _) = predict(m, &w, &prm, k).unwrap();
    // Both collection strategies must agree on these maps.
    let pp = PredictParams { strategy: Strategy::PseudoPaths, ..prm };
    let (b, _) = predict(m, &w, &pp, k).unwrap();
    // ... but for the nearer-surface check, which runs with the exact
    // strategy only (the pseudo-paths do not find every piece).
    assert!(b.is_none_or(|b| b.nearer_mm.is_none()), "pseudo-paths ran the nearer-surface check");
    assert_eq!(a.map(|a| Prediction { nearer_mm: None, ..a }), b, "strategies disagree");
    a
}

#[test]
fn case_i_perpendicular_foot() {
    let m = map_of(&[[p(2000, -3000), p(2000, 3000)]], &[]);
    let r = run(&m, &CRISP).unwrap();
    assert_eq!((r.case, r.range_mm, r.delta_mdeg, r.theta_mdeg, r.point), (Case::I, 2000, 0, 0, p(2000, 0)));
    assert_eq!(r.kappa, Kappa::ONE);
    assert_eq!(r.tolerance_mm, 30 + 20);
}

#[test]
fn case_ii_nearest_vertex_of_an_edge_inside_the_window() {
    // Edge (2000,100)–(2100,600): its foot lies off the edge (s = −0.96), so
    // the nearer vertex is the echo point: R = √(2000² + 100²) = 2002.5 mm,
    // θ = atan(100/2000) = 2.862°, δ = atan2(|e·v|, |e×v|) = atan2(250000, 990000) = 14.173°.
    let m = map_of(&[[p(2000, 100), p(2100, 600)]], &[]);
    let r = run(&m, &CRISP).unwrap();
    assert_eq!(r.case, Case::II);
    assert_eq!(r.point, p(2000, 100));
    assert_eq!(r.range_mm, 2002);
    assert!((r.theta_mdeg - 2862).abs() <= 1, "{}", r.theta_mdeg);
    assert!((r.delta_mdeg - 14173).abs() <= 1, "{}", r.delta_mdeg);
}

#[test]
fn case_iii_clipped_at_the_cone_edge() {
    // A wall whose foot lies at 40° (outside the 30° window): perpendicular
    // to the 40° ray at 2800 mm. Clipped at the 30° edge, where δ = 10° and
    // R = 2800 / cos 10° = 2843.2 mm.
    let (a, b) = (p(3109, 651), p(1823, 2183));
    let m = map_of(&[[a, b]], &[]);
    let r = run(&m, &CRISP).unwrap();
    assert_eq!(r.case, Case::III);
    // Independent f64: intersect the wall's line with the 30° ray.
    let (ax, ay, bx, by) = (a.x as f64, a.y as f64, b.x as f64, b.y as f64);
    let (dx, dy) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let t = ((ax * (by - ay)) - (ay * (bx - ax))) / (dx * (by - ay) - dy * (bx - ax));
    assert!((r.range_mm as f64 - t).abs() <= 1.0, "{} vs {t}", r.range_mm);
    assert!((r.theta_mdeg - 30_000).abs() <= 5, "{}", r.theta_mdeg);
    assert!((r.delta_mdeg - 10_000).abs() <= 100, "{}", r.delta_mdeg);
}

#[test]
fn case_iii_with_delta_beyond_the_limit_predicts_nothing() {
    // A wall beside the window: in range, but met at 60° to its normal.
    let m = map_of(&[[p(-3000, 1500), p(6000, 1500)]], &[]);
    assert_eq!(run(&m, &CRISP), None);
}

/// κ = 1 only from 2300 mm on: the nearest point of a wall at 2000 mm is in
/// a "ravine", and the subsurface search walks out along the surface.
struct FarOnly;
impl Credence for FarOnly {
    fn kappa(&self, e: &EchoGeometry) -> Kappa {
        if e.range_mm >= 2300 {
            Kappa::ONE
        } else {
            Kappa::ZERO
        }
    }
}

#[test]
fn subsurface_search_finds_the_first_credible_point() {
    let m = map_of(&[[p(2000, -3000), p(2000, 3000)]], &[]);
    // δ reaches 30° there: beyond the window's δ_max of 15° nothing is searched...
    assert_eq!(run(&m, &FarOnly), None);
    // ...so open it up to see the search walk.
    let r = run_wide(&m, &FarOnly).unwrap();
    // 50 mm steps from the foot: y = 1100 gives R = 2282.5, y = 1150 the
    // first R ≥ 2300: √(2000² + 1150²) = 2307.06.
    assert_eq!(r.range_mm, 2307);
    assert_eq!(r.point.x, 2000);
    assert_eq!(r.point.y.abs(), 1150);
    assert_eq!(r.case, Case::III);
}

#[test]
fn occlusion_a_nearer_piece_hides_the_farther_ones_nearest_point() {
    // A diamond pillar at 1350–1650 mm on the axis: its faces meet the rays
    // at about 45°, beyond δ_max, so it echoes nothing credible itself; but
    // it hides the wall's foot (3000, 0). Its shadow on the wall reaches
    // |y| = 300 (the tangent through (1500, ±150)); the ray to y = 300 only
    // grazes the pillar's corner (and the occlusion ray stops a millimetre
    // short, rounded), so the first unhidden 50 mm step is |y| = 300
    // (R = 3015.0) or 350 (R = 3020.3) — never the hidden foot.
    let diamond = [p(1500, -150), p(1650, 0), p(1500, 150), p(1350, 0)];
    let m = map_of(&[[p(3000, -3000), p(3000, 3000)]], &[&diamond]);
    let r = run(&m, &CRISP).unwrap();
    assert_eq!(r.obstacle, 0, "the wall, not the pillar");
    assert!(r.point.y.abs() == 300 || r.point.y.abs() == 350, "{:?}", r.point);
    assert!(r.range_mm == 3015 || r.range_mm == 3020, "{}", r.range_mm);
    // Without the pillar the foot is seen.
    let m = map_of(&[[p(3000, -3000), p(3000, 3000)]], &[]);
    assert_eq!(run(&m, &CRISP).unwrap().range_mm, 3000);
}

#[test]
fn occlusion_a_piece_beside_the_ray_hides_nothing() {
    let beside = [p(1500, 600), p(1650, 750), p(1500, 900), p(1350, 750)];
    let m = map_of(&[[p(3000, -3000), p(3000, 3000)]], &[&beside]);
    let r = run(&m, &CRISP).unwrap();
    assert_eq!((r.obstacle, r.range_mm, r.case), (0, 3000, Case::I));
}

#[test]
fn a_nearer_credible_beacon_wins() {
    let bx = [p(1500, -100), p(1700, -100), p(1700, 100), p(1500, 100)];
    let m = map_of(&[[p(3000, -3000), p(3000, 3000)]], &[&bx]);
    let r = run(&m, &CRISP).unwrap();
    assert_eq!((r.obstacle, r.range_mm, r.point, r.case), (1, 1500, p(1500, 0), Case::I));
}

#[test]
fn seams_between_pieces_of_one_obstacle_are_not_surfaces() {
    // One obstacle in two pieces sharing the seam x = 1600; the sensor sees
    // only the front face x = 1500 of the near piece.
    let near = [p(1500, -500), p(1600, -500), p(1600, 500), p(1500, 500)];
    let far = [p(1600, -500), p(2500, -500), p(2500, 500), p(1600, 500)];
    let mut m: Box<M> = Box::default();
    m.add_obstacle(ObstacleKind::Solid, &[&near[..], &far[..]]).unwrap();
    m.finish(300, 1000).unwrap();
    assert_eq!(m.piece(0).unwrap().internal, 0b0010, "edge 1 of piece 0 is the seam");
    assert_eq!(m.piece(1).unwrap().internal, 0b1000, "edge 3 of piece 1 is the seam");
    // Inside the near piece's shadow the far piece's seam would be at
    // 1600 mm: never predicted.
    let r = run(&m, &CRISP).unwrap();
    assert_eq!((r.range_mm, r.piece), (1500, 0));
}

#[test]
fn r_min_cuts_out_the_near_part() {
    // A wall at 450 mm (inside R_min = 500): what is left in range starts at
    // R = 500, y = ±218, where θ = δ = acos(450/500) = 25.8° > δ_max:
    // nothing credible with the crisp model; with δ_max 45° the echo is at
    // R_min exactly.
    let m = map_of(&[[p(450, -3000), p(450, 3000)]], &[]);
    assert_eq!(run(&m, &CRISP), None);
    let wide = Crisp { half_angle_mdeg: 30_000, delta_max_mdeg: 45_000 };
    let r = run_wide(&m, &wide).unwrap();
    assert!(r.range_mm == 500 || r.range_mm == 501, "{}", r.range_mm);
}

#[test]
fn crisp_predictions_on_the_cone_edge_match_the_geometric_range_at_every_heading() {
    // A long wall 1.5 m to the side; for every heading 0…360° in 0.1° steps
    // the nearest wall point in the wedge (what `--geometric` reports) must be
    // what the crisp model predicts, whenever its δ is within δ_max = 60°
    // (R ≤ 3000 mm). Clipped Case III points sit exactly on the cone edge.
    use echoloc::predict::nearest_in_window;
    let m = map_of(&[[p(-3000, 1500), p(6000, 1500)]], &[]);
    let prm = PredictParams::new(WindowParams {
        r_min_mm: 0,
        r_max_mm: 5000,
        half_angle_deg: 30.0,
        delta_max_deg: 60.0,
        ds_min_mm: 300,
        tb_mm: 300,
    });
    let crisp = Crisp { half_angle_mdeg: 30_000, delta_max_mdeg: 60_000 };
    let mut checked = 0;
    for k in 0..3600 {
        let h = (k as f32 / 10.0).to_radians();
        let w = Window::place(&prm.window, p(0, 0), h).unwrap();
        let Some(g) = nearest_in_window(&*m, &w).unwrap() else { continue };
        if g.range_mm > 2990.0 {
            continue;
        }
        let (r, _) = predict(&*m, &w, &prm, &crisp).unwrap();
        let r = r.unwrap_or_else(|| {
            panic!("heading {}°: nothing predicted, geometric {:.1} mm", k as f32 / 10.0, g.range_mm)
        });
        assert!(
            (r.range_mm as f64 - g.range_mm).abs() <= 2.0,
            "heading {}°: crisp {} mm, geometric {:.1} mm",
            k as f32 / 10.0,
            r.range_mm,
            g.range_mm
        );
        checked += 1;
    }
    assert!(checked > 1000, "{checked} headings checked");
}

#[test]
fn headings_of_many_turns_and_windows_beyond_the_coordinates() {
    use echoloc::window::WindowError;
    let m = map_of(&[[p(2000, -3000), p(2000, 3000)]], &[]);
    let prm = params();
    // 1e10 rad is many turns: reduced, it is a heading like any other, and
    // the window's box (and so the query) ends.
    let w = Window::place(&prm.window, p(0, 0), 1e10).unwrap();
    assert!(w.sector.heading_rad >= 0.0 && w.sector.heading_rad < std::f32::consts::TAU);
    let _ = predict(&*m, &w, &prm, &CRISP).unwrap();
    // A window whose corner paths would leave ±COORD_MAX is refused, not wrapped.
    let wide = WindowParams { r_max_mm: 100_000, half_angle_deg: 89.999, ds_min_mm: u32::MAX, tb_mm: 0, ..prm.window };
    assert_eq!(Window::place_for(&wide, p(1000, 1000), 0.3, Strategy::PseudoPaths).unwrap_err(), WindowError::BadRange);
    // The exact strategy lays out no paths: the same window places, and is searched.
    let w = Window::place(&wide, p(1000, 1000), 0.3).unwrap();
    assert!(w.layout().is_none());
    let _ = predict(&*m, &w, &PredictParams { window: wide, ..prm }, &CRISP).unwrap();
}

/// Item 5 of "bring your own robot": a window with d_s_min 20 mm at θ_o 30°
/// (MARGE's range) would need 328 pseudo-paths, more than a layout holds.
/// The exact strategy lays out none, so it places and predicts such a
/// window; the pseudo-path strategy refuses it in words a person can act on.
#[test]
fn an_exact_window_needs_no_pseudo_path_layout() {
    use echoloc::predict::{predict_mount, Mount, Pose};
    use echoloc::window::WindowError;
    let m = map_of(&[[p(2000, -3000), p(2000, 3000)]], &[]);
    let window = WindowParams { ds_min_mm: 20, ..WindowParams::MARGE };
    // Eq. (2) by hand: ⌈2·5500·tan 30° / (20·cos 15°)⌉ − 1 = ⌈328.7⌉ − 1 = 328.
    let err = Window::place_for(&window, p(0, 0), 0.0, Strategy::PseudoPaths).unwrap_err();
    assert_eq!(err, WindowError::TooManyPseudoPaths(328));
    let words = err.to_string();
    assert!(words.contains("328") && words.contains("exact strategy"), "{words}");
    // Exact: placed without a layout, and the wall straight ahead is found at
    // its perpendicular distance, Case I.
    let w = Window::place(&window, p(0, 0), 0.0).unwrap();
    assert!(w.layout().is_none() && w.paths().next().is_none());
    let prm = PredictParams::new(window);
    assert_eq!(prm.strategy, Strategy::Exact);
    let got = predict(&*m, &w, &prm, &CRISP).unwrap().0.expect("the wall is predicted");
    assert_eq!((got.range_mm, got.case), (2000, Case::I));
    // Through the ring path too, which places the window for its strategy.
    let pose = Pose { x_mm: 0.0, y_mm: 0.0, heading_rad: 0.0 };
    let ahead = Mount { x_mm: 0, y_mm: 0, heading_mdeg: 0 };
    let (ring, _) = predict_mount(&*m, &pose, &ahead, &prm, &CRISP).unwrap();
    assert_eq!(ring.map(|r| r.range_mm), Some(2000));
    // Searching the exact window with pseudo-paths is a typed refusal, not a silent miss.
    let pp = PredictParams { strategy: Strategy::PseudoPaths, ..prm };
    assert!(predict(&*m, &w, &pp, &CRISP).is_err());
    assert!(predict_mount(&*m, &pose, &ahead, &pp, &CRISP).is_err());
}
