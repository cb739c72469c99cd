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

mod ring;

pub use ring::{place_sensor, predict_mount, predict_ring, Mount, Pose, PIONEER16};

use heapless::Vec;

use crate::credence::{Credence, EchoGeometry, Kappa};
use crate::geometry::{Point, Rect, Segment};
use crate::map::Piece;
use crate::map::{Layer, MapSource};
use crate::window::{
    collect_beacons, is_beacon, CollectError, CollectStats, Strategy, Window, WindowError, WindowParams,
};

/// Most beacons one window may hold.
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
/// piece id, so the answer does not depend on the order of the visit. (A
/// window with more candidates than [`MAX_BEACONS`] is searched in grid
/// order without the early stop, with the same answer.)
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
    let mut keys: Vec<u32, MAX_BEACONS> = Vec::new();
    let mut overflow = false;
    let r2_max = sector.r_max_mm as u64 * sector.r_max_mm as u64;
    let shift = (u64::BITS - r2_max.leading_zeros()).saturating_sub(16);
    let scale = (1u64 << shift) as f32;
    let area = sector.bbox();
    let q = map
        .for_each_candidate_box(area, |id, bbox| {
            // Beside the cone: nothing of it in the window. (Worth it before the
            // pseudo-path tests; the exact strategy's own clipping is cheaper.)
            if params.strategy == Strategy::PseudoPaths && sector.box_outside_wedge(&bbox) {
                return;
            }
            let d2 = box_distance2(o, &bbox);
            if d2 > r2_max {
                return; // nothing of it within R_max
            }
            if keys.push(((d2 >> shift) as u32) << 16 | id as u32).is_err() {
                overflow = true;
            }
        })
        .map_err(|e| PredictError::Collect(CollectError::Map(e)))?;
    if overflow {
        return predict_unpruned(map, window, params, credence);
    }
    let mut stats = PredictStats::default();
    stats.collect.cells = q.cells;
    stats.collect.candidates = q.candidates;
    sort_keys(&mut keys);
    // `scripts/panic-never.sh --plant` only: an index no proof can bound,
    // which must make the panic-never link fail.
    #[cfg(echoloc_plant_panic)]
    let _ = keys[core::hint::black_box(0)];
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
    for &key in keys.iter() {
        let lb2 = (key >> 16) as f32 * scale;
        if best.is_some_and(|(r, _)| lb2 > (r + 1.0) * (r + 1.0)) {
            break; // this box and every later one lie beyond the best echo
        }
        let Some(piece) = map.piece(key as u16) else { continue };
        // The exact strategy needs no test of its own here: an edge the
        // search clips into the window makes the piece meet the sector, and
        // a piece that does not meet it has no such edge.
        if params.strategy != Strategy::Exact && !is_beacon(window, params.strategy, &piece, &mut stats.collect) {
            continue;
        }
        stats.beacons = stats.beacons.wrapping_add(1);
        // The exact strategy's candidates are every piece in the window's box
        // within R_max: they serve as the occlusion test's candidates too.
        let occluders = (params.strategy == Strategy::Exact).then_some((&keys[..], area, scale));
        search_piece(map, window, &piece, params, credence, occluders, Some(oblique_limit), &mut best, &mut stats);
    }
    let mut found = best.map(|(_, p)| p);
    if let (Some(p), Some(delta), Strategy::Exact) = (found.as_mut(), params.nearer_delta_deg, params.strategy) {
        // Every piece with a point nearer than the echo is among the keys
        // (they hold every box within R_max), in order of box distance.
        let lim = p.range_mm.saturating_sub(p.tolerance_mm) as f32;
        let mut near = Nearer::new(window, delta, p);
        for &key in keys.iter().take_while(|&&k| (k >> 16) as f32 * scale <= lim * lim) {
            near.piece(map, key as u16, Some((&keys[..], area, scale)), &mut stats);
        }
        p.nearer_mm = near.found();
    }
    Ok((found, stats))
}

