//! Shapes (simple polygons and polylines, mm) → convex pieces → the
//! firmware's map → blob.

use echoloc::geometry::{split_convex_with_holes, HolesError, Point, Ring, MAX_PIECE_VERTICES};
use echoloc::map::field::FieldHeader;
use echoloc::map::{Capacity, FieldParts, Map, MapError, MapSource, MapView, ObstacleKind};
use echoloc::predict::PredictParams;
use echoloc::window::WindowParams;

use super::field::{build_field, FieldData, FieldOptions};

/// The field's figures for the summary: nodes, free nodes, headings, bytes,
/// and the flash a square metre of free space costs.
pub fn field_summary(h: &FieldHeader, entry_bytes: usize) -> serde_json::Value {
    let node_m = f64::from(h.node_mm) / 1000.0;
    serde_json::json!({
        "node_mm": h.node_mm,
        "dirs": h.dirs,
        "nodes": h.nodes,
        "free_nodes": h.free_nodes,
        "reach_mm": h.reach_mm,
        "clearance_mm": h.clearance_mm,
        "entry_bytes": entry_bytes,
        "free_area_m2": (f64::from(h.free_nodes) * node_m * node_m * 100.0).round() / 100.0,
        "bytes_per_m2_stored": if h.node_mm > 0 { (f64::from(h.dirs) / (node_m * node_m)).round() } else { 0.0 },
    })
}

/// One obstacle as imported.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A simple polygon (either orientation) with simple holes strictly
    /// inside it, touching neither it nor one another.
    Solid {
        /// The outer boundary.
        outer: Vec<Point>,
        /// The holes.
        holes: Vec<Vec<Point>>,
    },
    /// A polyline wall.
    Wall(Vec<Point>),
}

impl Shape {
    /// Its vertices, holes included.
    pub fn vertex_count(&self) -> usize {
        match self {
            Shape::Solid { outer, holes } => outer.len() + holes.iter().map(Vec::len).sum::<usize>(),
            Shape::Wall(w) => w.len(),
        }
    }
}

/// Most vertices one polygon (outer ring, holes and two bridge vertices per
/// hole) may have before splitting. The splitter's working set is about 110
/// bytes a vertex on the stack: `main` runs every command on a thread with a large one.
pub const SPLIT_CAPACITY: usize = 32768;

