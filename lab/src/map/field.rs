//! The localization field the map compiler puts into the blob
//! (`echoloc::map::field`, `docs/map-blob.md`): free space for particles to
//! be drawn from, and at every node a transducer can reach, the exact
//! prediction for each of `dirs` headings.
//!
//! *Free* nodes are at least `clearance_mm` from every obstacle, outside all
//! of them, within their bounding box, and where `known_free` says the
//! source's free space is: for an occupancy grid, a cell the grid knows to
//! be free (unknown cells are not a place the robot is known to be able to
//! stand, whatever `--unknown` made of them for the polygons); for a GeoJSON
//! map, inside the building ([`super::free_space`]). *Stored* nodes are
//! those within `reach_mm` (plus a node's diagonal, so that the four nodes
//! around any transducer position are stored) of a free node.

use echoloc::credence::net::CredenceNet;
use echoloc::geometry::{Point, Rect};
use echoloc::map::field::{FieldHeader, FieldParts, FieldRun, MAX_DIRS};
use echoloc::map::{Expected, MapSource};
use echoloc::predict::{predict, PredictParams};
use echoloc::window::Window;

/// How the field is made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldOptions {
    /// Node spacing, mm.
    pub node_mm: u32,
    /// Headings per node.
    pub dirs: u32,
    /// Stored nodes reach this far beyond the free ones, mm (the ring's
    /// farthest transducer from the robot's centre must be within it).
    pub reach_mm: u32,
    /// Free nodes keep this distance from every obstacle, mm.
    pub clearance_mm: u32,
    /// The map's face lobe: the prediction's δ_max, degrees, for the field
    /// and, recorded in it, for the tracker (`WindowParams::with_map_lobe`).
    /// [`FIELD_DELTA_MAX_DEG`] (MARGE's 15°) by default; `map import --walls
    /// lines` (real buildings) takes [`SMOOTH_FACE_LOBE_DEG`].
    pub delta_max_deg: f32,
    /// Where the prediction with `delta_max_deg` credits no surface, the
    /// entry holds the first surface a prediction with this lobe finds,
    /// unsure (0, the default: none, the entry says nothing is heard).
    /// Degrees, above `delta_max_deg` and below 90. Opt-in for now: at 60°
    /// the depot is found from no pose within 30 m in 43 of 50 runs against
    /// 27 without (docs/localization.md, issue #36), but the committed depot
    /// blob, the scenarios made on it and the boards' figures are all of the
    /// field without it, and on tb3_sandbox it hands off wrongly more.
    pub fallback_deg: f32,
}

/// A map's face lobe by default, degrees ([`FieldOptions::delta_max_deg`]):
/// MARGE's δ_max, the paper's, which the simulator's faces (heard to about
/// 30° at 1 m) also satisfy.
pub const FIELD_DELTA_MAX_DEG: f32 = 15.0;

/// The face lobe of a real building, degrees: a painted wall is a mirror at
/// 49 kHz, heard by a Polaroid only within about ±10° of its normal at 1 m,
/// narrowing with range (DESIGN §4.9, after Kuc and Siegel). Measured on the
/// shared buildings' ladder (docs/real-buildings.md): 9° and more lose the
/// ACES map rung, 15° loses the Intel laser rung with the ring fired at
/// the scans; 7° and 8° hold every rung.
pub const SMOOTH_FACE_LOBE_DEG: f32 = 8.0;

impl Default for FieldOptions {
    /// 250 mm nodes, 64 headings (5.6°), reach 400 mm (a Pioneer's ring is
    /// within 260 mm of its centre), clearance 200 mm.
    fn default() -> Self {
        Self {
            node_mm: 250,
            dirs: 64,
            reach_mm: 400,
            clearance_mm: 200,
            delta_max_deg: FIELD_DELTA_MAX_DEG,
            fallback_deg: 0.0,
        }
    }
}

impl FieldOptions {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), String> {
        if !(50..=5000).contains(&self.node_mm) {
            return Err(format!("field node spacing {} mm: must be within 50..=5000", self.node_mm));
        }
        if self.dirs == 0 || self.dirs > MAX_DIRS {
            return Err(format!("field headings {}: must be within 1..={MAX_DIRS}", self.dirs));
        }
        if !(self.delta_max_deg > 0.0 && self.delta_max_deg < 90.0) {
            return Err(format!("field δ_max {}°: must be within (0, 90)", self.delta_max_deg));
        }
        if self.reach_mm > 5000 || self.clearance_mm > 5000 {
            return Err("field reach and clearance: at most 5000 mm".into());
        }
        if self.fallback_deg != 0.0 && !(self.fallback_deg > self.delta_max_deg && self.fallback_deg < 90.0) {
            return Err(format!(
                "field fallback lobe {}°: must be 0 (none) or above δ_max ({}°) and below 90",
                self.fallback_deg, self.delta_max_deg
            ));
        }
        Ok(())
    }
}