/// Sorts the candidate keys ascending without a panic path (the firmware's
/// panic-never link check; `sort_unstable` keeps one, its check for an
/// inconsistent `Ord`): a Shell sort on Ciura's gaps, in place, moving a
/// hole rather than swapping. Tested against `sort_unstable` below.
fn sort_keys(keys: &mut [u32]) {
    const GAPS: [usize; 6] = [132, 57, 23, 10, 4, 1];
    let n = keys.len();
    for gap in GAPS {
        for i in gap..n {
            let Some(&v) = keys.get(i) else { break };
            let mut j = i;
            while j >= gap {
                let Some(&u) = keys.get(j - gap) else { break };
                if u <= v {
                    break;
                }
                if let Some(slot) = keys.get_mut(j) {
                    *slot = u;
                }
                j -= gap;
            }
            if let Some(slot) = keys.get_mut(j) {
                *slot = v;
            }
        }
    }
}

/// The squared distance (mm²) from `o` to the box, exact, with each gap
/// clamped at 2²⁴ mm (far beyond any `R_max`): a lower bound of the squared
/// distance to any point of the piece it holds.
fn box_distance2(o: Point, b: &Rect) -> u64 {
    // In-range coordinates differ by less than 2³¹: the gaps are taken in
    // 32 bits (as `Point::sub` does), so each square is one 32 × 32 → 64-bit
    // multiply on a Cortex-M4.
    let gap = |lo: i32, v: i32, hi: i32| lo.wrapping_sub(v).max(v.wrapping_sub(hi)).clamp(0, 1 << 24) as u32 as u64;
    let (dx, dy) = (gap(b.min.x, o.x, b.max.x), gap(b.min.y, o.y, b.max.y));
    dx * dx + dy * dy
}

/// [`predict`] without its shortcuts: every beacon in grid order, no early
/// stop, occlusion through the grid. The same answer, slower: [`predict`]
/// falls back to it for a window with more than [`MAX_BEACONS`] candidates,
/// and tests and benchmarks compare the two. Never inlined: its beacon set
/// takes stack only when it runs.
#[inline(never)]
pub fn predict_unpruned<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    window: &Window,
    params: &PredictParams,
    credence: &K,
) -> Result<(Option<Prediction>, PredictStats), PredictError> {
    let mut beacons: Vec<u16, MAX_BEACONS> = Vec::new();
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

/// The search for [`Prediction::nearer_mm`] once `p` is known: fed the
/// pieces (every piece with a point nearer than `p`'s echo must be among
/// them), it keeps the nearest point of a front edge inside the window
/// (from `R_min` to `p`'s range less its tolerance), not occluded, that is
/// an end of its edge (a corner) or is seen within the check's δ of the
/// edge's normal. `p`'s own edge is left out: its nearer part failed κ, not
/// the geometry. The nearest point of an edge's part also has its least δ
/// (Proposition 2), so that point and the edge's ends decide an edge; the
/// answer does not depend on the order of the pieces.
struct Nearer<'w> {
    window: &'w Window,
    /// `(sin, cos)` of the δ limit.
    lim: (f32, f32),
    min_range: f32,
    piece: u16,
    edge: u8,
    limit: f32,
    nearest: f32,
}

impl<'w> Nearer<'w> {
    fn new(window: &'w Window, delta_deg: f32, p: &Prediction) -> Self {
        let limit = p.range_mm.saturating_sub(p.tolerance_mm) as f32;
        let lim = crate::f32math::sin_cos(delta_deg.to_radians());
        let min_range = window.sector.r_min_mm as f32;
        Self { window, lim, min_range, piece: p.piece, edge: p.edge, limit, nearest: limit }
    }