/// The import's figures, printed as JSON.
#[derive(Clone, Debug)]
pub struct MapSummary {
    pub polygons: usize,
    pub convex_pieces: usize,
    pub edges: usize,
    pub bytes: usize,
    pub buffer_mm: u32,
    pub cell_mm: u32,
    pub grid: (u16, u16),
    pub grid_refs: usize,
    /// Source-specific figures (the import's options, cell counts, …).
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl MapSummary {
    pub fn of<const P: usize, const V: usize, const C: usize, const R: usize>(
        m: &Map<P, V, C, R>,
        polygons: usize,
        bytes: usize,
    ) -> Self {
        let (cell_mm, cols, rows) = m.grid_dims();
        Self {
            polygons,
            convex_pieces: m.piece_count(),
            edges: m.true_vertex_count(),
            bytes,
            buffer_mm: m.buffer_mm(),
            cell_mm,
            grid: (cols, rows),
            grid_refs: m.grid_refs(),
            extra: serde_json::Map::new(),
        }
    }

    /// The figures of a compiled map read in place.
    pub fn of_view(v: &MapView<'_>, bytes: usize) -> Self {
        let (cell_mm, cols, rows) = v.grid_dims();
        Self {
            polygons: v.obstacle_count(),
            convex_pieces: v.piece_count(),
            edges: v.true_vertex_count(),
            bytes,
            buffer_mm: v.buffer_mm(),
            cell_mm,
            grid: (cols, rows),
            grid_refs: v.grid_refs(),
            extra: {
                let mut e = serde_json::Map::new();
                let f = v.field();
                if !f.is_empty() {
                    e.insert("field".into(), field_summary(f.header(), f.nodes() as usize * f.dirs() as usize));
                }
                e
            },
        }
    }

    pub fn to_json(&self) -> String {
        let mut v = serde_json::json!({
            "polygons": self.polygons,
            "convex_pieces": self.convex_pieces,
            "edges": self.edges,
            "bytes": self.bytes,
            "buffer_mm": self.buffer_mm,
            "cell_mm": self.cell_mm,
            "grid": [self.grid.0, self.grid.1],
            "grid_refs": self.grid_refs,
        });
        if let Some(o) = v.as_object_mut() {
            o.extend(self.extra.clone());
        }
        v.to_string()
    }
}

/// The map the host compiles into: the firmware reads the compiled blob in
/// place, so only flash limits it; this is a generous host-side bound
/// (32 768 pieces, enough for the depot tiled 8 × 8; piece ids are `u16`,
/// which no flash of this class outgrows: 65 536 pieces need about 8 MiB
/// of compiled map).
pub type CompileMap = Map<{ COMPILE_PIECES }, { COMPILE_VERTICES }, 262_144, 1_048_576>;
const COMPILE_PIECES: usize = 32_768;
const COMPILE_VERTICES: usize = 524_288;

/// Builds the map from `shapes` and compiles it (blob version 3) without a
/// localization field. The cell size starts at `cell_mm` and doubles until
/// the grid fits. Errors name the shape. Runs on its own thread: the
/// building map (about 5 MiB) is made on the stack before it is boxed in
/// unoptimised builds.
pub fn build_map(shapes: &[Shape], buffer_mm: u32, cell_mm: u32) -> Result<(Vec<u8>, MapSummary), String> {
    build_map_with(shapes, buffer_mm, cell_mm, None)
}

/// What a free point is, for the localization field: an occupancy grid's
/// known-free cells (`None`: any point clear of the obstacles).
pub type KnownFree<'a> = Option<&'a (dyn Fn(f64, f64) -> bool + Sync)>;

/// [`build_map`] with the localization field made with `field`
/// (`super::field`), when given.
pub fn build_map_with(
    shapes: &[Shape],
    buffer_mm: u32,
    cell_mm: u32,
    field: Option<(&FieldOptions, KnownFree<'_>)>,
) -> Result<(Vec<u8>, MapSummary), String> {
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .stack_size(64 << 20)
            .spawn_scoped(s, || build_map_here(shapes, buffer_mm, cell_mm, field))
            .map_err(|e| format!("cannot start the map builder: {e}"))?
            .join()
            .unwrap_or_else(|_| Err("the map builder panicked".to_string()))
    })
}