/// A field, owned, ready to be compiled into a blob.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldData {
    pub header: FieldHeader,
    pub row_start: Vec<u32>,
    pub runs: Vec<FieldRun>,
    pub free: Vec<u32>,
    pub entries: Vec<u8>,
}

impl FieldData {
    /// The parts, for `Map::compile_with_field`.
    pub fn parts(&self) -> FieldParts<'_> {
        FieldParts {
            header: self.header,
            row_start: &self.row_start,
            runs: &self.runs,
            free: &self.free,
            entries: &self.entries,
        }
    }
}

/// The predictor's settings with the fallback lobe (`None` for none).
fn fallback_params(params: &PredictParams, fallback_deg: f32) -> Option<PredictParams> {
    (fallback_deg > 0.0).then(|| {
        let mut wide = *params;
        wide.window.delta_max_deg = fallback_deg;
        wide
    })
}

/// The field's entry for a transducer at `apex` facing `heading`: the
/// prediction with `params` (sure: κ ≥ 0.9 and no nearer surface), else,
/// with a `fallback`, its prediction, unsure.
fn expected_at<M: MapSource + ?Sized>(
    map: &M,
    apex: Point,
    heading: f32,
    params: &PredictParams,
    fallback: Option<&PredictParams>,
    net: &CredenceNet,
) -> Result<u8, String> {
    let at = |p: &PredictParams| {
        Window::place_for(&p.window, apex, heading, p.strategy)
            .map_err(|e| format!("{e:?}"))
            .and_then(|w| predict(map, &w, p, net).map_err(|e| format!("{e:?}")))
            .map(|(p, _)| p)
    };
    match (at(params)?, fallback) {
        (Some(p), _) => Ok(Expected::encode(Some(p.range_mm), p.kappa.to_num::<f32>() >= 0.9 && p.nearer_mm.is_none())),
        (None, Some(f)) => Ok(Expected::encode(at(f)?.map(|p| p.range_mm), false)),
        (None, None) => Ok(Expected::encode(None, false)),
    }
}

/// Squared distance (mm²) from `p` to the piece `pts` (0 inside it):
/// convex and counter-clockwise, or a two-vertex wall.
fn dist2_to_piece(p: (f64, f64), pts: &[Point]) -> f64 {
    let n = pts.len();
    let mut inside = n >= 3;
    let mut best = f64::INFINITY;
    for i in 0..n {
        let a = pts[i];
        let b = pts[(i + 1) % n];
        let (ax, ay, bx, by) = (f64::from(a.x), f64::from(a.y), f64::from(b.x), f64::from(b.y));
        let (ex, ey) = (bx - ax, by - ay);
        let (px, py) = (p.0 - ax, p.1 - ay);
        if ex * py - ey * px < 0.0 {
            inside = false;
        }
        let l2 = ex * ex + ey * ey;
        let t = if l2 > 0.0 { ((px * ex + py * ey) / l2).clamp(0.0, 1.0) } else { 0.0 };
        let (dx, dy) = (px - t * ex, py - t * ey);
        best = best.min(dx * dx + dy * dy);
    }
    if inside {
        0.0
    } else {
        best
    }
}