    // One copy per map type, not one inlined into each caller (flash).
    #[inline(never)]
    fn piece<M: MapSource + ?Sized>(
        &mut self,
        map: &M,
        id: u16,
        occluders: Option<(&[u32], Rect, f32)>,
        stats: &mut PredictStats,
    ) {
        let sector = &self.window.sector;
        let o = sector.apex;
        let Some(piece) = map.piece(id) else { return };
        for (edge, a, b) in piece.front_edges(o) {
            if id == self.piece && edge == self.edge {
                continue;
            }
            // The wedge's part; the ranges cut it below.
            let Some(c) = sector.clip_edge(a, b) else { continue };
            let (lo, hi) = (c.lo.to_f32(), c.hi.to_f32());
            let ao = (diff_f32(a.x, o.x), diff_f32(a.y, o.y));
            let e = (diff_f32(b.x, a.x), diff_f32(b.y, a.y));
            let ee = e.0 * e.0 + e.1 * e.1;
            if ee == 0.0 {
                continue;
            }
            // The part nearer than the nearest so far, less what is blanked.
            let Some((q1, q2)) = roots(ao, e, self.nearest) else { continue };
            let (lo, hi) = (fmax(lo, q1), fmin(hi, q2));
            if lo > hi {
                continue;
            }
            let mut parts = [(lo, hi), (1.0, 0.0)];
            if let Some((p1, p2)) = roots(ao, e, self.min_range) {
                parts = [(lo, fmin(hi, p1)), (fmax(lo, p2), hi)];
            }
            let foot = -(ao.0 * e.0 + ao.1 * e.1) / ee;
            let ctx = EdgeCtx { o, a, b, axis: (0.0, 0.0), piece: id, obstacle: piece.obstacle, edge, occluders };
            for (x, y) in parts {
                if x > y {
                    continue;
                }
                // The part's nearest point (its least δ), and the edge's
                // ends where the part holds them: corners echo at any δ.
                self.point(map, &ctx, ao, e, crate::f32math::clamp(foot, x, y), stats);
                if x <= 0.0 {
                    self.point(map, &ctx, ao, e, 0.0, stats);
                }
                if y >= 1.0 {
                    self.point(map, &ctx, ao, e, 1.0, stats);
                }
            }
        }
    }

    /// The point at `s` along the edge (`ao`: its start from the
    /// transducer, `e`: the edge), if nearer than the nearest so far, a
    /// corner or seen within the δ limit, and not occluded. Not inlined: it
    /// is called from three places (flash).
    #[inline(never)]
    fn point<M: MapSource + ?Sized>(
        &mut self,
        map: &M,
        ctx: &EdgeCtx<'_>,
        ao: (f32, f32),
        e: (f32, f32),
        s: f32,
        stats: &mut PredictStats,
    ) {
        let v = (ao.0 + s * e.0, ao.1 + s * e.1);
        let range = crate::f32math::sqrt(v.0 * v.0 + v.1 * v.1);
        if range >= self.nearest {
            return;
        }
        // δ within the limit: |e·v|·cos ≤ |e×v|·sin.
        let along = (e.0 * v.0 + e.1 * v.1).abs();
        let across = (e.0 * v.1 - e.1 * v.0).abs();
        let corner = s <= 0.0 || s >= 1.0;
        if (corner || along * self.lim.1 <= across * self.lim.0) && !occluded(map, ctx, v, range, stats) {
            self.nearest = range;
        }
    }

    fn found(&self) -> Option<u32> {
        (self.nearest < self.limit).then(|| libm::roundf(self.nearest) as u32)
    }
}

