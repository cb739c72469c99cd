//! `echoloc-lab bench`: echoloc against the methods robots use today, for
//! the same sonar windows (the nearest obstacle inside the cone within
//! `R_max`, `predict --geometric`), side by side in one run:
//!
//! | method | representation | what it is |
//! |---|---|---|
//! | `bresenham_1deg`, `bresenham_0.25deg` | occupancy grid | a fan of rays by Bresenham's line, as ROS amcl's beam model casts each beam ([`grid::Grid::bresenham`]) |
//! | `bresenham_1deg_pruned` | occupancy grid | the 1° fan, each ray walked only to the fan's best range so far + 1.5 cells: the same answers ([`peers::bresenham_fan_pruned`]) |
//! | `ray_marching_1deg` | grid + Euclidean distance transform | a fan by ray marching, range_libc's "RM" ([`grid::DistanceMap::march`]) |
//! | `ray_marching_1deg_pruned` | grid + EDT | the same, each ray marched only to the best range so far + 1.5 cells: the same answers ([`peers::march_fan_pruned`]) |
//! | `parry2d_1deg` | polygons in a `parry2d` compound (its BVH) | a fan of rays cast by parry2d |
//! | `parry2d_polyline_1deg` | the surface edges in a `parry2d` `Polyline` (its BVH) | a fan, each ray's max time of impact the best range so far ([`peers::PolylineScene`]) |
//! | `cddt_1deg` | grid + range_libc's compressed directional distance transform, 108 directions | the 1° fan, each ray snapped to a discrete direction ([`peers::Cddt`]) |
//! | `echoloc_exact` | compiled map (read in place) | the exact nearest obstacle point in the window: the reference |
//! | `echoloc_pseudo_paths` | compiled map | the paper's pseudo-paths collect the pieces, then their nearest point |
//! | `echoloc_full` | compiled map | the full prediction (δ gate, quantised credence net, occlusion), for reference |
//!
//! Time per window over every window, methods interleaved in rounds;
//! completeness: the fraction of windows whose nearest obstacle a method
//! finds within 20 mm of the exact answer (one cell diagonal more for grid
//! methods), both "nothing in range" counting as found; memory of each
//! method's own structures. The exact reference is checked first against
//! an independent brute force over every piece on a sample of windows.
//!
//! Per half-angle, `summary` sets the full prediction against the fastest
//! peer (every method not echoloc's), against parry2d (the faster of its two
//! setups) and against the 1° Bresenham fan (the faster of pruned and
//! unpruned): each ratio is the peer's time over the full prediction's
//! (above 1: echoloc is faster).

pub mod brute;
mod export;
pub mod grid;
pub mod peers;
mod plot;

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use echoloc::credence::net::CredenceNet;
use echoloc::geometry::{Point, Rect};
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{nearest_in_window, predict, PredictParams};
use echoloc::window::{collect_beacons, Strategy, Window, WindowParams};
use parry2d_f64::math::{Pose, Vector};
use parry2d_f64::query::{Ray, RayCast};
use parry2d_f64::shape::{Compound, SharedShape};
use serde_json::{json, Value};

use crate::map::{read_compiled, read_shapes, view_of, AlignedBytes, LabError};

/// `bench`.
#[derive(Args)]
pub struct BenchArgs {
    /// The map: a compiled blob (.map), or a ROS map_server .yaml or .geojson (imported with a 100 mm buffer).
    /// Give several for a scaling run (one result per map).
    #[arg(long, required_unless_present = "from_json")]
    map: Vec<PathBuf>,
    /// With several maps: a PNG (or SVG, by the name) of time per window against the number of pieces, per method.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Draws --plot from an earlier run's JSON (`bench --json` of several maps) instead of benchmarking.
    #[arg(long = "from-json", conflicts_with = "map", requires = "plot")]
    from_json: Option<PathBuf>,
    /// Random free-space poses (one window each per half-angle).
    #[arg(long, default_value_t = 2000)]
    poses: usize,
    /// Seed of the pose generator.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Timing rounds (methods interleaved in each).
    #[arg(long, default_value_t = 5)]
    rounds: usize,
    /// Cell size of the occupancy grid the grid methods use, mm.
    #[arg(long = "cell-mm", default_value_t = 50)]
    cell_mm: u32,
    /// Half-angles of the windows, degrees (comma-separated).
    #[arg(long = "half-angles-deg", value_delimiter = ',', default_values_t = vec![15.0, 30.0])]
    half_angles_deg: Vec<f64>,
    /// One JSON object (the default prints the same, indented).
    #[arg(long)]
    json: bool,
    /// Writes the first map's windows at the first half-angle, with the
    /// host's exact and 1° Bresenham answers and the grid, for the
    /// firmware's `--bin bench_windows` (docs/benchmarks.md).
    #[arg(long = "export-windows")]
    export_windows: Option<PathBuf>,
}

