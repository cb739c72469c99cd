//! A window of more candidates than the search holds at once (a dense
//! building's clutter: a furnished lab mapped from a lidar run puts
//! hundreds of specks in one sonar window): [`predict`] searches it in
//! batches, nearest first, and must answer as the unpruned search does
//! with room for every beacon (grid order, no early stop, occlusion
//! through the grid), for both strategies and with the nearer-surface
//! check. Before the batches such a window was an error
//! (`TooManyBeacons`), and a dense map could not be compiled.

use echoloc::credence::net::CredenceNet;
use echoloc::credence::Credence;
use echoloc::geometry::Point;
use echoloc::map::{Map, ObstacleKind};
use echoloc::predict::{predict, predict_unpruned_with, PredictParams, MAX_BEACONS};
use echoloc::window::{Strategy, Window, WindowParams};

type M = Map<4096, 16384, 4096, 32768>;

use echoloc_host_tests::XorShift64 as Rng;

/// Uniform in [lo, hi), in millimetres.
fn mm(rng: &mut Rng, lo: i32, hi: i32) -> i32 {
    rng.range(lo.into(), hi.into()) as i32
}

/// A room of `specks` small squares (a laser map's furniture, 50–100 mm)
/// within `half` mm of its middle, a few short walls, the walls around it.
fn dense_room(rng: &mut Rng, specks: usize, half: i32) -> Box<M> {
    let mut m: Box<M> = Box::default();
    let h = half + 500;
    let room = [Point::new(-h, -h), Point::new(h, -h), Point::new(h, h), Point::new(-h, h), Point::new(-h, -h)];
    for w in room.windows(2) {
        m.add_obstacle(ObstacleKind::Wall, &[w]).unwrap();
    }
    for _ in 0..specks {
        let (x, y, s) = (mm(rng, -half, half), mm(rng, -half, half), mm(rng, 50, 100));
        // Keep the middle clear: the transducers stand there.
        if x.abs() < 400 && y.abs() < 400 {
            continue;
        }
        let sq = [Point::new(x, y), Point::new(x + s, y), Point::new(x + s, y + s), Point::new(x, y + s)];
        m.add_obstacle(ObstacleKind::Solid, &[&sq]).unwrap();
    }
    for _ in 0..20 {
        let (x, y) = (mm(rng, -half, half), mm(rng, -half, half));
        let (dx, dy) = (mm(rng, -900, 900), mm(rng, -900, 900));
        if (x.abs() < 1000 && y.abs() < 1000) || (dx == 0 && dy == 0) {
            continue;
        }
        m.add_obstacle(ObstacleKind::Wall, &[&[Point::new(x, y), Point::new(x + dx, y + dy)]]).unwrap();
    }
    m.finish(0, 1000).unwrap();
    m
}

/// A clear way along +x through a carpet of `specks` squares (everywhere
/// more than 37° off the axis, within 5.5 m), and a wall across it
/// 3.5–5 m ahead: seen from the origin along +x the window's box holds
/// hundreds of specks nearer than the wall, none in the cone, so the echo
/// lies past the first batch.
fn corridor(rng: &mut Rng, specks: usize) -> Box<M> {
    let mut m: Box<M> = Box::default();
    let x = mm(rng, 3500, 5000);
    m.add_obstacle(ObstacleKind::Wall, &[&[Point::new(x, -3000), Point::new(x + mm(rng, -300, 300), 3000)]]).unwrap();
    let mut n = 0;
    while n < specks {
        let (px, py, s) = (mm(rng, -200, 5500), mm(rng, -2800, 2800), mm(rng, 50, 100));
        if (py.abs() as f64) < 0.76 * px as f64 + 300.0 {
            continue;
        }
        let sq = [Point::new(px, py), Point::new(px + s, py), Point::new(px + s, py + s), Point::new(px, py + s)];
        m.add_obstacle(ObstacleKind::Solid, &[&sq]).unwrap();
        n += 1;
    }
    m.finish(0, 1000).unwrap();
    m
}

/// `predict` against the unpruned search with room for every beacon, at
/// transducers near the origin, headings within `turn` mrad of +x; returns how many
/// windows held more beacons than `MAX_BEACONS` and how many were searched
/// past the first batch.
fn check(m: &M, window: &WindowParams, credence: &impl Credence, rng: &mut Rng, turn: i32) -> (usize, usize) {
    let (mut dense, mut later) = (0, 0);
    for _ in 0..60 {
        let apex = Point::new(mm(rng, -300, 300), mm(rng, -300, 300));
        let heading = mm(rng, -turn, turn) as f32 / 1000.0;
        for strategy in [Strategy::Exact, Strategy::PseudoPaths] {
            let params = PredictParams { strategy, ..PredictParams::new(*window) };
            let w = Window::place_for(window, apex, heading, strategy).unwrap();
            let (got, stats) = predict(m, &w, &params, credence).unwrap();
            let (want, all) = predict_unpruned_with::<_, _, 4096>(m, &w, &params, credence).unwrap();
            assert_eq!(got, want, "{strategy:?} at {apex:?} heading {heading}");
            // More beacons than the unpruned search holds by default: what was an error.
            if all.beacons as usize > MAX_BEACONS {
                dense += 1;
            }
            // The grid scanned again: the search (or its nearer-surface
            // check) went past the first batch.
            if stats.collect.candidates > all.collect.candidates {
                later += 1;
            }
        }
    }
    (dense, later)
}