/// Searches every front edge of one beacon that meets the window.
/// `occluders`: the window's candidate keys, sorted, the box they were
/// found in and their distance scale (see [`occluded`]). `oblique_limit`:
/// `(sin, cos)` of an angle above δ_max, to pass over edges seen beyond it
/// everywhere (see [`seen_beyond`]).
#[allow(clippy::too_many_arguments)]
fn search_piece<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    window: &Window,
    piece: &Piece<'_>,
    params: &PredictParams,
    credence: &K,
    occluders: Option<(&[u32], Rect, f32)>,
    oblique_limit: Option<(f32, f32)>,
    best: &mut Option<(f32, Prediction)>,
    stats: &mut PredictStats,
) {
    let sector = &window.sector;
    let o = sector.apex;
    let axis = sector.axis_unit();
    // None when the transducer is inside this obstacle: nothing to see of it.
    for (edge, a, b) in piece.front_edges(o) {
        // An edge wholly beyond the best echo cannot give a nearer one:
        // skip its exact clipping (its box's distance bounds every point).
        if let Some((r, _)) = best {
            let e = Segment::new(a, b).bbox();
            // Gaps below 2²⁴ convert exactly; the 1 mm margin dwarfs the rounding of the squares.
            let gap = |lo: i32, v: i32, hi: i32| {
                (lo as i64 - v as i64).max(v as i64 - hi as i64).clamp(0, 1 << 24) as i32 as f32
            };
            let (dx, dy) = (gap(e.min.x, o.x, e.max.x), gap(e.min.y, o.y, e.max.y));
            if dx * dx + dy * dy > (*r + 1.0) * (*r + 1.0) {
                continue;
            }
        }
        if oblique_limit.is_some_and(|lim| seen_beyond(o, a, b, lim)) {
            continue; // every point of it fails the δ test: no exact clipping
        }
        let Some((lo, hi)) = sector.edge_window(a, b) else { continue };
        stats.edges = stats.edges.wrapping_add(1);
        let ctx = EdgeCtx { o, a, b, axis, piece: piece.id, obstacle: piece.obstacle, edge, occluders };
        search_edge(map, &ctx, lo, hi, sector.r_min_mm, sector.r_max_mm, params, credence, best, stats);
    }
}

/// Whether every point of edge `a → b` is seen from `o` at an incidence δ
/// beyond the angle whose `(sin, cos)` is `lim` (below 90°). δ is least at
/// the point of the edge nearest the foot of the perpendicular from `o`
/// (Proposition 2: it grows with the distance from the foot), so with the
/// foot inside the edge nothing is passed over, and otherwise only the end
/// nearer the foot is tested: `tan δ = |e·v| / |e×v|` there, `v` that end
/// from `o`. In `f32` from the exact differences: each product is within a
/// few ulp of `|e|·|v|`, so the angle is within 10⁻⁶ rad (the caller's
/// margin is 0.01°). An oblique edge costs this instead of its exact
/// clipping and the first steps of its walk.
#[inline]
fn seen_beyond(o: Point, a: Point, b: Point, lim: (f32, f32)) -> bool {
    let e = (diff_f32(b.x, a.x), diff_f32(b.y, a.y));
    let va = (diff_f32(a.x, o.x), diff_f32(a.y, o.y));
    let along_a = e.0 * va.0 + e.1 * va.1;
    let v = if along_a >= 0.0 {
        va // the foot lies before a
    } else {
        let vb = (diff_f32(b.x, o.x), diff_f32(b.y, o.y));
        if e.0 * vb.0 + e.1 * vb.1 > 0.0 {
            return false; // the foot lies on the edge: δ = 0 there
        }
        vb
    };
    let along = (e.0 * v.0 + e.1 * v.1).abs();
    let across = (e.0 * v.1 - e.1 * v.0).abs();
    along * lim.1 > across * lim.0
}

struct EdgeCtx<'k> {
    o: Point,
    a: Point,
    b: Point,
    axis: (f32, f32),
    piece: u16,
    obstacle: u16,
    edge: u8,
    /// The window's candidate keys, sorted by box distance, the box they
    /// were found in and their distance scale, when known.
    occluders: Option<(&'k [u32], Rect, f32)>,
}

/// The larger of two numbers that are not NaN (`f32::max` is a library call
/// on a Cortex-M4, for its NaN rule).
#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The smaller of two numbers that are not NaN.
#[inline(always)]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `a − b` as `f32`, rounded once: through `i32` (the FPU converts it) when
/// the difference fits, else through `i64` (a library call on a Cortex-M4).
#[inline]
fn diff_f32(a: i32, b: i32) -> f32 {
    match a.checked_sub(b) {
        Some(d) => d as f32,
        None => (a as i64 - b as i64) as f32,
    }
}

