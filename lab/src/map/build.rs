//! Shapes (simple polygons and polylines, mm) → convex pieces → the
//! firmware's map → blob.

use echoloc::geometry::{split_convex, Point, SplitError, MAX_PIECE_VERTICES};
use echoloc::map::{Capacity, Map, MapError, ObstacleKind, StandardMap};

/// One obstacle as imported.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A simple polygon (either orientation).
    Solid(Vec<Point>),
    /// A polyline wall.
    Wall(Vec<Point>),
}

/// Most vertices one polygon may have before splitting.
const SPLIT_CAPACITY: usize = 8192;

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
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::json!({
            "polygons": self.polygons,
            "convex_pieces": self.convex_pieces,
            "edges": self.edges,
            "bytes": self.bytes,
            "buffer_mm": self.buffer_mm,
            "cell_mm": self.cell_mm,
            "grid": [self.grid.0, self.grid.1],
            "grid_refs": self.grid_refs,
        })
        .to_string()
    }
}

/// Builds the firmware's map from `shapes` and encodes it. The cell size
/// starts at `cell_mm` and doubles until the grid fits the firmware's
/// capacity. Errors name the shape.
pub fn build_map(shapes: &[Shape], buffer_mm: u32, cell_mm: u32) -> Result<(Vec<u8>, MapSummary), String> {
    let mut map: Box<StandardMap> = Box::default();
    for (i, shape) in shapes.iter().enumerate() {
        match shape {
            Shape::Solid(ring) => {
                let mut first = true;
                split_convex::<SPLIT_CAPACITY, MapError>(ring, MAX_PIECE_VERTICES, |piece| {
                    map.push_piece(ObstacleKind::Solid, std::mem::take(&mut first), piece).map(|_| ())
                })
                .map_err(|e| match e {
                    SplitError::Sink(e) => format!("shape {i}: {}", map_error(e)),
                    e => format!("shape {i}: cannot split into convex pieces: {e:?}"),
                })?;
            }
            Shape::Wall(line) => {
                for (k, seg) in line.windows(2).enumerate() {
                    if seg[0] == seg[1] {
                        continue; // a repeated position is no segment
                    }
                    map.push_piece(ObstacleKind::Wall, k == 0, seg)
                        .map_err(|e| format!("shape {i}, segment {k}: {}", map_error(e)))?;
                }
            }
        }
    }
    let mut cell = cell_mm.max(1);
    loop {
        match map.finish(buffer_mm, cell) {
            Ok(()) => break,
            Err(MapError::Full(Capacity::Cells | Capacity::CellRefs)) if cell < u32::MAX / 2 => cell *= 2,
            Err(e) => return Err(map_error(e)),
        }
    }
    let mut blob = vec![0u8; map.encoded_len()];
    let n = map.encode(&mut blob).map_err(|e| format!("{e:?}"))?;
    blob.truncate(n);
    let summary = MapSummary::of(&map, shapes.len(), n);
    Ok((blob, summary))
}

fn map_error(e: MapError) -> String {
    match e {
        MapError::Full(c) => format!("the map exceeds the firmware's capacity ({c:?}) of echoloc::map::StandardMap"),
        e => format!("{e:?}"),
    }
}
