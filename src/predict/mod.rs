//! Range prediction (paper §5, DESIGN §4.5): what a transducer should read.
//!
//! For each beacon in the window and each of its *front* edges (signature
//! test 1, from the transducer's t-vector; seams between pieces of one
//! obstacle are not surfaces), the edge is cut to the window exactly; the
//! candidate nearest the transducer is the perpendicular foot when it lies
//! in the window (Case I, δ = 0), else the nearest end of the cut edge
//! (Case II when the whole edge is inside, Case III when it was clipped),
//! which by Proposition 2 also has the smallest cone arc deviation δ
//! (test 2: δ ≤ δ_max, whatever the credence model). Its credence κ(R, θ, δ) comes from a [`Credence`] model; when
//! κ < τ_κ the search moves outward along the surface in small increments
//! (the subsurface search of §5.3) to the first credible point (test 3). A
//! credible point whose ray from the transducer meets another piece is
//! occluded (test 4, exact t-vector tests through the grid) and the search
//! goes on past it. The prediction is the nearest credible, unoccluded
//! point over every beacon: the first echo.
//!
//! δ is the angle between the edge normal and the ray to the echo point,
//! computed from vectors (`atan2(|e·v|, |e×v|)`), not the printed slope
//! formulas (10)–(12), which break by quadrant.
//!
//! ```
//! use echoloc::credence::crisp::Crisp;
//! use echoloc::geometry::Point;
//! use echoloc::map::{Map, ObstacleKind};
//! use echoloc::predict::{predict, PredictParams};
//! use echoloc::window::{Window, WindowParams};
//!
//! let mut map: Map<16, 256, 64, 256> = Map::new();
//! map.add_obstacle(ObstacleKind::Wall, &[&[Point::new(2000, -3000), Point::new(2000, 3000)][..]]).unwrap();
//! map.finish(300, 1000).unwrap();
//! let params = PredictParams::new(WindowParams { half_angle_deg: 15.0, ..WindowParams::MARGE });
//! let crisp = Crisp { half_angle_mdeg: 15_000, delta_max_mdeg: 15_000 };
//! let window = Window::place(&params.window, Point::new(0, 0), 0.0).unwrap();
//! let (p, _) = predict(&map, &window, &params, &crisp).unwrap();
//! let p = p.expect("the wall is straight ahead");
//! assert_eq!(p.range_mm, 2000);
//! assert_eq!(p.delta_mdeg, 0);
//! ```

mod edge;
mod keys;
mod nearer;
mod nearest;
mod occlusion;
mod ring;
mod search;

pub use nearest::{nearest_in_window, Nearest};
pub use ring::{place_sensor, predict_mount, predict_ring, Mount, Pose, PIONEER16};

use edge::Occluders;
use keys::{box_distance2, NearestKeys};
use nearer::Nearer;
use search::search_piece;

use heapless::Vec;

use crate::credence::{Credence, Kappa};
use crate::geometry::Point;
use crate::map::MapSource;
use crate::window::{
    collect_beacons, is_beacon_with, CollectError, CollectStats, PathEnds, Strategy, Window, WindowError, WindowParams,
};

/// Most beacons [`predict_unpruned`] holds for one window, and most candidates
/// [`predict`] holds at once (a window of more is searched in batches).
pub const MAX_BEACONS: usize = 256;
/// Most κ evaluations along one direction of one edge.
pub const MAX_SUBSURFACE_STEPS: u32 = 128;

/// Prediction settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PredictParams {
    /// The sensor window.
    pub window: WindowParams,
    /// How beacons are collected.
    pub strategy: Strategy,
    /// τ_κ: the least credence of a prediction.
    #[cfg_attr(feature = "defmt", defmt(Debug2Format))]
    pub tau_kappa: Kappa,
    /// Subsurface search increment along an edge, mm.
    pub step_mm: u32,
    /// Tolerance on a predicted range: fixed part, mm ...
    pub tolerance_mm: u32,
    /// ... plus this many thousandths of the range.
    pub tolerance_permille: u32,
    /// The nearer-surface check ([`Prediction::nearer_mm`]): a face seen
    /// within this cone arc deviation, degrees, or any corner, nearer than
    /// the echo point makes a prediction ambiguous. `None`: no check (the
    /// paper's predictor as printed). With the exact strategy only: the
    /// others do not find every piece in the window.
    pub nearer_delta_deg: Option<f32>,
}