/// The roots of `|ao + s·e|² = r²` as `(s1, s2)`, `s1 ≤ s2`, if any.
fn roots(ao: (f32, f32), e: (f32, f32), r: f32) -> Option<(f32, f32)> {
    let ee = e.0 * e.0 + e.1 * e.1;
    let b = ao.0 * e.0 + ao.1 * e.1;
    let c = ao.0 * ao.0 + ao.1 * ao.1 - r * r;
    let disc = b * b - ee * c;
    if disc < 0.0 || ee == 0.0 {
        return None;
    }
    let sq = crate::f32math::sqrt(disc);
    Some(((-b - sq) / ee, (-b + sq) / ee))
}

#[allow(clippy::too_many_arguments)]
fn search_edge<M: MapSource + ?Sized, K: Credence + ?Sized>(
    map: &M,
    ctx: &EdgeCtx<'_>,
    lo: f32,
    hi: f32,
    r_min: u32,
    r_max: u32,
    params: &PredictParams,
    credence: &K,
    best: &mut Option<(f32, Prediction)>,
    stats: &mut PredictStats,
) {
    let ao = (diff_f32(ctx.a.x, ctx.o.x), diff_f32(ctx.a.y, ctx.o.y));
    let e = (diff_f32(ctx.b.x, ctx.a.x), diff_f32(ctx.b.y, ctx.a.y));
    let len = crate::f32math::sqrt(e.0 * e.0 + e.1 * e.1);
    if len == 0.0 {
        return;
    }
    let foot = -(ao.0 * e.0 + ao.1 * e.1) / (len * len);
    let delta_max_mdeg = libm::roundf(params.window.delta_max_deg * 1000.0) as i32;
    // The window's ranges cut [lo, hi] into at most two intervals.
    let Some((q1, q2)) = roots(ao, e, r_max as f32) else { return };
    let (lo, hi) = (fmax(lo, q1), fmin(hi, q2));
    let whole = lo <= 0.0 && hi >= 1.0;
    let mut parts = [(lo, hi), (1.0, 0.0)];
    if r_min > 0 {
        if let Some((p1, p2)) = roots(ao, e, r_min as f32) {
            parts = [(lo, fmin(hi, p1)), (fmax(lo, p2), hi)];
        }
    }
    for (x, y) in parts {
        if x > y {
            continue;
        }
        let ds = fmax(params.step_mm.max(1) as f32 / len, (y - x) / MAX_SUBSURFACE_STEPS as f32);
        // Walk away from the point nearest the transducer: towards y from it
        // (itself included), then towards x when the foot lies inside.
        let near = crate::f32math::clamp(foot, x, y);
        for (end, dir, include_start) in [(y, 1.0f32, true), (x, -1.0f32, false)] {
            if !include_start && x >= near {
                continue;
            }
            let mut s = near;
            if !include_start {
                s = fmax(s - ds, end);
            }
            // A hard bound too: f32 steps on a very long edge could stall.
            let mut steps = 0;
            loop {
                steps += 1;
                if steps > MAX_SUBSURFACE_STEPS + 1 {
                    break;
                }
                let v = (ao.0 + s * e.0, ao.1 + s * e.1);
                let range = crate::f32math::sqrt(v.0 * v.0 + v.1 * v.1);
                // Farther along only gets farther; an equal range goes to the lower piece id.
                if best.is_some_and(|(r, p)| range > r || (range == r && ctx.piece >= p.piece)) {
                    break;
                }
                let delta = crate::f32math::atan2((e.0 * v.0 + e.1 * v.1).abs(), (e.0 * v.1 - e.1 * v.0).abs());
                let delta_mdeg = libm::roundf(delta.to_degrees() * 1000.0) as i32;
                // Test 2: δ grows with distance from the foot (Proposition 2),
                // so past δ_max nothing farther along this way can echo. (Before
                // θ: a step that fails it needs no second arctangent.)
                if delta_mdeg > delta_max_mdeg {
                    break;
                }
                let theta =
                    crate::f32math::atan2(ctx.axis.0 * v.1 - ctx.axis.1 * v.0, ctx.axis.0 * v.0 + ctx.axis.1 * v.1);
                let echo = EchoGeometry {
                    range_mm: libm::roundf(range) as u32,
                    theta_mdeg: libm::roundf(theta.to_degrees() * 1000.0) as i32,
                    delta_mdeg,
                };
                // Where κ provably cannot reach τ the net need not run: the
                // candidate is passed over either way.
                let kappa = if credence.may_reach(&echo, params.tau_kappa) {
                    stats.kappa_evals = stats.kappa_evals.wrapping_add(1);
                    credence.kappa(&echo)
                } else {
                    stats.kappa_bounded = stats.kappa_bounded.wrapping_add(1);
                    Kappa::ZERO
                };
                if kappa >= params.tau_kappa && !occluded(map, ctx, v, range, stats) {
                    let case = if (s - foot).abs() * len < 0.5 {
                        Case::I
                    } else if whole {
                        Case::II
                    } else {
                        Case::III
                    };
                    // (Within R_max of an in-range apex: saturating is exact there.)
                    let point = Point::new(
                        ctx.o.x.saturating_add(libm::roundf(v.0) as i32),
                        ctx.o.y.saturating_add(libm::roundf(v.1) as i32),
                    );
                    let tol = (params.tolerance_mm as u64
                        + echo.range_mm as u64 * params.tolerance_permille as u64 / 1000)
                        .min(u32::MAX as u64) as u32;
                    *best = Some((
                        range,
                        Prediction {
                            range_mm: echo.range_mm,
                            kappa,
                            theta_mdeg: echo.theta_mdeg,
                            delta_mdeg: if case == Case::I { 0 } else { echo.delta_mdeg },
                            piece: ctx.piece,
                            obstacle: ctx.obstacle,
                            edge: ctx.edge,
                            point,
                            tolerance_mm: tol,
                            case,
                            nearer_mm: None,
                        },
                    ));
                    break;
                }
                if (end - s) * dir <= 0.0 {
                    break;
                }
                s += ds * dir;
                if (end - s) * dir < 0.0 {
                    s = end;
                }
            }
        }
    }
}