/// The windows' reach, mm.
pub const R_MAX_MM: u32 = 5_500;
/// Completeness tolerance, m.
const TOL_M: f64 = 0.020;

/// One window: the sensor at `apex` looking along `heading`.
#[derive(Clone, Copy, Debug)]
pub struct Win {
    pub apex: Point,
    pub heading: f32,
}

impl Win {
    pub fn origin_m(&self) -> (f64, f64) {
        (f64::from(self.apex.x) / 1000.0, f64::from(self.apex.y) / 1000.0)
    }
}

/// Free-space poses: inside the map's bounds, outside every buffered piece.
pub(crate) fn poses(map: &MapView<'_>, n: usize, seed: u64) -> Vec<Win> {
    let Some(b) = map.bounds() else { return Vec::new() };
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        s.wrapping_mul(0x2545_F491_4F6C_DD1D)
    };
    let mut out = Vec::new();
    for _ in 0..n * 1000 {
        if out.len() == n {
            break;
        }
        let x = b.min.x + (next() % (b.max.x - b.min.x).max(1) as u64) as i32;
        let y = b.min.y + (next() % (b.max.y - b.min.y).max(1) as u64) as i32;
        let heading = (next() % 6_283_185) as f32 / 1e6 - std::f32::consts::PI;
        let p = Point::new(x, y);
        let mut free = true;
        let _ = map.for_each_candidate(Rect::around(p), |piece| free &= !piece.buffered.tvector(p).is_inside());
        if free {
            out.push(Win { apex: p, heading });
        }
    }
    out
}

/// A ray fan: `half` each side of `heading` in `step` (radians), both ends included.
pub(crate) fn fan(heading: f64, half: f64, step: f64) -> impl Iterator<Item = (f64, f64)> {
    let n = (half / step).round() as i64;
    (-n..=n).map(move |k| {
        let a = heading + k as f64 * step;
        (a.cos(), a.sin())
    })
}

pub(crate) fn min_opt(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(x), Some(y)) => Some(x.min(y)),
        (x, None) => x,
        (None, y) => y,
    }
}

/// The parry2d peer: the true pieces as convex polygons (segments for walls)
/// in one compound, which keeps its own BVH.
pub(crate) struct ParryScene {
    compound: Option<Compound>,
    bytes: usize,
}

impl ParryScene {
    pub(crate) fn new(outlines: &[Vec<(f64, f64)>]) -> Self {
        let mut bytes = 0;
        let parts: Vec<(Pose, SharedShape)> = outlines
            .iter()
            .filter_map(|pts| {
                let s = match pts.as_slice() {
                    [a, b] => Some(SharedShape::segment(Vector::new(a.0, a.1), Vector::new(b.0, b.1))),
                    _ => SharedShape::convex_polyline(pts.iter().map(|p| Vector::new(p.0, p.1)).collect()),
                }?;
                // Points and normals (2 × 16 B a vertex), the shape and its Arc.
                bytes += pts.len() * 32 + 64;
                Some((Pose::IDENTITY, s))
            })
            .collect();
        // The BVH: about two nodes per leaf, an AABB and links each.
        bytes += parts.len() * 2 * 48;
        Self { compound: (!parts.is_empty()).then(|| Compound::new(parts)), bytes }
    }

    pub(crate) fn cast(&self, o: (f64, f64), d: (f64, f64), max: f64) -> Option<f64> {
        let c = self.compound.as_ref()?;
        let ray = Ray::new(Vector::new(o.0, o.1), Vector::new(d.0, d.1));
        c.cast_local_ray(&ray, max, true)
    }
}

type Method<'a> = Box<dyn Fn(&Win) -> Option<f64> + 'a>;

/// The map as the bench reads it: the compiled bytes, aligned.
pub(crate) fn load(path: &std::path::Path) -> Result<AlignedBytes, LabError> {
    if path.extension().is_some_and(|e| e == "map") {
        return read_compiled(path);
    }
    let shapes = read_shapes(path)?;
    let (blob, _) =
        crate::map::build::build_map(&shapes, 100, 500).map_err(|e| LabError(format!("{}: {e}", path.display())))?;
    Ok(AlignedBytes::new(&blob))
}