impl PredictParams {
    /// Defaults around `window`: exact collection, τ_κ = 0.5, 50 mm
    /// increments, tolerance 30 mm + 1 % of the range (the Polaroid ranging
    /// module's stated accuracy), and the nearer-surface check for faces
    /// within 2·δ_max.
    pub fn new(window: WindowParams) -> Self {
        Self {
            window,
            strategy: Strategy::Exact,
            tau_kappa: Kappa::from_bits(1 << 14),
            step_mm: 50,
            tolerance_mm: 30,
            tolerance_permille: 10,
            nearer_delta_deg: Some(2.0 * window.delta_max_deg),
        }
    }
}

/// Which of the paper's cases gave the predicted point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Case {
    /// Case I: the perpendicular foot, δ = 0.
    I,
    /// Case II: the edge lies wholly in the window; the point is its nearest
    /// credible part (its nearer vertex, unless the subsurface search moved on).
    II,
    /// Case III: the edge was clipped to the window first.
    III,
}

/// A predicted reading.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Prediction {
    /// Range to the echo point, mm.
    pub range_mm: u32,
    /// Its credence.
    #[cfg_attr(feature = "defmt", defmt(Debug2Format))]
    pub kappa: Kappa,
    /// Angle of the echo point off the transducer axis, millidegrees (counter-clockwise positive).
    pub theta_mdeg: i32,
    /// Cone arc deviation at the echo point, millidegrees.
    pub delta_mdeg: i32,
    /// The piece echoing.
    pub piece: u16,
    /// Its obstacle.
    pub obstacle: u16,
    /// The edge (surface) of the piece.
    pub edge: u8,
    /// The echo point in the map, mm (rounded).
    pub point: Point,
    /// Expected |R_obs − R_calc| bound, mm.
    pub tolerance_mm: u32,
    /// Which case produced it.
    pub case: Case,
    /// The range, mm, of the nearest mapped surface in the window that lies
    /// nearer than the echo point by more than the tolerance and that a
    /// sonar may still hear although the paper's tests pass over it: a
    /// corner (an outside edge diffracts, an inside corner retro-reflects)
    /// or a face seen beyond δ_max but within
    /// [`PredictParams::nearer_delta_deg`]. `None` when there is none (or
    /// the check is off). A prediction with one is ambiguous: a shorter echo
    /// may be the map's own.
    pub nearer_mm: Option<u32>,
}

/// Why prediction failed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PredictError {
    /// Bad window parameters or placement.
    Window(WindowError),
    /// Beacon collection failed.
    Collect(CollectError),
}

impl core::fmt::Display for PredictError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Window(e) => write!(f, "window: {e}"),
            Self::Collect(e) => write!(f, "beacon collection: {e}"),
        }
    }
}

impl From<WindowError> for PredictError {
    fn from(e: WindowError) -> Self {
        Self::Window(e)
    }
}

impl From<CollectError> for PredictError {
    fn from(e: CollectError) -> Self {
        Self::Collect(e)
    }
}

/// Counts of one prediction's work. Diagnostics counted modulo 2³² (one
/// prediction stays far below; sums over many rings wrap rather than trap).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PredictStats {
    /// The beacon collection's counts.
    pub collect: CollectStats,
    /// Beacons searched: for the exact strategy, every candidate searched
    /// before the early stop (its edge clipping is the exact test).
    pub beacons: u32,
    /// Front edges searched: those that meet the window, less those seen
    /// beyond δ_max at every point (passed over before their clipping).
    pub edges: u32,
    /// κ evaluations.
    pub kappa_evals: u32,
    /// Candidates passed over without running the credence model, because
    /// its κ could not reach τ there ([`Credence::may_reach`]).
    pub kappa_bounded: u32,
    /// Occlusion tests (segment queries through the grid).
    pub occlusion_tests: u32,
}

impl core::ops::AddAssign for PredictStats {
    /// Sums the counts (for a ring, or many rings), modulo 2³².
    fn add_assign(&mut self, o: PredictStats) {
        self.collect += o.collect;
        self.beacons = self.beacons.wrapping_add(o.beacons);
        self.edges = self.edges.wrapping_add(o.edges);
        self.kappa_evals = self.kappa_evals.wrapping_add(o.kappa_evals);
        self.kappa_bounded = self.kappa_bounded.wrapping_add(o.kappa_bounded);
        self.occlusion_tests = self.occlusion_tests.wrapping_add(o.occlusion_tests);
    }
}