/// Builds the field of `map` (finished) with the predictor's `params` and
/// the shipped credence net. `known_free(x_mm, y_mm)`, when given, says
/// whether the source (an occupancy grid) knows a point to be free.
pub fn build_field<M: MapSource + Sync + ?Sized>(
    map: &M,
    params: &PredictParams,
    opts: &FieldOptions,
    known_free: Option<&(dyn Fn(f64, f64) -> bool + Sync)>,
) -> Result<FieldData, String> {
    opts.validate()?;
    let mut bounds: Option<Rect> = None;
    for id in 0..map.piece_count() {
        if let Some(p) = map.piece(id as u16) {
            for &v in p.shape.vertices() {
                let r = Rect::around(v);
                bounds = Some(bounds.map_or(r, |b| b.union(r)));
            }
        }
    }
    let empty = || FieldData {
        header: FieldHeader { reach_mm: opts.reach_mm, clearance_mm: opts.clearance_mm, ..FieldParts::NONE.header },
        row_start: vec![0],
        runs: Vec::new(),
        free: Vec::new(),
        entries: Vec::new(),
    };
    // An empty map has no room anywhere that the field could describe: an
    // empty field (the localizer refuses to search it, with a typed error).
    let Some(b) = bounds else { return Ok(empty()) };
    let node = i64::from(opts.node_mm);
    // The grid reaches beyond the obstacles' box by the reach and a node, so
    // that transducers of a robot at the box's edge have nodes around them.
    let margin = (i64::from(opts.reach_mm) + 2 * node) / node;
    let floor_div = |v: i64| v.div_euclid(node);
    let (c0, r0) = (floor_div(i64::from(b.min.x)) - margin, floor_div(i64::from(b.min.y)) - margin);
    let (c1, r1) = (floor_div(i64::from(b.max.x)) + margin + 1, floor_div(i64::from(b.max.y)) + margin + 1);
    let (cols, rows) = ((c1 - c0 + 1) as usize, (r1 - r0 + 1) as usize);
    if cols > usize::from(u16::MAX) || rows > usize::from(u16::MAX) || cols * rows > 64 << 20 {
        return Err(format!("a field of {cols} × {rows} nodes is too large: use larger nodes"));
    }
    let (ox, oy) = (c0 * node, r0 * node);
    if ox.abs() > i64::from(echoloc::geometry::COORD_MAX)
        || (ox + (cols as i64 - 1) * node).abs() > i64::from(echoloc::geometry::COORD_MAX)
        || oy.abs() > i64::from(echoloc::geometry::COORD_MAX)
        || (oy + (rows as i64 - 1) * node).abs() > i64::from(echoloc::geometry::COORD_MAX)
    {
        return Err("the field's nodes would reach beyond ±COORD_MAX".into());
    }
    let pos = |c: usize, r: usize| ((ox + c as i64 * node) as f64, (oy + r as i64 * node) as f64);
    // Free nodes: inside the obstacles' box, clear of every piece by the
    // clearance, and known free.
    let clear = f64::from(opts.clearance_mm);
    let inner = |x: f64, y: f64| {
        x >= f64::from(b.min.x) && x <= f64::from(b.max.x) && y >= f64::from(b.min.y) && y <= f64::from(b.max.y)
    };
    let mut free = vec![false; cols * rows];
    for r in 0..rows {
        for c in 0..cols {
            let (x, y) = pos(c, r);
            if !inner(x, y) || !known_free.is_none_or(|f| f(x, y)) {
                continue;
            }
            let q = Rect {
                min: Point::new((x - clear - 1.0) as i32, (y - clear - 1.0) as i32),
                max: Point::new((x + clear + 1.0) as i32, (y + clear + 1.0) as i32),
            };
            let mut ok = true;
            map.for_each_candidate_box(q, |id, _| {
                if ok {
                    if let Some(p) = map.piece(id) {
                        if dist2_to_piece((x, y), p.shape.vertices()) < clear * clear {
                            ok = false;
                        }
                    }
                }
            })
            .map_err(|e| format!("{e:?}"))?;
            free[r * cols + c] = ok;
        }
    }
    let free_count = free.iter().filter(|&&f| f).count();
    // Stored: within reach + a diagonal of a free node.
    let reach = f64::from(opts.reach_mm) + node as f64 * std::f64::consts::SQRT_2;
    let k = (reach / node as f64).ceil() as i64;
    let offsets: Vec<(i64, i64)> = (-k..=k)
        .flat_map(|dj| (-k..=k).map(move |di| (di, dj)))
        .filter(|&(di, dj)| ((di * di + dj * dj) as f64).sqrt() * node as f64 <= reach)
        .collect();
    let mut stored = vec![false; cols * rows];
    for r in 0..rows {
        for c in 0..cols {
            if !free[r * cols + c] {
                continue;
            }
            for &(di, dj) in &offsets {
                let (cc, rr) = (c as i64 + di, r as i64 + dj);
                if cc >= 0 && rr >= 0 && (cc as usize) < cols && (rr as usize) < rows {
                    stored[rr as usize * cols + cc as usize] = true;
                }
            }
        }
    }
    // Runs, row by row; node numbers in that order.
    let mut row_start = Vec::with_capacity(rows + 1);
    let mut runs: Vec<FieldRun> = Vec::new();
    let mut order: Vec<(usize, usize)> = Vec::new();
    for r in 0..rows {
        row_start.push(runs.len() as u32);
        let mut c = 0;
        while c < cols {
            if !stored[r * cols + c] {
                c += 1;
                continue;
            }
            let start = c;
            while c < cols && stored[r * cols + c] {
                c += 1;
            }
            runs.push(FieldRun { col: start as u16, len: (c - start) as u16, first: order.len() as u32 });
            order.extend((start..c).map(|cc| (cc, r)));
        }
    }
    row_start.push(runs.len() as u32);
    let nodes = order.len();
    let mut free_bits = vec![0u32; nodes.div_ceil(32)];
    for (n, &(c, r)) in order.iter().enumerate() {
        if free[r * cols + c] {
            free_bits[n / 32] |= 1 << (n % 32);
        }
    }
    // The predictions, spread over the machine's cores.
    let dirs = opts.dirs as usize;
    let fallback = fallback_params(params, opts.fallback_deg);
    let net = CredenceNet::shipped();
    let mut entries = vec![0u8; nodes * dirs];
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, 16);
    let chunk = nodes.div_ceil(threads).max(1);
    let failed = std::sync::Mutex::new(None::<String>);
    std::thread::scope(|s| {
        for (part, out) in order.chunks(chunk).zip(entries.chunks_mut(chunk * dirs)) {
            let (net, failed) = (&net, &failed);
            s.spawn(move || {
                for (k, &(c, r)) in part.iter().enumerate() {
                    let (x, y) = pos(c, r);
                    let apex = Point::new(x as i32, y as i32);
                    for d in 0..dirs {
                        let heading = (d as f64 * std::f64::consts::TAU / dirs as f64) as f32;
                        let p = expected_at(map, apex, heading, params, fallback.as_ref(), net);
                        match p {
                            Ok(e) => out[k * dirs + d] = e,
                            Err(e) => {
                                if let Ok(mut f) = failed.lock() {
                                    f.get_or_insert(format!("predicting at ({x}, {y}) mm: {e}"));
                                }
                                return;
                            }
                        }
                    }
                }
            });
        }
    });
    if let Some(e) = failed.into_inner().ok().flatten() {
        return Err(e);
    }
    let w = &params.window;
    let header = FieldHeader {
        node_mm: opts.node_mm,
        origin_x: ox as i32,
        origin_y: oy as i32,
        cols: cols as u32,
        rows: rows as u32,
        dirs: opts.dirs,
        runs: runs.len() as u32,
        nodes: nodes as u32,
        free_nodes: free_count as u32,
        reach_mm: opts.reach_mm,
        clearance_mm: opts.clearance_mm,
        r_min_mm: w.r_min_mm,
        r_max_mm: w.r_max_mm,
        half_angle_mdeg: (w.half_angle_deg * 1000.0).round() as u32,
        delta_max_mdeg: (w.delta_max_deg * 1000.0).round() as u32,
        fallback_mdeg: (opts.fallback_deg * 1000.0).round() as u32,
    };
    if nodes == 0 {
        // No room for the robot anywhere: an empty field (the localizer
        // refuses to search on it).
        return Ok(FieldData {
            header: FieldHeader { reach_mm: opts.reach_mm, clearance_mm: opts.clearance_mm, ..FieldParts::NONE.header },
            row_start: vec![0],
            runs: Vec::new(),
            free: Vec::new(),
            entries: Vec::new(),
        });
    }
    Ok(FieldData { header, row_start, runs, free: free_bits, entries })
}