/// Test 4: does the ray from the transducer to the point `v` (relative to
/// it) meet any other piece? The ray stops a millimetre short of the point,
/// so a neighbour that only touches the echo point does not hide it.
///
/// With the window's sorted candidates at hand (every piece whose box meets
/// the window's box, within `R_max`), and the ray inside that box, only the
/// candidates whose box lies nearer than the point are tested: a piece the
/// ray meets at `q` has `q` in its box, so its box meets the window's box,
/// and its box is no farther than `q`. The answer is the grid query's,
/// without walking the grid again.
fn occluded<M: MapSource + ?Sized>(
    map: &M,
    ctx: &EdgeCtx<'_>,
    v: (f32, f32),
    range: f32,
    stats: &mut PredictStats,
) -> bool {
    stats.occlusion_tests = stats.occlusion_tests.wrapping_add(1);
    let k = fmax((range - 1.0) / range, 0.0);
    let end = Point::new(
        ctx.o.x.saturating_add(libm::roundf(v.0 * k) as i32),
        ctx.o.y.saturating_add(libm::roundf(v.1 * k) as i32),
    );
    let seg = Segment::new(ctx.o, end);
    let reach = seg.bbox();
    if let Some((keys, _, scale)) =
        ctx.occluders.filter(|(_, area, _)| area.contains(reach.min) && area.contains(reach.max))
    {
        let reach2 = (range + 1.0) * (range + 1.0);
        for &key in keys {
            if (key >> 16) as f32 * scale > reach2 {
                break; // this box and every later one lie beyond the point
            }
            let id = key as u16;
            if id == ctx.piece {
                continue;
            }
            if let Some(p) = map.piece(id) {
                if p.bbox.overlaps(&reach) && p.shape.hits_segment(seg.a, seg.b) {
                    return true;
                }
            }
        }
        return false;
    }
    let mut hidden = false;
    let _ = map.for_each_hit(seg, Layer::True, |p| {
        if p.id != ctx.piece {
            hidden = true;
        }
    });
    hidden
}