#[test]
fn a_window_of_more_candidates_than_the_search_holds_answers_as_the_unpruned_search() {
    let net = CredenceNet::shipped();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut dense, mut later) = (0, 0);
    for (specks, half) in [(1800, 3500), (1800, 2500), (1200, 6000)] {
        let m = dense_room(&mut rng, specks, half);
        for window in [
            WindowParams::POLAROID_6500,
            WindowParams { half_angle_deg: 12.7, delta_max_deg: 8.0, ..WindowParams::POLAROID_6500 },
        ] {
            let (d, l) = check(&m, &window, &net, &mut rng, 3141);
            println!("{specks} specks within {half} mm, θ_o {}°: {d} windows of more than {MAX_BEACONS} beacons, {l} searched past the first batch", window.half_angle_deg);
            dense += d;
            later += l;
        }
    }
    for specks in [400, 700] {
        let m = corridor(&mut rng, specks);
        for window in [
            WindowParams::POLAROID_6500,
            WindowParams { half_angle_deg: 12.7, delta_max_deg: 8.0, ..WindowParams::POLAROID_6500 },
        ] {
            let (d, l) = check(&m, &window, &net, &mut rng, 50);
            println!(
                "a corridor through {specks} specks, θ_o {}°: {l} searched past the first batch",
                window.half_angle_deg
            );
            dense += d;
            later += l;
        }
    }
    // The test means something only if it reached both kinds of window.
    assert!(dense >= 100, "only {dense} windows held more than {MAX_BEACONS} beacons");
    assert!(later >= 20, "only {later} windows were searched past the first batch");
}

/// The occlusion test may take its occluders from the first batch only
/// up to the distance the batch is complete to. Here the batch holds a
/// slanted wall (its box starts at 3.70 m; its nearest point, straight
/// ahead, 3.86 m) and 255 specks beside the cone, and leaves out a short
/// wall across the ray to that point (its box starts at 3.76 m):
/// the point is hidden, and the echo is the wall's next point the ray
/// reaches, as the unpruned search (occlusion through the grid) says.
#[test]
fn an_echo_hidden_by_a_piece_past_the_first_batch_is_hidden() {
    let net = CredenceNet::shipped();
    let mut rng = Rng(0x1234_5678_9abc_def1);
    let mut m: Box<M> = Box::default();
    let (a, b) = (Point::new(3700, -2500), Point::new(4000, 2000));
    m.add_obstacle(ObstacleKind::Wall, &[&[a, b]]).unwrap();
    // The foot of the perpendicular from the origin, by hand: t = −a·d / |d|².
    let d = (b.x as f64 - a.x as f64, b.y as f64 - a.y as f64);
    let t = -(a.x as f64 * d.0 + a.y as f64 * d.1) / (d.0 * d.0 + d.1 * d.1);
    let foot = (a.x as f64 + t * d.0, a.y as f64 + t * d.1);
    // The hiding piece: 100 mm of wall across the ray at 98.5 % of the way,
    // turned 30° from it (seen at 60°, beyond δ_max: no echo of its own).
    let r = (foot.0 * foot.0 + foot.1 * foot.1).sqrt();
    let (u, v) = ((foot.0 / r, foot.1 / r), (-foot.1 / r, foot.0 / r));
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let w = (c * u.0 + s * v.0, c * u.1 + s * v.1);
    let end = |k: f64| Point::new((0.985 * foot.0 + k * w.0).round() as i32, (0.985 * foot.1 + k * w.1).round() as i32);
    m.add_obstacle(ObstacleKind::Wall, &[&[end(-50.0), end(50.0)]]).unwrap();
    let mut n = 0;
    while n < 255 {
        let (px, py) = (mm(&mut rng, 0, 3400), mm(&mut rng, -2700, 2700));
        if (py.abs() as f64) < 0.76 * px as f64 + 300.0 || px * px + py * py > 3500 * 3500 {
            continue;
        }
        let sq = [Point::new(px, py), Point::new(px + 60, py), Point::new(px + 60, py + 60), Point::new(px, py + 60)];
        m.add_obstacle(ObstacleKind::Solid, &[&sq]).unwrap();
        n += 1;
    }
    m.finish(0, 1000).unwrap();
    let window = WindowParams::POLAROID_6500;
    let params = PredictParams::new(window);
    let w = Window::place_for(&window, Point::new(0, 0), 0.0, Strategy::Exact).unwrap();
    let (got, stats) = predict(&*m, &w, &params, &net).unwrap();
    let (want, _) = predict_unpruned_with::<_, _, 4096>(&*m, &w, &params, &net).unwrap();
    assert_eq!(got, want);
    let got = got.expect("the wall echoes");
    assert_eq!(got.piece, 0, "the echo is the wall's");
    // Not the hidden foot: a point of the wall beside it.
    let off = ((got.point.x as f64 - foot.0).powi(2) + (got.point.y as f64 - foot.1).powi(2)).sqrt();
    assert!(off > 5.0, "the echo {:?} is the hidden foot {foot:?}", got.point);
    assert!(stats.collect.candidates as usize > MAX_BEACONS, "the window held {} candidates", stats.collect.candidates);
}