/// How the field's expected readings compare with the exact prediction at
/// random transducer poses of the Pioneer ring on robots spread over free
/// space (`echoloc-lab map field-check`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FieldCheck {
    /// Transducer poses compared.
    pub samples: usize,
    /// Both predict nothing.
    pub both_nothing: usize,
    /// Both predict an echo.
    pub both_echo: usize,
    /// The exact predicts an echo, the field nothing.
    pub field_missed: usize,
    /// The exact predicts nothing, the field an echo.
    pub field_invented: usize,
    /// The field has no node there.
    pub off_field: usize,
    /// Where both predict an echo: |range error| (mm) quantiles 50, 90, 99 %.
    pub error_mm: [f64; 3],
    /// ... the share within the exact prediction's own tolerance.
    pub within_tolerance: f64,
    /// ... the share where both call it sure, or both unsure.
    pub same_sureness: f64,
    /// Of the samples, those whose exact prediction is the fallback lobe's
    /// (the field's own rule, [`FieldOptions::fallback_deg`]).
    pub fallback: usize,
}

impl FieldCheck {
    pub fn json(&self) -> serde_json::Value {
        let share = |n: usize| (n as f64 / self.samples.max(1) as f64 * 1e4).round() / 1e4;
        serde_json::json!({
            "samples": self.samples,
            "both_nothing": share(self.both_nothing),
            "both_echo": share(self.both_echo),
            "field_missed": share(self.field_missed),
            "field_invented": share(self.field_invented),
            "off_field": share(self.off_field),
            "from_the_fallback_lobe": share(self.fallback),
            "class_agreement": share(self.both_nothing + self.both_echo),
            "echo_error_mm": {"p50": self.error_mm[0], "p90": self.error_mm[1], "p99": self.error_mm[2]},
            "echo_within_tolerance": (self.within_tolerance * 1e4).round() / 1e4,
            "echo_same_sureness": (self.same_sureness * 1e4).round() / 1e4,
        })
    }
}