/// The true pieces' outlines, m.
pub(crate) fn outlines_of(map: &MapView<'_>) -> Vec<Vec<(f64, f64)>> {
    map.pieces_iter()
        .map(|p| p.shape.vertices().iter().map(|v| (f64::from(v.x) / 1000.0, f64::from(v.y) / 1000.0)).collect())
        .collect()
}

pub fn bench_cmd(a: &BenchArgs) -> Result<String, LabError> {
    if a.poses == 0 || a.rounds == 0 || a.cell_mm == 0 {
        return Err(LabError("--poses, --rounds and --cell-mm must be positive".into()));
    }
    if a.half_angles_deg.is_empty() || a.half_angles_deg.iter().any(|h| !(h.is_finite() && *h > 0.0 && *h < 90.0)) {
        return Err(LabError("--half-angles-deg: each in (0, 90)".into()));
    }
    if let Some(p) = &a.plot {
        if p.extension().is_none_or(|e| e != "png" && e != "svg") {
            return Err(LabError(format!("--plot {}: must end in .png or .svg", p.display())));
        }
    }
    if let (Some(j), Some(p)) = (&a.from_json, &a.plot) {
        let text = std::fs::read_to_string(j).map_err(|e| LabError(format!("{}: {e}", j.display())))?;
        let v: Value = serde_json::from_str(&text).map_err(|e| LabError(format!("{}: not JSON: {e}", j.display())))?;
        let results = match v.get("maps").and_then(Value::as_array) {
            Some(m) => m.clone(),
            None => vec![v.clone()],
        };
        if results.iter().all(|r| r["methods"].as_array().is_none_or(|m| m.is_empty())) {
            return Err(LabError(format!("{}: no \"methods\" with results (bench --json's form)", j.display())));
        }
        let bytes = plot::scaling_as(&results, crate::figure::Format::of(p)).map_err(LabError)?;
        crate::map::write_atomically(p, &bytes)?;
        return Ok(json!({"plot": p.display().to_string(), "maps": results.len()}).to_string());
    }
    let results = a
        .map
        .iter()
        .enumerate()
        .map(|(i, m)| bench_map(m, a, if i == 0 { a.export_windows.as_deref() } else { None }))
        .collect::<Result<Vec<_>, _>>()?;
    if let Some(p) = &a.plot {
        let png = plot::scaling_as(&results, crate::figure::Format::of(p)).map_err(LabError)?;
        std::fs::write(p, png).map_err(|e| LabError(format!("--plot {}: {e}", p.display())))?;
    }
    let v =
        if results.len() == 1 { results.into_iter().next().unwrap_or_default() } else { json!({ "maps": results }) };
    Ok(if a.json { v.to_string() } else { serde_json::to_string_pretty(&v).unwrap_or_default() })
}