fn build_map_here(
    shapes: &[Shape],
    buffer_mm: u32,
    cell_mm: u32,
    field: Option<(&FieldOptions, KnownFree<'_>)>,
) -> Result<(Vec<u8>, MapSummary), String> {
    let mut map: Box<CompileMap> = Box::default();
    for (i, shape) in shapes.iter().enumerate() {
        match shape {
            Shape::Solid { outer, holes } => {
                let mut first = true;
                let hs: Vec<&[Point]> = holes.iter().map(Vec::as_slice).collect();
                split_convex_with_holes::<SPLIT_CAPACITY, MapError>(outer, &hs, MAX_PIECE_VERTICES, |piece| {
                    map.push_piece(ObstacleKind::Solid, std::mem::take(&mut first), piece).map(|_| ())
                })
                .map_err(|e| match e {
                    HolesError::Sink(MapError::Full(c)) => capacity_error(shapes, c),
                    HolesError::Sink(e) => format!("shape {i}: {}", map_error(e)),
                    e => format!("shape {i}: cannot split into convex pieces: {}", holes_error(e)),
                })?;
            }
            Shape::Wall(line) => {
                // The first segment actually pushed starts the obstacle
                // (a repeated first position is skipped, not merged away).
                let mut first = true;
                for (k, seg) in line.windows(2).enumerate() {
                    if seg[0] == seg[1] {
                        continue; // a repeated position is no segment
                    }
                    map.push_piece(ObstacleKind::Wall, first, seg).map_err(|e| match e {
                        MapError::Full(c) => capacity_error(shapes, c),
                        e => format!("shape {i}, segment {k}: {}", map_error(e)),
                    })?;
                    first = false;
                }
                if first {
                    return Err(format!("shape {i}: a wall whose positions are all the same has no segment"));
                }
            }
        }
    }
    let mut cell = cell_mm.max(1);
    loop {
        match map.finish(buffer_mm, cell) {
            Ok(()) => break,
            Err(MapError::Full(Capacity::Cells | Capacity::CellRefs)) if cell < u32::MAX / 2 => cell *= 2,
            Err(MapError::Full(c)) => return Err(capacity_error(shapes, c)),
            Err(e) => return Err(map_error(e)),
        }
    }
    let data = match field {
        Some((opts, known)) => {
            let params = PredictParams::new(WindowParams {
                tb_mm: buffer_mm,
                delta_max_deg: opts.delta_max_deg,
                ..WindowParams::POLAROID_6500
            });
            Some(build_field(&*map, &params, opts, known)?)
        }
        None => None,
    };
    let parts = data.as_ref().map_or(FieldParts::NONE, FieldData::parts);
    let mut blob = vec![0u8; map.compiled_len_with(&parts)];
    let n = map.compile_with_field(&parts, &mut blob).map_err(|e| format!("{e:?}"))?;
    blob.truncate(n);
    let mut summary = MapSummary::of(&map, shapes.len(), n);
    if let Some(d) = &data {
        summary.extra.insert("field".into(), field_summary(&d.header, d.entries.len()));
    }
    Ok((blob, summary))
}

fn map_error(e: MapError) -> String {
    match e {
        MapError::Full(c) => format!("the map exceeds the compiler's capacity ({c:?}) of CompileMap"),
        e => format!("{e:?}"),
    }
}

/// Words for a splitting error (the Debug name stays in, for searching).
pub fn holes_error(e: HolesError<MapError>) -> String {
    let ring = |r: Ring| match r {
        Ring::Outer => "the outer ring".to_string(),
        Ring::Hole(h) => format!("hole {h}"),
    };
    match e {
        HolesError::TooManyVertices => {
            format!("TooManyVertices: more than {SPLIT_CAPACITY} vertices in one polygon (holes count two extra each)")
        }
        HolesError::CoordinateOutOfRange(r) => {
            format!("CoordinateOutOfRange: {} has a coordinate beyond ±COORD_MAX", ring(r))
        }
        HolesError::Degenerate(r) => format!("Degenerate: {} has no area", ring(r)),
        HolesError::Intersect { ring_a, edge_a, ring_b, edge_b } if ring_a == ring_b => {
            format!("NotSimple: edges {edge_a} and {edge_b} of {} meet", ring(ring_a))
        }
        HolesError::Intersect { ring_a, edge_a, ring_b, edge_b } => {
            format!("RingsMeet: edge {edge_a} of {} meets edge {edge_b} of {}", ring(ring_a), ring(ring_b))
        }
        HolesError::HoleOutside(h) => format!("HoleOutside: hole {h} is not inside the outer ring"),
        HolesError::NestedHoles { outer, inner } => format!("NestedHoles: hole {inner} lies inside hole {outer}"),
        HolesError::NoBridge(h) => format!("NoBridge: no bridge found for hole {h}"),
        HolesError::NoEar => "NoEar: ear clipping found no ear".to_string(),
        HolesError::Sink(e) => map_error(e),
    }
}

/// What the whole map would need, against what `CompileMap` holds.
fn capacity_error(shapes: &[Shape], c: Capacity) -> String {
    let (mut pieces, mut verts, mut buffered, mut obstacles) = (0usize, 0usize, 0usize, 0usize);
    for shape in shapes {
        obstacles += 1;
        match shape {
            Shape::Solid { outer, holes } => {
                let hs: Vec<&[Point]> = holes.iter().map(Vec::as_slice).collect();
                let _ = split_convex_with_holes::<SPLIT_CAPACITY, ()>(outer, &hs, MAX_PIECE_VERTICES, |p| {
                    pieces += 1;
                    verts += p.len();
                    buffered += p.len() + 8;
                    Ok(())
                });
            }
            Shape::Wall(line) => {
                let n = line.windows(2).filter(|s| s[0] != s[1]).count();
                pieces += n;
                verts += 2 * n;
                buffered += 10 * n;
            }
        }
    }
    let (p_cap, v_cap) = (COMPILE_PIECES, COMPILE_VERTICES);
    format!(
        "the map exceeds the compiler's capacity ({c:?}): it needs {obstacles} obstacles and \
         {pieces} convex pieces (it holds {p_cap} of each) and {verts} true + up to {buffered} buffered vertices \
         (it holds {v_cap} in all); simplify more (--simplify-mm) or split the map"
    )
}