/// Compares the field of `view` with the exact prediction at `robots`
/// robot poses drawn over its free space, each with the Pioneer ring's 16
/// transducers (`seed` fixes the draws).
pub fn check_field(view: &echoloc::map::MapView<'_>, robots: usize, seed: u64) -> Result<FieldCheck, String> {
    use echoloc::localize::{FieldLookup, ParticleSet, Rng};
    use echoloc::predict::{predict_mount, Pose, PIONEER16};
    let field = view.field();
    if field.is_empty() {
        return Err("the map has no localization field (compiled with --no-field?)".into());
    }
    let lookup = FieldLookup::new(field);
    // The field's own δ_max is not stored in the blob: the check is against the tracker's prediction.
    let params = PredictParams::new(echoloc::window::WindowParams {
        tb_mm: view.buffer_mm(),
        ..echoloc::window::WindowParams::POLAROID_6500
    });
    // Where the field holds the fallback lobe's surface, so does the exact side.
    let wide = field.fallback_deg().and_then(|d| fallback_params(&params, d));
    let net = CredenceNet::shipped();
    let mut rng = Rng::new(seed);
    let mut c = FieldCheck::default();
    let mut errors = Vec::new();
    let (mut tol, mut same) = (0usize, 0usize);
    for _ in 0..robots {
        let p = ParticleSet::<0>::free_pose(&mut rng, &lookup).ok_or("no free space")?;
        let pose = Pose { x_mm: p[0] * 1e3, y_mm: p[1] * 1e3, heading_rad: p[2] };
        for m in &PIONEER16 {
            let (mut exact, _) = predict_mount(view, &pose, m, &params, &net).map_err(|e| format!("{e:?}"))?;
            let mut from_fallback = false;
            if let (None, Some(w)) = (exact, &wide) {
                exact = predict_mount(view, &pose, m, w, &net).map_err(|e| format!("{e:?}"))?.0;
                from_fallback = exact.is_some();
                c.fallback += usize::from(from_fallback);
            }
            let (s, co) = (p[2].sin(), p[2].cos());
            let (mx, my) = (m.x_mm as f32, m.y_mm as f32);
            let (tx, ty) = (pose.x_mm + co * mx - s * my, pose.y_mm + s * mx + co * my);
            let th = p[2] + (m.heading_mdeg as f32 / 1000.0).to_radians();
            c.samples += 1;
            match (exact, lookup.expected(tx, ty, th)) {
                (_, None) => c.off_field += 1,
                (None, Some(Expected::Nothing)) => c.both_nothing += 1,
                (Some(_), Some(Expected::Nothing)) => c.field_missed += 1,
                (None, Some(Expected::Echo { .. })) => c.field_invented += 1,
                (Some(e), Some(Expected::Echo { range_mm, sure })) => {
                    c.both_echo += 1;
                    let err = (f64::from(range_mm) - f64::from(e.range_mm)).abs();
                    errors.push(err);
                    if err <= f64::from(e.tolerance_mm) {
                        tol += 1;
                    }
                    let exact_sure = !from_fallback && e.kappa.to_num::<f32>() >= 0.9 && e.nearer_mm.is_none();
                    if exact_sure == sure {
                        same += 1;
                    }
                }
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let q = |f: f64| errors.get(((errors.len() as f64 * f) as usize).min(errors.len().saturating_sub(1))).copied();
    c.error_mm = [q(0.5), q(0.9), q(0.99)].map(|v| v.map_or(0.0, |v| v.round()));
    c.within_tolerance = tol as f64 / c.both_echo.max(1) as f64;
    c.same_sureness = same as f64 / c.both_echo.max(1) as f64;
    Ok(c)
}