fn bench_map(
    path: &std::path::Path,
    a: &BenchArgs,
    export: Option<&std::path::Path>,
) -> Result<serde_json::Value, LabError> {
    let aligned = load(path)?;
    let map = view_of(&aligned, path)?;
    let outlines = outlines_of(&map);
    let wins = poses(&map, a.poses, a.seed);
    if wins.len() < a.poses {
        return Err(LabError(format!("only {} free poses found", wins.len())));
    }
    let t = Instant::now();
    let res = f64::from(a.cell_mm) / 1000.0;
    let grid = grid::Grid::rasterise(&outlines, res, 2);
    let dist = grid::DistanceMap::of(&grid);
    let parry = ParryScene::new(&outlines);
    let setup_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let polyline = peers::PolylineScene::new(&outlines);
    let polyline_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let cddt = peers::Cddt::new(&grid, peers::CDDT_THETA_DISCRETIZATION);
    let cddt_s = t.elapsed().as_secs_f64();
    let net = CredenceNet::shipped();
    let r_max = f64::from(R_MAX_MM) / 1000.0;
    let diag = res * std::f64::consts::SQRT_2;

    let mut methods_json = Vec::new();
    let mut summary = Vec::new();
    let mut checks = Vec::new();
    for &half_deg in &a.half_angles_deg {
        let wp = WindowParams {
            r_min_mm: 0,
            r_max_mm: R_MAX_MM,
            half_angle_deg: half_deg as f32,
            tb_mm: map.buffer_mm(),
            ..WindowParams::MARGE
        };
        wp.validate().map_err(|e| LabError(format!("window: {e:?}")))?;
        let params = PredictParams::new(WindowParams { r_min_mm: WindowParams::MARGE.r_min_mm, ..wp });
        let place = |w: &Win| Window::place(&wp, w.apex, w.heading).ok();
        let half = half_deg.to_radians();
        let exact = |w: &Win| -> Option<f64> {
            let win = place(w)?;
            nearest_in_window(&map, &win).ok().flatten().map(|n| n.range_mm / 1000.0)
        };
        // The reference, then its check against the brute force.
        let reference: Vec<Option<f64>> = wins.iter().map(exact).collect();
        checks.push(brute::check(&outlines, &wins, &reference, half, r_max, half_deg));

        let methods: Vec<(&str, bool, usize, Method<'_>)> = vec![
            (
                "bresenham_1deg",
                true,
                grid.bytes(),
                Box::new(|w: &Win| {
                    peers::bresenham_fan(&grid, w.origin_m(), f64::from(w.heading), half, 1f64.to_radians(), r_max)
                }),
            ),
            (
                "bresenham_1deg_pruned",
                true,
                grid.bytes(),
                Box::new(|w: &Win| {
                    peers::bresenham_fan_pruned(
                        &grid,
                        w.origin_m(),
                        f64::from(w.heading),
                        half,
                        1f64.to_radians(),
                        r_max,
                    )
                }),
            ),
            (
                "bresenham_0.25deg",
                true,
                grid.bytes(),
                Box::new(|w: &Win| {
                    peers::bresenham_fan(&grid, w.origin_m(), f64::from(w.heading), half, 0.25f64.to_radians(), r_max)
                }),
            ),
            (
                "ray_marching_1deg",
                true,
                grid.bytes() + dist.bytes(),
                Box::new(|w: &Win| {
                    peers::march_fan(&grid, &dist, w.origin_m(), f64::from(w.heading), half, 1f64.to_radians(), r_max)
                }),
            ),
            (
                "ray_marching_1deg_pruned",
                true,
                grid.bytes() + dist.bytes(),
                Box::new(|w: &Win| {
                    peers::march_fan_pruned(
                        &grid,
                        &dist,
                        w.origin_m(),
                        f64::from(w.heading),
                        half,
                        1f64.to_radians(),
                        r_max,
                    )
                }),
            ),
            (
                "parry2d_1deg",
                false,
                parry.bytes,
                Box::new(|w: &Win| {
                    fan(f64::from(w.heading), half, 1f64.to_radians())
                        .fold(None, |b, d| min_opt(b, parry.cast(w.origin_m(), d, r_max)))
                }),
            ),
            (
                "parry2d_polyline_1deg",
                false,
                polyline.bytes,
                Box::new(|w: &Win| {
                    polyline.fan_pruned(w.origin_m(), f64::from(w.heading), half, 1f64.to_radians(), r_max)
                }),
            ),
            (
                "cddt_1deg",
                true,
                cddt.bytes(),
                Box::new(|w: &Win| cddt.fan(w.origin_m(), f64::from(w.heading), half, 1f64.to_radians(), r_max)),
            ),
            ("echoloc_exact", false, aligned.bytes().len(), Box::new(exact)),
            (
                "echoloc_pseudo_paths",
                false,
                aligned.bytes().len(),
                Box::new(|w: &Win| {
                    let win = Window::place_for(&wp, w.apex, w.heading, Strategy::PseudoPaths).ok()?;
                    let mut ids: heapless::Vec<u16, 512> = heapless::Vec::new();
                    collect_beacons(&map, &win, Strategy::PseudoPaths, &mut ids).ok()?;
                    ids.iter()
                        .filter_map(|&id| map.piece(id).and_then(|p| win.sector.nearest(p.shape)))
                        .map(|(d, _)| d / 1000.0)
                        .fold(None, |b, d| min_opt(b, Some(d)))
                }),
            ),
            (
                "echoloc_full",
                false,
                aligned.bytes().len(),
                Box::new(|w: &Win| {
                    let win = Window::place(&params.window, w.apex, w.heading).ok()?;
                    predict(&map, &win, &params, &net).ok()?.0.map(|p| f64::from(p.range_mm) / 1000.0)
                }),
            ),
        ];
        if let (Some(out), true) = (export, half_deg == a.half_angles_deg[0]) {
            let bres: Vec<Option<f64>> = wins.iter().map(|w| (methods[0].3)(w)).collect();
            export::write(out, &wins, &reference, &bres, &grid, half_deg, &aligned)?;
        }
        // Completeness (untimed), then time in rounds, methods interleaved.
        let mut found = vec![0usize; methods.len()];
        for (k, (_, is_grid, _, f)) in methods.iter().enumerate() {
            let tol = TOL_M + if *is_grid { diag } else { 0.0 };
            found[k] = wins
                .iter()
                .zip(&reference)
                .filter(|(w, r)| match (f(w), **r) {
                    (None, None) => true,
                    (Some(m), Some(r)) => (m - r).abs() <= tol,
                    _ => false,
                })
                .count();
        }
        let mut ns = vec![0f64; methods.len()];
        let mut sink = 0.0;
        for round in 0..a.rounds {
            for i in 0..methods.len() {
                let k = (i + round) % methods.len();
                let f = &methods[k].3;
                let t0 = Instant::now();
                for w in &wins {
                    sink += f(std::hint::black_box(w)).unwrap_or(0.0);
                }
                ns[k] += t0.elapsed().as_nanos() as f64;
            }
        }
        std::hint::black_box(sink);
        let per = |k: usize| ns[k] / (a.rounds * wins.len()) as f64;
        let full = methods.iter().position(|m| m.0 == "echoloc_full").map_or(1.0, per);
        for (k, (name, _, bytes, _)) in methods.iter().enumerate() {
            let completeness = (*name != "echoloc_full").then(|| round4(found[k] as f64 / wins.len() as f64));
            methods_json.push(json!({
                "name": name, "half_angle_deg": half_deg,
                "ns_per_window": per(k).round(), "ratio_to_echoloc": round4(per(k) / full),
                "completeness": completeness, "bytes": bytes,
            }));
        }
        // The full prediction against the fastest peer, parry2d's faster
        // setup and the faster 1° Bresenham fan.
        let fastest = |pick: &dyn Fn(&str) -> bool| -> Value {
            let best =
                methods.iter().enumerate().filter(|(_, m)| pick(m.0)).min_by(|a, b| per(a.0).total_cmp(&per(b.0)));
            match best {
                Some((k, m)) => json!({"method": m.0, "ns_per_window": per(k).round(), "ratio": round4(per(k) / full)}),
                None => Value::Null,
            }
        };
        summary.push(json!({
            "half_angle_deg": half_deg,
            "echoloc_full_ns_per_window": full.round(),
            "fastest_peer": fastest(&|n: &str| !n.starts_with("echoloc")),
            "parry2d": fastest(&|n: &str| n.starts_with("parry2d")),
            "bresenham_1deg": fastest(&|n: &str| n.starts_with("bresenham_1deg")),
        }));
    }
    eprintln!("{}", summary_table(&path.display().to_string(), &summary));
    Ok(json!({
        "map": path.display().to_string(), "pieces": map.piece_count(), "windows_per_half_angle": wins.len(),
        "rounds": a.rounds, "cell_mm": a.cell_mm, "grid": [grid.w, grid.h], "r_max_m": r_max,
        "setup_s": round4(setup_s), "reference_check": checks, "methods": methods_json, "summary": summary,
        "polyline_segments": polyline.segments, "polyline_setup_s": round4(polyline_s),
        "cddt": {"theta_discretization": cddt.theta_discretization, "zero_points": cddt.zero_points(),
                 "bytes": cddt.bytes(), "setup_s": round4(cddt_s)},
    }))
}