/// The nearest obstacle point in a window, geometrically.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Its distance from the transducer, mm.
    pub range_mm: f64,
    /// The point in the map, mm.
    pub point: (f64, f64),
    /// The piece it lies on.
    pub piece: u16,
}

/// `predict --geometric`: the nearest obstacle point in the wedge
/// `|φ| ≤ θ_o` within `R_max` (no δ, κ or `R_min`); `None` if there is none.
pub fn nearest_in_window<M: MapSource + ?Sized>(map: &M, window: &Window) -> Result<Option<Nearest>, PredictError> {
    let mut best: Option<Nearest> = None;
    map.for_each_candidate(window.sector.bbox(), |p| {
        if let Some((d, q)) = window.sector.nearest(p.shape) {
            if best.is_none_or(|b| d < b.range_mm) {
                best = Some(Nearest { range_mm: d, point: q, piece: p.id });
            }
        }
    })
    .map_err(|e| PredictError::Collect(CollectError::Map(e)))?;
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::{seen_beyond, sort_keys};
    use crate::geometry::Point;

    /// Against a brute force in `f64`: the least δ over 2 001 points of the
    /// edge (and its foot, when inside). An edge passed over must be seen
    /// beyond δ_max + 0.009° everywhere; one kept must come within 0.011°
    /// of the limit somewhere (the test is not much looser than it says).
    #[test]
    fn oblique_edges_are_passed_over_exactly_when_seen_beyond_the_limit() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = |span: i64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x >> 11) as i64 % (2 * span + 1) - span) as i32
        };
        let delta_max = 15.0f32;
        let lim = crate::f32math::sin_cos((delta_max + 0.01).to_radians());
        let (mut passed, mut kept) = (0, 0);
        for i in 0..20_000 {
            let span = [300, 5_000, 60_000][i % 3];
            let (o, a) = (Point::new(next(span), next(span)), Point::new(next(span), next(span)));
            let b = Point::new(a.x + next(span / 2), a.y + next(span / 2));
            if a == b {
                continue;
            }
            let e = ((b.x - a.x) as f64, (b.y - a.y) as f64);
            let delta_at = |s: f64| {
                let v = ((a.x - o.x) as f64 + s * e.0, (a.y - o.y) as f64 + s * e.1);
                (e.0 * v.0 + e.1 * v.1).abs().atan2((e.0 * v.1 - e.1 * v.0).abs()).to_degrees()
            };
            let foot = -(((a.x - o.x) as f64) * e.0 + ((a.y - o.y) as f64) * e.1) / (e.0 * e.0 + e.1 * e.1);
            let mut least = (0..=2_000).map(|k| delta_at(k as f64 / 2_000.0)).fold(f64::INFINITY, f64::min);
            if (0.0..=1.0).contains(&foot) {
                least = least.min(delta_at(foot));
            }
            if seen_beyond(o, a, b, lim) {
                passed += 1;
                assert!(least > f64::from(delta_max) + 0.009, "{o:?} {a:?} {b:?}: least δ {least}° passed over");
            } else {
                kept += 1;
                assert!(least < f64::from(delta_max) + 0.011, "{o:?} {a:?} {b:?}: least δ {least}° kept");
            }
        }
        assert!(passed > 5_000 && kept > 2_000, "passed over {passed}, kept {kept}");
    }

    /// Against `sort_unstable` on random lengths on both sides of the
    /// insertion/heap switch, with many repeated keys.
    #[test]
    fn sort_keys_matches_sort_unstable() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for case in 0..5_000 {
            let len = (next() % 300) as usize;
            let modulus = if case % 3 == 0 { 7 } else { u32::MAX as u64 };
            let mut keys = [0u32; 300];
            for k in keys[..len].iter_mut() {
                *k = (next() % modulus) as u32;
            }
            let mut want = keys;
            want[..len].sort_unstable();
            sort_keys(&mut keys[..len]);
            assert_eq!(keys[..len], want[..len], "case {case}, length {len}");
        }
    }
}