/// Predicts the reading of the transducer whose window is `window`.
///
/// Pieces are visited nearest first (by the distance to their box) and the
/// search stops at the first piece whose box lies beyond the best credible
/// echo found: nothing there can be nearer. Ties in range go to the lower
/// piece id, so the answer does not depend on the order of the visit. A
/// window with more candidates than [`MAX_BEACONS`] (a dense building's
/// clutter) is searched in batches of the nearest [`MAX_BEACONS`], with the
/// same answer and the same fixed memory.
pub fn predict<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    window: &Window,
    params: &PredictParams,
    credence: &K,
) -> Result<(Option<Prediction>, PredictStats), PredictError> {
    if !window.supports(params.strategy) {
        return Err(PredictError::Collect(CollectError::NoPseudoPaths));
    }
    let sector = &window.sector;
    let o = sector.apex;
    // Candidates as `(d² >> shift) << 16 | id`, d² the exact squared distance
    // to the piece's box, `shift` such that R_max² fits 16 bits: sorting the
    // keys sorts by a lower bound of the distance, then by id; and
    // `(key >> 16) · 2^shift` is a lower bound of d².
    let r2_max = sector.r_max_mm as u64 * sector.r_max_mm as u64;
    let shift = (u64::BITS - r2_max.leading_zeros()).saturating_sub(16);
    let scale = (1u64 << shift) as f32;
    let area = sector.bbox();
    let lower_bound = |key: u32| (key >> 16) as f32 * scale;
    let mut keys = NearestKeys::<MAX_BEACONS>::new();
    let mut stats = PredictStats::default();
    nearest_keys(map, o, area, r2_max, shift, None, &mut keys, &mut stats)?;
    // `scripts/panic-never.sh --plant` only: an index no proof can bound,
    // which must make the panic-never link fail.
    #[cfg(echoloc_plant_panic)]
    let _ = keys.held()[core::hint::black_box(0)];
    // `scripts/panic-never.sh --overflow --plant` only: a sum no bound covers,
    // which the overflow count must find.
    #[cfg(echoloc_plant_overflow)]
    {
        stats.collect.cells = core::hint::black_box(stats.collect.cells) + core::hint::black_box(1);
    }
    let mut best: Option<(f32, Prediction)> = None;
    // 0.01° above δ_max: the walk's δ (f32, rounded to millidegrees) is
    // within 0.001° of the true angle, this test's within 10⁻⁴°.
    let oblique_limit = crate::f32math::sin_cos((params.window.delta_max_deg + 0.01).to_radians());
    // The pseudo-paths' end points, once for every candidate.
    let mut ends = (params.strategy == Strategy::PseudoPaths).then(|| PathEnds::new(window));
    // Batches of the nearest candidates, nearest first; one unless the
    // window holds more than MAX_BEACONS. Past the first, the occlusion
    // test walks the grid (the nearer candidates are no longer at hand).
    let mut first = true;
    'batches: loop {
        let complete = keys.dropped().map_or(f32::INFINITY, lower_bound);
        let occluders = first.then_some(Occluders { keys: keys.held(), area, scale, complete });
        for &key in keys.held() {
            if best.is_some_and(|(r, _)| lower_bound(key) > (r + 1.0) * (r + 1.0)) {
                break 'batches; // this box and every later one lie beyond the best echo
            }
            let Some(piece) = map.piece(key as u16) else { continue };
            // The exact strategy needs no test of its own here: an edge the
            // search clips into the window makes the piece meet the sector, and
            // a piece that does not meet it has no such edge. The pseudo-paths
            // first pass over a box beside the cone (nothing of it in the window;
            // the exact strategy's own clipping is cheaper than this test).
            if let Some(ends) = &mut ends {
                if sector.box_outside_wedge(&piece.bbox)
                    || !is_beacon_with(window, Some(ends), &piece, &mut stats.collect)
                {
                    continue;
                }
            }
            stats.beacons = stats.beacons.wrapping_add(1);
            // The candidates are every piece in the window's box within R_max:
            // they serve as the occlusion test's candidates too.
            search_piece(map, window, &piece, params, credence, occluders, Some(oblique_limit), &mut best, &mut stats);
        }
        let (Some(_), Some(&last)) = (keys.dropped(), keys.held().last()) else { break };
        if best.is_some_and(|(r, _)| complete > (r + 1.0) * (r + 1.0)) {
            break; // what was left out lies beyond the best echo
        }
        nearest_keys(map, o, area, r2_max, shift, Some(last), &mut keys, &mut stats)?;
        first = false;
    }
    let mut found = best.map(|(_, p)| p);
    if let (Some(p), Some(delta), Strategy::Exact) = (found.as_mut(), params.nearer_delta_deg, params.strategy) {
        // Every piece with a point nearer than the echo is among the
        // candidates (they hold every box within R_max), in order of box
        // distance: the first batch again if the search went past it.
        let lim = p.range_mm.saturating_sub(p.tolerance_mm) as f32;
        let mut near = Nearer::new(window, delta, p);
        if !first {
            nearest_keys(map, o, area, r2_max, shift, None, &mut keys, &mut stats)?;
            first = true;
        }
        loop {
            let complete = keys.dropped().map_or(f32::INFINITY, lower_bound);
            let occluders = first.then_some(Occluders { keys: keys.held(), area, scale, complete });
            for &key in keys.held().iter().take_while(|&&k| lower_bound(k) <= lim * lim) {
                near.piece(map, key as u16, occluders, &mut stats);
            }
            let (Some(_), Some(&last)) = (keys.dropped(), keys.held().last()) else { break };
            if complete > lim * lim {
                break;
            }
            nearest_keys(map, o, area, r2_max, shift, Some(last), &mut keys, &mut stats)?;
            first = false;
        }
        p.nearer_mm = near.found();
    }
    Ok((found, stats))
}