/// The summary as a table (printed to stderr, beside the JSON on stdout).
fn summary_table(map: &str, summary: &[Value]) -> String {
    let mut out = format!(
        "{map}: the full prediction against the peers (ratio: the peer's ns over the full's; above 1: echoloc faster)\n\
         {:>5} {:>8} | {:<25}{:>8}{:>7} | {:<22}{:>8}{:>7} | {:<22}{:>8}{:>7}\n",
        "half", "full ns", "fastest peer", "ns", "ratio", "parry2d", "ns", "ratio", "bresenham 1deg", "ns", "ratio"
    );
    let cell = |v: &Value, w: usize| {
        format!(
            "{:<w$}{:>8}{:>7.2}",
            v["method"].as_str().unwrap_or("-"),
            v["ns_per_window"].as_f64().unwrap_or(f64::NAN),
            v["ratio"].as_f64().unwrap_or(f64::NAN),
        )
    };
    for s in summary {
        out += &format!(
            "{:>5} {:>8} | {} | {} | {}\n",
            s["half_angle_deg"].as_f64().unwrap_or(f64::NAN),
            s["echoloc_full_ns_per_window"].as_f64().unwrap_or(f64::NAN),
            cell(&s["fastest_peer"], 25),
            cell(&s["parry2d"], 22),
            cell(&s["bresenham_1deg"], 22),
        );
    }
    out
}

fn round4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}