/// Puts into `keys` the `MAX_BEACONS` nearest of the window's candidates
/// after the key `after` (all of them when they fit), sorted: every piece
/// whose box lies in the window's box `area` within `R_max` of `o`.
#[allow(clippy::too_many_arguments)]
fn nearest_keys<M: MapSource + ?Sized>(
    map: &M,
    o: Point,
    area: crate::geometry::Rect,
    r2_max: u64,
    shift: u32,
    after: Option<u32>,
    keys: &mut NearestKeys<MAX_BEACONS>,
    stats: &mut PredictStats,
) -> Result<(), PredictError> {
    keys.clear();
    let q = map
        .for_each_candidate_box(area, |id, bbox| {
            let d2 = box_distance2(o, &bbox);
            if d2 > r2_max {
                return; // nothing of it within R_max
            }
            let key = ((d2 >> shift) as u32) << 16 | id as u32;
            if after.is_none_or(|a| key > a) {
                keys.offer(key);
            }
        })
        .map_err(|e| PredictError::Collect(CollectError::Map(e)))?;
    keys.sort();
    stats.collect.cells = stats.collect.cells.wrapping_add(q.cells);
    stats.collect.candidates = stats.collect.candidates.wrapping_add(q.candidates);
    Ok(())
}

/// [`predict`] without its shortcuts: every beacon in grid order, no early
/// stop, occlusion through the grid. The same answer, slower, for windows of
/// up to [`MAX_BEACONS`] beacons ([`CollectError::TooManyBeacons`] past
/// them, where [`predict`] searches in batches): tests and benchmarks
/// compare the two.
#[inline]
pub fn predict_unpruned<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    window: &Window,
    params: &PredictParams,
    credence: &K,
) -> Result<(Option<Prediction>, PredictStats), PredictError> {
    predict_unpruned_with::<M, K, MAX_BEACONS>(map, window, params, credence)
}

/// [`predict_unpruned`] with room for `B` beacons: the reference a test
/// holds [`predict`]'s batches to on a window of more than [`MAX_BEACONS`].
/// Never inlined: its beacon set takes stack only when it runs.
#[inline(never)]
pub fn predict_unpruned_with<M: MapSource + ?Sized, K: Credence + ?Sized, const B: usize>(
    map: &M,
    window: &Window,
    params: &PredictParams,
    credence: &K,
) -> Result<(Option<Prediction>, PredictStats), PredictError> {
    let mut beacons: Vec<u16, B> = Vec::new();
    let mut stats =
        PredictStats { collect: collect_beacons(map, window, params.strategy, &mut beacons)?, ..Default::default() };
    stats.beacons = beacons.len() as u32;
    let mut best: Option<(f32, Prediction)> = None;
    for &id in &beacons {
        let Some(piece) = map.piece(id) else { continue };
        search_piece(map, window, &piece, params, credence, None, None, &mut best, &mut stats);
    }
    let mut found = best.map(|(_, p)| p);
    if let (Some(p), Some(delta), Strategy::Exact) = (found.as_mut(), params.nearer_delta_deg, params.strategy) {
        // The beacons are every piece that meets the window.
        let mut near = Nearer::new(window, delta, p);
        for &id in &beacons {
            near.piece(map, id, None, &mut stats);
        }
        p.nearer_mm = near.found();
    }
    Ok((found, stats))
}
